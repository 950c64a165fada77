"""Landmarks (``fm.fit(..., landmarks=(indices, positions))``): they place the
template, hold their vertices at their targets through the fit, and bad ones are refused
naming the landmark."""

from __future__ import annotations

import foldmatch_rs as fm
import numpy as np
import pytest

from bench import harness, sim_cases

N = 21  # grid side


@pytest.fixture(scope="module")
def sheet():
    """A flat square sheet (template) and, as the scan, the same sheet turned by 90° about its
    normal: the same points, so the scan alone cannot show the turn."""
    case = fm.folded_sheet(nx=N, ny=N, scan_points=500, noise=0.0)
    v, f = case["template_vertices"], case["faces"]
    c = v.mean(0)
    truth = np.column_stack([c[0] - (v[:, 1] - c[1]), c[1] + (v[:, 0] - c[0]), v[:, 2]])
    return v, f, truth


def rmse(a, b):
    return float(np.sqrt(((a - b) ** 2).sum(1).mean()))


def test_landmarks_settle_a_turn_the_scan_cannot_show(sheet):
    v, f, truth = sheet
    plain = fm.fit(v, f, truth, iterations=30)
    assert rmse(plain.vertices, truth) > 0.2 * np.ptp(v[:, 0])
    corners = np.array([0, N - 1, N * (N - 1), N * N - 1])
    guided = fm.fit(v, f, truth, landmarks=(corners, truth[corners]), iterations=30)
    assert rmse(guided.vertices, truth) < 0.01 * np.ptp(v[:, 0])
    assert guided.params["landmark_weight"] == fm.DEFAULT_PARAMS["landmark_weight"] == 1.0


def test_one_landmark_chooses_among_the_search_s_readings(sheet):
    """One or two landmarks fix no orientation by themselves: the pre-alignment's search places
    the template (here in one of the square sheet's four readings, which the scan cannot tell
    apart), and the landmark chooses the reading that puts it at its target. Moved by its
    translation alone, as before, the template stayed turned."""
    v, f, truth = sheet
    corner = np.array([N - 1])
    guided = fm.fit(v, f, truth, landmarks=(corner, truth[corner]), iterations=30)
    assert rmse(guided.vertices, truth) < 0.01 * np.ptp(v[:, 0])
    # Without a search there is nothing to choose from: the translation alone.
    unsearched = fm.fit(v, f, truth, landmarks=(corner, truth[corner]), iterations=30, prealign="centroid")
    assert rmse(unsearched.vertices, truth) > 0.2 * np.ptp(v[:, 0])


def test_two_landmarks_settle_a_garment_turned_back_to_front():
    """The real T-shirt's point scan turned 180° about the vertical: without landmarks its two
    readings tie and the fit ends back to front (f_R 0.37); with a landmark on the front of the
    chest and one at the hem it ends within 1.25× the unturned fit, and given z-up the two
    landmarks keep the search's placement (docs/method.md "Landmarks")."""
    from bench import cases, prealign

    why = cases.real_data_missing()
    if why:
        pytest.skip(why)
    case = next(c for c in cases.real_cases(kinds=("points",)) if c.name == "vto-tshirt-0000-pts")
    t, f = case.template_vertices, case.faces
    unmoved = rmse(fm.fit(t, f, case.target).vertices, case.ground_truth)
    c = t.mean(0)
    chosen = np.array([int(np.argmax(t[:, 2] - c[2])), int(np.argmin(t[:, 1]))])
    for move in ("turn180", "zup"):
        m = prealign.moved(case, prealign.RIGID[move])
        g = m["ground_truth"]
        r = fm.fit(t, f, m["target"], landmarks=(chosen, g[chosen]))
        assert rmse(r.vertices, g) < 1.25 * unmoved, (move, rmse(r.vertices, g), unmoved)


def test_landmark_vertices_end_near_their_targets_and_the_weight_sets_how_near(sheet):
    v, f, _ = sheet
    width = np.ptp(v[:, 0])
    # Targets moved along the sheet by 2 % of its width from their vertices' places.
    chosen = np.array([6 * N + 6, 6 * N + 14, 14 * N + 10])
    targets = v[chosen] + [0.02 * width, 0.0, 0.0]
    gap = {}
    for w in (0.0, 1.0, 5.0):
        r = fm.fit(v, f, v, landmarks=(chosen, targets), params={"landmark_weight": w}, iterations=40)
        gap[w] = np.linalg.norm(r.vertices[chosen] - targets, axis=1).max()
        assert r.params["landmark_weight"] == w
    assert gap[0.0] > 0.015 * width, gap
    assert gap[1.0] < 0.006 * width, gap
    assert gap[5.0] < gap[1.0], gap


@pytest.mark.parametrize(
    "landmarks, message",
    [
        (([0, N * N], [[0, 0, 0], [1, 1, 1]]), f"landmark 1: vertex {N * N} is out of range"),
        (([-1], [[0, 0, 0]]), "landmark 0: vertex -1 is out of range"),
        (([4, 4], [[0, 0, 0], [1, 1, 1]]), "landmark 1: vertex 4 is already constrained by landmark 0"),
        (([3], [[0, np.nan, 0]]), r"landmark 0: non-finite target coordinate \(NaN\) for vertex 3"),
        (([3], [[0, np.inf, 0]]), r"landmark 0: non-finite target coordinate \(inf\) for vertex 3"),
        (([1, 2], [[0, 0, 0]]), "2 vertex indices but 1 target positions"),
        (([1], [[0, 0]]), r"positions must have shape \(L, 3\), got \(1, 2\)"),
        (([[1]], [[0, 0, 0]]), r"indices must have shape \(L,\)"),
        (([1.5], [[0, 0, 0]]), "indices must be integers"),
        (([], np.zeros((0, 3))), "no landmarks"),
        (([1],), r"expected \(template_vertex_indices, target_positions\), got tuple of length 1"),
    ],
)
def test_bad_landmarks_are_refused_naming_the_landmark(sheet, landmarks, message):
    v, f, truth = sheet
    with pytest.raises(fm.InvalidInputError, match=message):
        fm.fit(v, f, truth, landmarks=landmarks, iterations=2)


