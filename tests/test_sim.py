"""bench/sim_cloth.py and bench/sim_cases.py (issue 28; docs/simulated.md): the stored tiny
simulated drape (bench/data/sim-sphere-tiny.npz) is checked for what a cloth simulation must
give (edge lengths kept, nothing inside the sphere or under the ground, a real drape), its cases
for a per-vertex correspondence and a camera scan with the stated noise and outliers, and,
where Newton is installed, the simulator for reproducing the stored state."""

from __future__ import annotations

import importlib.util
import warnings

import numpy as np
import pytest

from bench import cases, sim_cases, sim_cloth


@pytest.fixture(scope="module")
def tiny():
    return sim_cases.load_tiny()


def test_stored_tiny_state_is_a_physical_drape(tiny):
    scene = sim_cloth.SMALL
    rest, final = tiny.rest, tiny.final
    assert rest.shape == final.shape == (scene.vertices, 3)
    # cloth barely stretches: every edge within 5 % of its rest length
    ratios = sim_cloth.edge_ratios(rest, final, tiny.faces, tiny.pinned)
    assert 0.95 < ratios.min() and ratios.max() < 1.05, (ratios.min(), ratios.max())
    # nothing inside the sphere or under the ground (contact keeps a particle radius away)
    edge = float(np.median(np.linalg.norm(rest[tiny.faces[:, 0]] - rest[tiny.faces[:, 1]], axis=1)))
    assert sim_cloth.collider_distance(final, scene.colliders).min() > -0.1 * edge
    # a drape, not the flat sheet: the centre lies on top of the sphere, the corners hang
    # below its equator
    (sphere,) = scene.colliders
    centre = final[(scene.n_v // 2) * scene.n_u + scene.n_u // 2]
    top = np.asarray(sphere.centre) + [0, 0, sphere.size[0]]
    assert np.linalg.norm(centre - top) < 0.05
    corners = final[[0, scene.n_u - 1, scene.vertices - scene.n_u, scene.vertices - 1]]
    assert (corners[:, 2] < sphere.centre[2]).all()


def test_template_and_truth_correspond_vertex_by_vertex(tiny):
    case = sim_cases.tiny_case("mesh")
    assert case.template_vertices.shape == case.ground_truth.shape
    np.testing.assert_array_equal(case.target, case.ground_truth)
    # the placed template is the rest mesh moved by a similarity: every distance scaled alike
    d_rest = np.linalg.norm(tiny.rest - tiny.rest[0], axis=1)[1:]
    d_placed = np.linalg.norm(case.template_vertices - case.template_vertices[0], axis=1)[1:]
    scale = case.meta["prealign"]["scale"]
    np.testing.assert_allclose(d_placed, scale * d_rest, rtol=1e-3)
    # vertex i of the template is vertex i of the truth: the truth's edges over the template's
    # faces keep the template's lengths (a shuffled truth would not)
    ratios = sim_cloth.edge_ratios(case.template_vertices, case.ground_truth, case.faces, tiny.pinned)
    assert np.abs(ratios / np.median(ratios) - 1).max() < 0.06


def test_scan_is_camera_visible_noisy_with_outliers(tiny):
    from bench import dressed_scans

    case = sim_cases.tiny_case("scan")
    truth, faces = case.ground_truth, case.faces
    diag = cases.bbox_diagonal(truth)
    outliers = case.meta["outliers"]
    assert outliers >= 1 and len(case.target) == case.meta["points"] <= 400 + outliers
    _, _, closest = dressed_scans.closest_on_mesh(case.target, truth, faces)
    d = np.linalg.norm(closest - case.target, axis=1)
    near = d < 4 * sim_cases.SCAN_NOISE * diag
    assert near.sum() >= len(d) - outliers - 2
    # the stated noise: the near points' distances are those of N(0, σ²) per coordinate off a
    # surface (mean |normal component| = σ √(2/π))
    sigma = sim_cases.SCAN_NOISE * diag
    assert 0.5 * sigma < d[near].mean() < 1.3 * sigma
    # camera visibility: the sheet's underside over the sphere is hidden, so no scan point lies
    # under the cloth inside the sphere's shadow (between the sphere and the cloth's top)
    (sphere,) = sim_cloth.SMALL.colliders
    r = np.linalg.norm(case.target[near] - np.asarray(sphere.centre), axis=1)
    assert (r > sphere.size[0] - 2 * sigma).all()


def test_the_default_fit_improves_on_the_placed_template():
    import foldmatch_rs as fm

    from bench import harness

    case = sim_cases.tiny_case("scan")
    arrays = harness.case_arrays(case)
    start = harness.evaluate(arrays, case.template_vertices)["f_R"]
    fitted = fm.fit(case.template_vertices, case.faces, case.target).vertices
    assert harness.evaluate(arrays, fitted)["f_R"] < 0.7 * start


@pytest.mark.skipif(importlib.util.find_spec("newton") is None, reason="newton is not installed")
def test_the_simulator_reproduces_the_stored_state(tiny):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = sim_cloth.simulate(sim_cloth.SMALL)
    np.testing.assert_array_equal(r.faces, tiny.faces)
    np.testing.assert_allclose(r.rest, tiny.rest, atol=1e-6)
    assert np.abs(r.final - tiny.final).max() < 2e-3


def test_stored_flag_sequence_is_a_physical_motion_with_per_frame_truth():
    """bench/sim_sequence.py's flag in gusty wind (the tracking benchmark's simulated,
    held-out sequence): every frame keeps the cloth's edge lengths, the pole edge stays where
    it is pinned, and the flag moves between frames."""
    from bench import sim_sequence

    frames = sim_sequence.frames()
    scene = sim_sequence.SCENE
    assert len(frames) == 24
    numbers = [n for n, _, _ in frames]
    assert numbers == sorted(numbers) and np.all(np.diff(numbers) == sim_sequence.EVERY)
    rest, faces = sim_cloth.rest_mesh(scene)
    pole = sim_cloth.pinned(scene)
    diagonal = cases.bbox_diagonal(frames[0][1])
    motions = []
    for i, (_, positions, frame_faces) in enumerate(frames):
        np.testing.assert_array_equal(frame_faces, faces)
        ratios = sim_cloth.edge_ratios(rest, positions, faces, pole)
        assert 0.9 < np.percentile(ratios, 1) and np.percentile(ratios, 99) < 1.15
        np.testing.assert_allclose(positions[pole], rest[pole], atol=1e-5)
        if i:
            motions.append(np.linalg.norm(positions - frames[i - 1][1], axis=1).mean() / diagonal)
    # a flapping flag: every frame moves, by up to a few per cent of the diagonal
    assert min(motions) > 0.003 and max(motions) > 0.015, motions


@pytest.mark.parametrize("name", ["sim-flag2", "sim-drape"])
def test_stored_held_out_sequences_are_physical_motions(name):
    """bench/sim_sequence.py's other sequences (the flag in another wind, a sheet landing on a
    sphere): stored, recorded every other simulated frame, the cloth's edge lengths kept, and
    moving between frames."""
    from bench import sim_sequence

    frames = sim_sequence.frames(name)
    seq = sim_sequence.SEQUENCES[name]
    numbers = [n for n, _, _ in frames]
    assert len(frames) >= 24 and np.all(np.diff(numbers) == sim_sequence.EVERY)
    rest, faces = sim_cloth.rest_mesh(seq.scene)
    pinned = sim_cloth.pinned(seq.scene)
    diagonal = cases.bbox_diagonal(frames[0][1])
    for i, (_, positions, frame_faces) in enumerate(frames):
        np.testing.assert_array_equal(frame_faces, faces)
        ratios = sim_cloth.edge_ratios(rest, positions, faces, pinned)
        assert 0.85 < np.percentile(ratios, 1) and np.percentile(ratios, 99) < 1.2, (i, ratios)
        if i:
            motion = np.linalg.norm(positions - frames[i - 1][1], axis=1).mean() / diagonal
            assert motion > 1e-4, (i, motion)


def test_a_scanner_mesh_frame_is_the_point_scan_triangulated_as_one_sheet():
    """`bench.tracking --scans mesh`: a frame's mesh holds the very points of its point-cloud
    scan (so the two kinds of frames differ by their faces alone), triangulated into one
    sheet (a disk: V − E + F = 1, no edge on three faces) that covers the cloth's area."""
    from bench import sim_sequence, tracking

    chart = sim_sequence.chart("sim-drape")
    for number, vertices, faces in sim_sequence.frames("sim-drape")[::15]:
        points, triangles = tracking.scanner_mesh(vertices, faces, chart, seed=1000 + number)
        np.testing.assert_array_equal(points, tracking.noisy_scan(vertices, faces, seed=1000 + number))
        edges = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), 1)
        unique, count = np.unique(edges, axis=0, return_counts=True)
        assert count.max() == 2
        assert len(np.unique(triangles)) - len(unique) + len(triangles) == 1
        area = cases.face_areas(points, triangles).sum() / cases.face_areas(vertices, faces).sum()
        assert 0.9 < area < 1.1, area


@pytest.mark.parametrize("scans", ["points", "mesh"])
def test_tracking_benchmark_runs_on_the_simulated_sequence(scans):
    """`python -m bench.tracking --sequence sim-flag [--scans mesh]` on its first frames: the
    template is the first frame's mesh, which the tracker keeps, and every figure is
    reported."""
    import argparse

    from bench import tracking

    args = argparse.Namespace(
        scans=scans,
        sequence=tracking.SIM_SEQUENCE,
        every=1,
        limit=3,
        mode="track",
        preset="tracking",
        iterations=40,
        prediction=0.0,
        reanchor=False,
        set=[],
        threads=None,
        json=None,
    )
    summary = tracking.run(args)
    assert summary["frames"] == [n for n, _, _ in tracking.frames_of(tracking.SIM_SEQUENCE)][:3]
    assert summary["first_f_R_pct"] <= tracking.FIRST_FRAME_MAX
    # the later frames moved 1.5–2 % of the diagonal; tracked, they stay well within that
    assert 0 < summary["max_f_R_pct"] < 2.0
