"""Rim matching on mesh targets (docs/method.md "Rim matching"): the template's boundary loops
laid onto the target mesh's boundary at their rest arc length, on a flag a cloth simulator
blew into folds (bench/sim_cases.py, the cached Newton state: third-party physics, not a
formula of ours)."""

from __future__ import annotations

import foldmatch_rs as fm
import numpy as np
import pytest

from bench import harness, sim_cases


@pytest.fixture(scope="module")
def flag():
    found = {c.name: c for c in sim_cases.sim_cases(("flag",), simulate=False)}
    if "sim-flag-mesh" not in found:
        pytest.skip("the cached simulated flag (bench/data/sim/flag.npz) is missing")
    return found


def boundary_vertex_count(faces: np.ndarray) -> int:
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    return len(np.unique(unique[counts == 1]))


def test_the_rim_places_a_fit_swirled_along_the_flag(flag):
    # The default fit of the simulated flag's mesh lies on its surface but swirled along it;
    # laying its rim onto the mesh's rim at arc length brings it well closer to the truth,
    # and every rim vertex is matched (one loop each), without folding faces beyond the
    # truth's own + 1 point.
    # (The coherent candidate is off in both: without the rim the first fit's edges spread past
    # its gate, and its candidate, kept there, places the flag by CPD's motion instead.)
    case = flag["sim-flag-mesh"]
    arrays = harness.case_arrays(case)
    on = fm.fit(
        case.template_vertices,
        case.faces,
        case.target,
        target_faces=case.target_faces,
        params={"coherent_gate": 0.0},
    )
    off = fm.fit(
        case.template_vertices,
        case.faces,
        case.target,
        target_faces=case.target_faces,
        params={"rim_weight": 0.0, "coherent_gate": 0.0},
    )
    e_on, e_off = harness.evaluate(arrays, on.vertices), harness.evaluate(arrays, off.vertices)
    assert e_on["f_R"] < 0.75 * e_off["f_R"], (e_on["f_R"], e_off["f_R"])
    assert on.diagnostics["rim_matched"] == boundary_vertex_count(case.faces)
    assert off.diagnostics["rim_matched"] == 0
    truth_flips = harness.evaluate(arrays, case.ground_truth)["f_F"]
    assert e_on["f_F"] <= truth_flips + 0.01, (e_on["f_F"], truth_flips)


def test_a_point_cloud_target_has_no_rim_to_match(flag):
    # Without target faces there is no boundary: the fit is the one without rim matching.
    case = flag["sim-flag-scan"]
    on = fm.fit(case.template_vertices, case.faces, case.target)
    off = fm.fit(case.template_vertices, case.faces, case.target, params={"rim_weight": 0.0})
    assert on.diagnostics["rim_matched"] == 0
    np.testing.assert_array_equal(on.vertices, off.vertices)


def test_a_negative_rim_weight_is_refused_by_name():
    with pytest.raises(fm.InvalidParameterError, match="rim_weight"):
        fm.FitParams(rim_weight=-0.1)


def test_the_paper_preset_has_no_rim_matching():
    assert fm.FitParams("paper").rim_weight == 0.0
    assert fm.FitParams().rim_weight > 0.0
