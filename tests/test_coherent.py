"""The coherent candidate (docs/method.md "Coherent candidate"; `coherent_gate`): a fit whose
edges spread past the gate is fitted again from a Coherent Point Drift start, and the second
fit is kept only when it lies closer to the scan in both directed distances. Checked on the
physically simulated flag and heap (bench/sim_cases.py, from the simulator's stored states in
bench/data/sim), where the candidate makes the default the lowest of every method run
(bench/peer_figures_sim.json), and on cases where it must change nothing."""

from __future__ import annotations

import json
import pathlib

import foldmatch_rs as fm
import numpy as np
import pytest

from bench import harness, sim_cases, sim_cloth

PEERS = json.loads((pathlib.Path(__file__).parents[1] / "bench" / "peer_figures_sim.json").read_text())


def sim_case(scene: str, kind: str):
    order = list(sim_cloth.SCENES)
    sim = sim_cases.cached_state(sim_cloth.SCENES[scene])
    assert sim is not None, f"bench/data/sim holds no state of {scene}"
    cases = sim_cases.cases_of(
        scene,
        sim,
        sim_cloth.collider_meshes(sim_cloth.SCENES[scene]),
        sim_cases.SCAN_POINTS["small"],
        seed=2800 + order.index(scene),
        kinds=(kind,),
    )
    return next(iter(cases))


def fit_both(case):
    on = fm.fit(case.template_vertices, case.faces, case.target, target_faces=case.target_faces)
    off = fm.fit(
        case.template_vertices,
        case.faces,
        case.target,
        target_faces=case.target_faces,
        params={"coherent_gate": 0.0},
    )
    return on, off


@pytest.mark.parametrize("scene", ["flag", "heap"])
def test_the_candidate_places_a_drape_the_first_fit_slid(scene):
    case = sim_case(scene, "scan")
    arrays = harness.case_arrays(case)
    on, off = fit_both(case)
    figures = on.diagnostics["coherent"]
    assert "coherent" not in off.diagnostics or off.diagnostics["coherent"] is None
    assert figures["edge_distortion"] >= 1.2 and figures["kept"]
    # kept because it lies closer to the scan in both directions
    assert figures["fit_to_scan"][1] < figures["fit_to_scan"][0]
    assert figures["scan_to_fit"][1] < figures["scan_to_fit"][0]
    assert on.quality["fit_to_scan"] == pytest.approx(figures["fit_to_scan"][1])
    f_on = harness.evaluate(arrays, on.vertices)["f_R"]
    f_off = harness.evaluate(arrays, off.vertices)["f_R"]
    best_peer = PEERS["cases"][case.name]["f_R"]
    # the first fit loses to CPD on these scans; the candidate's does not
    assert f_off > best_peer
    assert f_on < (0.85 if scene == "flag" else 0.9) * f_off
    # below the best peer on the flag by 12 %; on the heap by 0.1 % (0.0702 against probreg's
    # CPD 0.0703, `python -m bench.sim`), which the test allows half a per cent either way
    assert f_on < (1.0 if scene == "flag" else 1.005) * best_peer


def test_a_candidate_not_closer_in_both_directions_changes_nothing():
    case = sim_case("flag", "mesh")
    on, off = fit_both(case)
    figures = on.diagnostics["coherent"]
    assert figures["edge_distortion"] >= 1.2 and not figures["kept"]
    closer = [figures[k][1] < figures[k][0] for k in ("fit_to_scan", "scan_to_fit")]
    assert not all(closer)
    np.testing.assert_array_equal(on.vertices, off.vertices)


def test_a_fit_below_the_gate_runs_no_candidate():
    c = fm.folded_sheet(nx=16, ny=16, scan_points=800, noise=0.002, seed=3)
    on = fm.fit(c["template_vertices"], c["faces"], c["scan"])
    assert on.quality["edge_distortion"] < 1.2
    assert on.diagnostics.get("coherent") is None
    # the same fit with the gate below its distortion runs the candidate
    low = fm.fit(c["template_vertices"], c["faces"], c["scan"], params={"coherent_gate": 1.0})
    assert low.diagnostics["coherent"]["edge_distortion"] == pytest.approx(on.quality["edge_distortion"])
    if not low.diagnostics["coherent"]["kept"]:
        np.testing.assert_array_equal(low.vertices, on.vertices)


def test_the_gate_is_a_setting_of_the_presets():
    assert fm.FitParams("default").coherent_gate == pytest.approx(1.2)
    for preset in ("fast", "paper", "tracking"):
        assert fm.FitParams(preset).coherent_gate == 0.0
    with pytest.raises(fm.InvalidParameterError, match="coherent_gate"):
        fm.FitParams("default", coherent_gate=-1.0)


def test_a_scan_of_part_of_the_garment_runs_no_candidate():
    """The bent-over T-shirt (real, ../shared/data) seen by one camera rig on its front
    (bench/partial.py's half scan): its fit reaches the gate but leaves its unseen back without
    scan support, and CPD, which models a scan of the whole template, would draw that back onto
    the front (f_R 0.043 -> 0.055): no candidate. Its whole scan gets one."""
    from bench import cases, partial

    why = cases.real_data_missing()
    if why:
        pytest.skip(why)
    case = next(c for c in cases.real_cases(kinds=("mesh",)) if c.name == "vto-tshirt-0200-mesh")
    whole = fm.fit(case.template_vertices, case.faces, case.target)
    assert whole.diagnostics["coherent"]["kept"]
    half = fm.fit(case.template_vertices, case.faces, partial.half_scan(case))
    assert half.quality["edge_distortion"] >= 1.2
    assert half.quality["unsupported_share"] > 0.05
    assert half.diagnostics.get("coherent") is None
