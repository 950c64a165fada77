"""The isometric refinement in a single fit (docs/method.md "Isometric refinement"): its hold
term against crumpling on a noisy scan, its plane normal, and its settings' domains."""

from __future__ import annotations

import foldmatch_rs as fm
import pytest

from bench import cases, harness


def test_the_hold_keeps_a_noisy_paper_sized_fit_from_flipping_faces():
    # The harness's noisy paper-sized folded sheet (13K vertices, one scan point per vertex):
    # free edge springs let the refinement follow the noise and flip faces beyond the truth's
    # own + 1 point; holding the edge vectors at the schedule's result keeps them within.
    case = next(c for c in cases.generated_cases("paper", ("noisy",)) if c.name.startswith("sheet"))
    arrays = harness.case_arrays(case)
    truth_flips = harness.evaluate(arrays, case.ground_truth)["f_F"]
    figures = {}
    for hold in (0.0, 1.0):
        params = {"isometric_iterations": 30, "isometric_weight": 3.0, "isometric_hold": hold}
        fitted = fm.fit(case.template_vertices, case.faces, case.target, params=params).vertices
        figures[hold] = harness.evaluate(arrays, fitted)
    assert figures[0.0]["f_F"] > truth_flips + 0.01, figures[0.0]["f_F"]
    assert figures[1.0]["f_F"] <= truth_flips + 0.01, figures[1.0]["f_F"]
    # And the fit stays as close to the truth.
    assert figures[1.0]["f_R"] < 1.1 * figures[0.0]["f_R"]


def test_a_negative_hold_is_refused_by_name():
    with pytest.raises(fm.InvalidParameterError, match="isometric_hold"):
        fm.FitParams(isometric_hold=-1.0)


def test_the_plane_normal_is_the_scan_s_in_a_fit_and_the_fit_s_when_tracking():
    # The tracking preset pulls each vertex along its own normal (docs/method.md "Tracking");
    # the choice reaches the fit (a different result) and a bad value is refused by name.
    case = next(c for c in cases.generated_cases("small", ("noisy",)) if c.name.startswith("sheet"))
    v, f, x = case.template_vertices, case.faces, case.target
    assert fm.FitParams()["isometric_plane"] == "scan"
    assert fm.FitParams("tracking")["isometric_plane"] == "fit"
    single = {"selection": "single"}
    scan_plane = fm.fit(v, f, x, iterations=20, params=single).vertices
    fit_plane = fm.fit(v, f, x, iterations=20, params={**single, "isometric_plane": "fit"}).vertices
    assert abs(scan_plane - fit_plane).max() > 1e-6
    with pytest.raises(fm.InvalidParameterError, match="isometric_plane"):
        fm.FitParams(isometric_plane="mesh")