def test_a_negative_landmark_weight_is_refused(sheet):
    v, f, truth = sheet
    with pytest.raises(fm.InvalidParameterError, match="landmark_weight"):
        fm.fit(v, f, truth, landmarks=([0], truth[:1]), params={"landmark_weight": -1.0}, iterations=2)


def rim_corners(vertices: np.ndarray, faces: np.ndarray, count: int) -> np.ndarray:
    """`count` boundary vertices spread by farthest-point sampling."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    rim = np.unique(unique[counts == 1])
    chosen = [int(rim[0])]
    nearest = np.linalg.norm(vertices[rim] - vertices[rim[0]], axis=1)
    while len(chosen) < count:
        j = int(rim[int(np.argmax(nearest))])
        chosen.append(j)
        nearest = np.minimum(nearest, np.linalg.norm(vertices[rim] - vertices[j], axis=1))
    return np.array(chosen)


@pytest.mark.parametrize(
    ("scene", "case_name", "count"), [("sphere", "sim-sphere-mesh", 4), ("box", "sim-box-scan", 8)]
)
def test_landmarks_on_a_drape_do_not_hold_the_rigid_phase_below_the_scan(scene, case_name, count):
    # A flat sheet a cloth simulator draped over a sphere / a box (bench/sim_cases.py, the
    # cached Newton state), its rim's corners given at their true (hanging) places: the
    # landmarks place the flat template at the corners' level, below the drape's top. The
    # rigid phase must still carry it up onto the scan (landmarks do not enter it): held to
    # the landmarks it stalled there and the fit ended 5-10x farther from the truth than
    # without them (docs/method.md "Landmarks").
    found = {c.name: c for c in sim_cases.sim_cases((scene,), simulate=False)}
    if case_name not in found:
        pytest.skip(f"the cached simulated {scene} (bench/data/sim/{scene}.npz) is missing")
    case = found[case_name]
    arrays = harness.case_arrays(case)
    v, f, x = case.template_vertices, case.faces, case.target
    corners = rim_corners(v, f, count)
    without = fm.fit(v, f, x, target_faces=case.target_faces)
    guided = fm.fit(v, f, x, target_faces=case.target_faces, landmarks=(corners, case.ground_truth[corners]))
    f_without = harness.evaluate(arrays, without.vertices)["f_R"]
    f_guided = harness.evaluate(arrays, guided.vertices)["f_R"]
    assert f_guided < 1.1 * f_without, (f_guided, f_without)


@pytest.fixture(scope="module")
def marked_sheet():
    """A generated folded sheet (template, faces, clean scan, truth) and six landmark vertices:
    its corners and two edge midpoints."""
    case = fm.folded_sheet(nx=N, ny=N, scan_points=800, noise=0.0)
    v, f, x, g = case["template_vertices"], case["faces"], case["scan"], case["ground_truth"]
    return v, f, x, g, np.array([0, N - 1, N * (N - 1), N * N - 1, N // 2, N * (N // 2)])


def test_with_the_similarity_the_template_s_unit_does_not_change_the_landmark_fit(marked_sheet):
    # prealign="similarity" with landmarks: the landmarks' placement sets the template's size,
    # and the fit is that of the template so placed, whatever unit the scan and its landmarks
    # are in. The rest shape had been the template as given, so the same scan and landmarks
    # in millimetres fitted differently (RMS to the truth 1.18x that in the template's unit).
    v, f, x, g, marks = marked_sheet
    fits = {}
    for unit in (1.0, 1000.0):
        r = fm.fit(v, f, unit * x, landmarks=(marks, unit * g[marks]), prealign="similarity")
        fits[unit] = r.vertices / unit
    np.testing.assert_allclose(fits[1000.0], fits[1.0], rtol=0, atol=1e-9 * np.ptp(v[:, 0]))
    assert rmse(fits[1.0], g) < 0.05 * np.ptp(v[:, 0])


def test_the_template_s_given_place_does_not_change_the_landmark_fit(marked_sheet):
    # The landmarks place the template (their vertices' rigid fit onto their targets) and the
    # template so placed is the fit's template and rest shape: turned and moved anywhere
    # before, it fits the same.
    v, f, x, g, marks = marked_sheet
    a = np.radians(70.0)
    turn = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    moved = v @ turn.T + np.array([3.0, -2.0, 5.0])
    given = fm.fit(v, f, x, landmarks=(marks, g[marks]))
    elsewhere = fm.fit(moved, f, x, landmarks=(marks, g[marks]))
    np.testing.assert_allclose(elsewhere.vertices, given.vertices, rtol=0, atol=1e-9 * np.ptp(v[:, 0]))
    assert rmse(given.vertices, g) < 0.05 * np.ptp(v[:, 0])
