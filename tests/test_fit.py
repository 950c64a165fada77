"""End-to-end fits on generated cases with known ground truth, determinism, input handling and
bad-input errors (issue: FoldMatch core)."""

from __future__ import annotations

import math
import re

import foldmatch_rs as fm
import numpy as np
import pytest

N = 41  # grid side of the generated sheet


@pytest.fixture(scope="module")
def case():
    """A flat sheet and the same sheet with folds and a rigid offset (3° and 0.05 along the
    normal), scanned as 3000 surface samples (a different count than the template's 1681)."""
    return fm.folded_sheet(nx=N, ny=N, scan_points=3000, rotation_degrees=3.0, offset=(0, 0, 0.05))


@pytest.fixture(scope="module")
def fitted(case):
    return fm.fit(case["template_vertices"], case["faces"], case["scan"])


def rmse(a, b):
    return float(np.sqrt(((a - b) ** 2).sum(1).mean()))


def flipped_fraction(case, fitted_vertices, margin):
    """Fraction of faces whose normal turned by more than 90°, over the faces whose vertices are
    all at least ``margin`` grid steps away from the sheet's boundary."""
    f = case["faces"]
    i, j = f % N, f // N
    inner = ((i >= margin) & (j >= margin) & (i < N - margin) & (j < N - margin)).all(1)

    def normals(v):
        a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
        return np.cross(b - a, c - a)

    dots = (normals(case["template_vertices"]) * normals(fitted_vertices)).sum(1)
    return float((dots[inner] < 0).mean())


def test_foldmatch_halves_the_ground_truth_error(case, fitted):
    before = rmse(case["template_vertices"], case["ground_truth"])
    after = rmse(fitted.vertices, case["ground_truth"])
    assert after < before / 2, (before, after)
    assert fitted.iterations == fm.DEFAULT_PARAMS["iterations"] == 80
    assert fitted.vertices.shape == case["template_vertices"].shape


def test_few_flips_away_from_the_boundary(case, fitted):
    # "Away from the boundary": at least 5 edges in (2-ring neighborhoods plus the reach of the
    # boundary's one-sided attraction). Near the boundary the paper's method does crumple;
    # docs/method.md reports the whole-sheet figure.
    assert flipped_fraction(case, fitted.vertices, margin=5) < 0.01


def test_nrga_mode_runs_on_the_same_case(case):
    r = fm.fit(case["template_vertices"], case["faces"], case["scan"], params=dict(method="nrga"))
    before = rmse(case["template_vertices"], case["ground_truth"])
    assert rmse(r.vertices, case["ground_truth"]) < before
    assert np.all(r.wvf == 0), "NRGa has no per-step deformation gradient"
    assert r.wvf_accumulated_magnitude.max() > 0


def test_units_do_not_matter(case, fitted):
    """The same case in millimetres instead of metres gives the same fit, in millimetres."""
    mm = fm.fit(case["template_vertices"] * 1000, case["faces"], case["scan"] * 1000)
    np.testing.assert_allclose(mm.vertices / 1000, fitted.vertices, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(mm.wvf_accumulated, fitted.wvf_accumulated, atol=1e-9)


def test_thread_count_does_not_change_a_bit(case):
    args = (case["template_vertices"], case["faces"], case["scan"])
    one = fm.fit(*args, iterations=20, threads=1)
    two = fm.fit(*args, iterations=20, threads=2)
    assert np.array_equal(one.vertices, two.vertices)
    assert np.array_equal(one.wvf_accumulated, two.wvf_accumulated)


def test_layouts_and_dtypes_give_the_same_result(case):
    v, f, x = case["template_vertices"], case["faces"], case["scan"]
    base = fm.fit(v, f, x, iterations=10)
    fortran = fm.fit(np.asfortranarray(v), f.astype(np.uint32), np.asfortranarray(x), iterations=10)
    strided = np.zeros((len(v), 6))
    strided[:, ::2] = v
    assert not strided[:, ::2].flags.c_contiguous
    viewed = fm.fit(strided[:, ::2], f, x.tolist(), iterations=10)
    assert np.array_equal(base.vertices, fortran.vertices)
    assert np.array_equal(base.vertices, viewed.vertices)
    # float32 inputs are converted once: the same fit as the float64 copy of those values.
    v32, x32 = v.astype(np.float32), x.astype(np.float32)
    a = fm.fit(v32, f, x32, iterations=10)
    b = fm.fit(v32.astype(np.float64), f, x32.astype(np.float64), iterations=10)
    assert np.array_equal(a.vertices, b.vertices)
    assert a.vertices.dtype == np.float64


def unaligned(a: np.ndarray) -> np.ndarray:
    """A C-contiguous copy of ``a`` one byte off its alignment (as an array unpickled from a
    buffer, e.g. by Dask, may be)."""
    raw = np.zeros(a.nbytes + 1, dtype=np.uint8)
    out = raw[1:].view(a.dtype).reshape(a.shape)
    out[...] = a
    assert out.flags.c_contiguous and not out.flags.aligned
    return out


def test_unaligned_arrays_are_accepted(case):
    v, f, x = case["template_vertices"], case["faces"], case["scan"]
    base = fm.fit(v, f, x, iterations=5)
    moved = fm.fit(unaligned(v), unaligned(f.astype(np.int64)), unaligned(x), iterations=5)
    assert np.array_equal(base.vertices, moved.vertices)


def test_outputs_own_their_memory(fitted):
    for a in (fitted.vertices, fitted.wvf, fitted.wvf_accumulated, fitted.wvf_magnitude):
        assert a.flags.owndata or a.base is not None  # a NumPy array wrapping Rust's Vec
        assert a.flags.c_contiguous and a.flags.writeable


def test_history_callback_and_early_stop(case):
    seen = []

    def callback(info):
        seen.append(info["iteration"])
        return info["iteration"] < 7

    r = fm.fit(
        case["template_vertices"],
        case["faces"],
        case["scan"],
        callback=callback,
        params=dict(snapshot_every=3),
    )
    assert seen == list(range(1, 8)) and r.iterations == 7
    assert r.diagnostics["stopped_by_callback"]
    assert [i for i, _ in r.snapshots] == [3, 6]
    assert r.history["mean_displacement"].shape == (7,)


def test_callback_exception_propagates(case):
    def boom(info):
        raise KeyError("from callback")

    with pytest.raises(KeyError, match="from callback"):
        fm.fit(case["template_vertices"], case["faces"], case["scan"], callback=boom)


def test_tolerance_stops_early(case):
    r = fm.fit(case["template_vertices"], case["faces"], case["scan"], params=dict(tolerance=1e-3))
    assert r.diagnostics["converged"] and r.iterations < 100
    assert r.history["mean_displacement"][-1] < 1e-3


def test_literal_readings_stay_reachable(case):
    r = fm.fit(
        case["template_vertices"],
        case["faces"],
        case["scan"],
        iterations=5,
        params=dict(
            numerator="literal",
            summation="sum",
            damping_mode="force",
            velocity_sync=False,
            regularization="log_euclidean",
        ),
    )
    assert r.params["numerator"] == "literal" and r.params["velocity_sync"] is False


def test_trimesh_objects_are_accepted(case):
    trimesh = pytest.importorskip("trimesh")
    tmpl = trimesh.Trimesh(case["template_vertices"], case["faces"], process=False)
    scan = trimesh.PointCloud(case["scan"])
    r = fm.fit(tmpl, target=scan, iterations=5)
    mesh = r.to_trimesh()
    assert len(mesh.vertices) == len(tmpl.vertices)
    assert mesh.visual.vertex_colors.shape == (len(tmpl.vertices), 4)


# ---- bad input ----------------------------------------------------------------------------

SMALL = fm.folded_sheet(nx=6, ny=6)


def small(**over):
    args = {"template": SMALL["template_vertices"], "template_faces": SMALL["faces"], "target": SMALL["scan"]}
    args.update(over)
    return args


@pytest.mark.parametrize(
    "over, match",
    [
        ({"template": np.zeros((0, 3))}, "at least one point"),
        ({"target": np.zeros((5, 2))}, r"shape \(n, 3\)"),
        ({"template_faces": np.array([[0, 1, 99]])}, "refers to vertex 99"),
        ({"template_faces": np.array([[0, -1, 2]])}, "refers to vertex -1"),
        ({"template_faces": np.array([[0.5, 1, 2]])}, "integers"),
    ],
)
def test_bad_arrays_raise_invalid_input(over, match):
    with pytest.raises(fm.InvalidInputError, match=match):
        fm.fit(**small(**over))


def test_nan_names_the_row():
    v = SMALL["template_vertices"].copy()
    v[7, 1] = np.nan
    with pytest.raises(ValueError, match="template_vertices: non-finite coordinate at row 7"):
        fm.fit(**small(template=v))
    x = SMALL["scan"].copy()
    x[3, 0] = np.inf
    with pytest.raises(fm.InvalidInputError, match="target: non-finite coordinate at row 3"):
        fm.fit(**small(target=x))


@pytest.mark.parametrize(
    "param, value",
    [
        ("iterations", -1),
        ("rings", 0),
        ("rings", 9),
        ("rho", 0.0),
        ("damping", 1.5),
        ("softening", -1.0),
        ("psi", float("nan")),
        ("method", "cpd"),
        ("k_min", 0),
    ],
)
def test_parameters_out_of_range(param, value):
    with pytest.raises(fm.InvalidParameterError):
        fm.fit(**small(), params={param: value})


def test_degenerate_and_duplicate_faces_are_reported_and_skipped():
    f = np.vstack([SMALL["faces"], [[0, 0, 1], SMALL["faces"][3][::-1]]])
    r = fm.fit(**small(template_faces=f), iterations=5)
    n = len(SMALL["faces"])
    assert r.diagnostics["degenerate_faces"] == [n]
    assert r.diagnostics["duplicate_faces"] == [n + 1]
    assert np.isfinite(r.vertices).all()


def test_isolated_vertex_follows_its_particle():
    v = np.vstack([SMALL["template_vertices"], [[0.0, 0.0, 0.05]]])
    r = fm.fit(**small(template=v), iterations=10)
    assert r.diagnostics["isolated_vertices"] == 1
    assert np.isfinite(r.vertices).all()
    assert np.linalg.norm(r.vertices[-1] - v[-1]) > 0


def test_far_away_template_is_refused_or_prealigned():
    far = SMALL["template_vertices"] + np.array([100.0, 0, 0])
    with pytest.raises(fm.InvalidInputError, match="diagonals from the scan"):
        fm.fit(**small(template=far), prealign="none")
    for mode in ("centroid", "rigid"):
        r = fm.fit(**small(template=far), prealign=mode, iterations=20)
        assert np.abs(r.vertices.mean(0) - SMALL["scan"].mean(0)).max() < 0.05
    # The default pre-alignment is the rigid search: the far template is found without asking.
    r = fm.fit(**small(template=far), iterations=20)
    assert r.params.prealign == "rigid"
    assert np.abs(r.vertices.mean(0) - SMALL["scan"].mean(0)).max() < 0.05


def test_a_template_in_other_units_is_refused_by_the_rigid_prealignment():
    # In millimetres against a scan in metres: no rigid motion places it; the error says so and
    # names the remedy, which places it.
    mm = 1000.0 * SMALL["template_vertices"]
    with pytest.raises(fm.InvalidInputError, match=r"diagonal is 9\d\d\.\d+ times the scan's.*similarity"):
        fm.fit(**small(template=mm), iterations=5)
    r = fm.fit(**small(template=mm), prealign="similarity", iterations=20)
    assert np.abs(r.vertices.mean(0) - SMALL["scan"].mean(0)).max() < 0.05


def _turned(points, axis, degrees, shift):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    t = np.radians(degrees)
    r = np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * (k @ k)
    return points @ r.T + shift


def test_rigid_prealign_fits_a_turned_scan_in_the_scan_frame():
    # The demo sheet's scan turned 60° about an oblique axis and shifted by three diagonals:
    # the default prealign="rigid" lands as close to the moved truth as the fit of the unmoved scan does to
    # the truth, and its vertices lie in the scan's frame as given.
    # (A flat rectangle is symmetric: on a gently folded scan several of its readings score
    # alike and the turn is ambiguous, docs/method.md "Global pre-alignment"; folds of 0.1 let
    # the scan's shape decide.)
    case = fm.folded_sheet(nx=25, ny=17, scan_points=2000, noise=0.002, seed=3, fold_amplitude=0.1)
    v, f, x, g = case["template_vertices"], case["faces"], case["scan"], case["ground_truth"]
    shift = 3.0 * (x.max(0) - x.min(0))  # far enough for prealign="none" to refuse it
    base = fm.fit(v, f, x, iterations=60)
    moved = fm.fit(v, f, _turned(x, [1, 2, -1.5], 60, shift), iterations=60)
    err = np.sqrt(((base.vertices - g) ** 2).sum(1).mean())
    err_moved = np.sqrt(((moved.vertices - _turned(g, [1, 2, -1.5], 60, shift)) ** 2).sum(1).mean())
    assert err_moved < 1.25 * err
    # What the search did is in the diagnostics: searched and moved, with the orientations that
    # fit alike (a flat rectangle has several); nothing when it did not run.
    p = moved.diagnostics["prealign"]
    assert p["searched"] and p["moved"] and p["readings"] >= 1 and p["score"] < p["identity_score"]
    assert fm.fit(v, f, x, iterations=2, prealign="none").diagnostics["prealign"] is None
    with pytest.raises(fm.InvalidInputError, match="diagonals from the scan"):
        fm.fit(v, f, _turned(x, [1, 2, -1.5], 60, shift), prealign="none", iterations=5)


def test_similarity_prealign_fits_a_scan_in_millimetres():
    # The folded truth's vertices as the scan, turned and shifted, once in metres (placed by
    # prealign="rigid") and once in millimetres (prealign="similarity"): the similarity finds
    # the units, so both fits land on the truth alike, within issue 27's 1.25× (measured on the
    # harness by `python -m bench.prealign`).
    case = fm.folded_sheet(nx=25, ny=17, seed=3)
    v, f, g = case["template_vertices"], case["faces"], case["ground_truth"]
    truth = _turned(g, [1, 2, -1.5], 60, np.array([0.3, -0.2, 0.05]))
    metres = fm.fit(v, f, truth, prealign="rigid", iterations=60)
    mm = fm.fit(v, f, 1000.0 * truth, prealign="similarity", iterations=60)
    err = np.sqrt(((metres.vertices - truth) ** 2).sum(1).mean())
    err_mm = np.sqrt(((mm.vertices / 1000.0 - truth) ** 2).sum(1).mean())
    assert err_mm < 1.25 * err
    # Without the similarity the millimetre scan is refused: no rigid motion places it.
    with pytest.raises(fm.InvalidInputError, match="times the scan's"):
        fm.fit(v, f, 1000.0 * truth, prealign="rigid", iterations=60)
    a = fm.prealign(v, 1000.0 * g, motion="similarity")
    assert a["searched"] and abs(a["scale"] / 1000.0 - 1) < 0.05 and a["readings"] >= 1
    a = fm.prealign(v, v + 0.001)  # placed already: its half turns searched, kept as given
    assert a["searched"] and np.array_equal(a["rotation"], np.eye(3)) and a["scale"] == 1.0
    assert np.array_equal(a["translation"], np.zeros(3))
    with pytest.raises(fm.InvalidParameterError, match="motion"):
        fm.prealign(v, g, motion="affine")


def test_errors_are_typed_subclasses():
    assert issubclass(fm.InvalidInputError, ValueError)
    assert issubclass(fm.InvalidParameterError, ValueError)
    assert issubclass(fm.MeshFileError, OSError)
    assert issubclass(fm.NumericalError, RuntimeError)
    assert issubclass(fm.InternalError, fm.FoldMatchError)


def test_knn_slack_spares_queries_in_the_early_phases_only():
    """knn_slack (default 0.1) makes the rigid and coarse phases' neighbourhoods
    (1 + σ)-approximate: fewer fresh k-d tree queries there, the same fit quality, and with
    no rigid or coarse phase (the paper preset: FoldMatch iterations only) nothing changes."""
    far = fm.folded_sheet(nx=N, ny=N, scan_points=3000, rotation_degrees=10.0, offset=(0.05, 0, 0.3))
    args = (far["template_vertices"], far["faces"], far["scan"])
    assert fm.DEFAULT_PARAMS["knn_slack"] == 0.1
    exact = fm.fit(*args, params=dict(selection="single", knn_slack=0.0))
    slack = {s: fm.fit(*args, params=dict(selection="single", knn_slack=s)) for s in (0.1, 0.5)}
    assert (
        exact.diagnostics["knn_queries"]
        > slack[0.1].diagnostics["knn_queries"]
        > slack[0.5].diagnostics["knn_queries"]
    )
    for r in slack.values():
        assert not np.array_equal(r.vertices, exact.vertices)
        assert rmse(r.vertices, far["ground_truth"]) < 1.2 * rmse(exact.vertices, far["ground_truth"])
    paper = [fm.fit(*args, preset="paper", iterations=20, params=dict(knn_slack=s)) for s in (0.0, 0.5)]
    np.testing.assert_array_equal(paper[0].vertices, paper[1].vertices)
    with pytest.raises(fm.InvalidParameterError, match="knn_slack"):
        fm.fit(*args, params=dict(knn_slack=1.5))


def scan_distance(x, y):
    """Brute-force mean distance from every scan point to its nearest fitted vertex."""
    return float(np.sqrt(((x[:, None, :] - y[None, :, :]) ** 2).sum(-1).min(1)).mean())


def edge_spread(template, fitted_vertices, faces):
    """Standard deviation of the log edge-length ratios over the unique edges (NumPy)."""
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    e = np.unique(e, axis=0)
    rest = np.linalg.norm(template[e[:, 0]] - template[e[:, 1]], axis=1)
    now = np.linalg.norm(fitted_vertices[e[:, 0]] - fitted_vertices[e[:, 1]], axis=1)
    return float(np.std(np.log(now / rest)))


def selected(distances, spreads, margin):
    """Schedule selection's rule: the least spread among the fits within the margin of the
    closest one (the earlier on ties)."""
    tied = [i for i, d in enumerate(distances) if d <= (1 + margin) * min(distances)]
    return min(tied, key=lambda i: (spreads[i], i))


def test_accurate_preset_is_the_default_with_150_iterations_and_every_fit_freed(case):
    """preset="accurate" is the default with 150 iterations and every unstretched fit refined
    to the template's metric: the same parameters otherwise, and the same fit as asking the
    default for those two."""
    v, f, x = case["template_vertices"], case["faces"], case["scan"]
    r = fm.fit(v, f, x, preset="accurate")
    freed = {"iterations": 150, "unstretched_refinement": "every_fit"}
    assert r.params == {**fm.DEFAULT_PARAMS, **freed}
    assert r.iterations == 150
    same = fm.fit(v, f, x, iterations=150, params={"unstretched_refinement": "every_fit"})
    np.testing.assert_array_equal(r.vertices, same.vertices)


def test_wide_selection_selects_among_three_schedules(case):
    """selection="scan_distance_wide" fits the given, sharp and gentle (⅔ two-way, longer
    annealing) schedules and keeps the one the selection rule picks from brute-force scan→fit
    distances and NumPy edge-length spreads; each equals its single run."""
    v, f, x = case["template_vertices"], case["faces"], case["scan"]
    # The schedules alone: the candidates are compared before the isometric refinement.
    r = fm.fit(
        v,
        f,
        x,
        iterations=20,
        params=dict(selection="scan_distance_wide", rigid_sample=1, isometric_iterations=0),
    )
    single = fm.FitParams(iterations=20, selection="single", rigid_sample=1, isometric_iterations=0)
    alone = [
        fm.fit(v, f, x, params=single),
        fm.fit(
            v, f, x, params=single.replace(two_way=1.0, coarse_fraction=0.3, anneal=1.0, anneal_fraction=0.0)
        ),
        fm.fit(
            v, f, x, params=single.replace(two_way=fm.DEFAULT_PARAMS["two_way"] / 1.5, anneal_fraction=0.8)
        ),
    ]

    d = [scan_distance(x, a.vertices) for a in alone]
    spreads = [edge_spread(v, a.vertices, f) for a in alone]
    np.testing.assert_allclose(r.diagnostics["candidate_scan_distances"], d, rtol=1e-12)
    np.testing.assert_allclose(r.diagnostics["candidate_edge_spreads"], spreads, rtol=1e-9)
    best = selected(d, spreads, r.params["selection_margin"])
    assert r.diagnostics["schedule"] == ["given", "sharp", "gentle"][best]
    np.testing.assert_array_equal(r.vertices, alone[best].vertices)
    assert r.params["selection"] == "scan_distance_wide"


def test_wall_seconds_split_the_call(case):
    """Setup, iterations and finish are timed inside the call: each one measured (positive),
    together within the wall time measured around it. (Which part is the largest is a
    matter for the benchmarks: under load, a 40-iteration fit's setup has taken longer than
    its iterations.)"""
    import time

    t0 = time.perf_counter()
    r = fm.fit(
        case["template_vertices"],
        case["faces"],
        case["scan"],
        iterations=40,
        params={"isometric_iterations": 0},
    )
    wall = time.perf_counter() - t0
    setup, iterations, finish = r.diagnostics["wall_seconds"]
    assert min(setup, iterations, finish) > 0 and setup + iterations + finish <= wall


def test_paper_preset_is_the_method_as_printed(case):
    r = fm.fit(case["template_vertices"], case["faces"], case["scan"], preset="paper", iterations=5)
    assert r.params["two_way"] == 0 and r.params["rigid_fraction"] == 0
    assert r.params["coarse_fraction"] == 0 and r.params["rings"] == 2
    assert r.params["anneal"] == 1 and r.params["rest_rigidity"] == 0
    with pytest.raises(fm.InvalidParameterError, match="preset"):
        fm.fit(case["template_vertices"], case["faces"], case["scan"], preset="turbo")


def test_two_way_pull_sums_by_default_and_the_mean_stays_reachable(case):
    """The default combines the two-way pulls by coverage (their sum × M / N), weight 4.5; the
    previous rule (their mean) and the tracking preset's are reachable and fit differently."""
    v, f, x = case["template_vertices"], case["faces"], case["scan"]
    default = fm.fit(v, f, x, iterations=20, params=dict(selection="single"))
    mean = fm.fit(v, f, x, iterations=20, params=dict(selection="single", two_way_pull="mean"))
    assert default.params["two_way_pull"] == "coverage" and default.params["two_way"] == 4.5
    assert mean.params["two_way_pull"] == "mean"
    assert np.abs(default.vertices - mean.vertices).max() > 1e-6
    tracking = fm.fit(v, f, x, iterations=2, preset="tracking")
    assert tracking.params["two_way_pull"] == "mean"
    with pytest.raises(fm.InvalidParameterError, match="two_way_pull"):
        fm.fit(v, f, x, iterations=2, params=dict(two_way_pull="sum"))


def test_gil_is_released_during_the_fit(case):
    """A Python thread keeps running while the core computes."""
    import threading
    import time

    ticks = []
    done = threading.Event()

    def ticker():
        while not done.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=ticker)
    t.start()
    start = time.perf_counter()
    fm.fit(case["template_vertices"], case["faces"], case["scan"], iterations=60, preset="paper")
    end = time.perf_counter()
    done.set()
    t.join()
    during = [x for x in ticks if start < x < end]
    # With the GIL held for the whole fit the ticker could not run at all in between.
    assert len(during) > 0.2 * (end - start) / 0.002, (len(during), end - start)


def test_selection_keeps_the_closer_schedule_or_on_a_near_tie_the_less_stretched(case):
    """The default fits the given and the sharp schedule and keeps the one whose mean
    scan→nearest-fitted-vertex distance is lower, or, within the 6 % margin, the one whose
    edge lengths spread less from the template's (checked against brute-force NumPy figures);
    margin 0 keeps the closer; each candidate equals the single-schedule fit run on its
    own."""
    v, f, x = case["template_vertices"], case["faces"], case["scan"]
    # From the placement as given (the margins below pick both schedules from there); the
    # schedules alone (the candidates are compared before the isometric refinement, and
    # before any coherent candidate, docs/method.md "Coherent candidate").
    alone = dict(isometric_iterations=0, coherent_gate=0.0)
    chosen = fm.fit(v, f, x, iterations=30, prealign="none", params=alone)
    given = fm.fit(v, f, x, iterations=30, prealign="none", params=dict(selection="single", **alone))
    sharp = fm.fit(
        v,
        f,
        x,
        iterations=30,
        prealign="none",
        params=dict(
            selection="single", two_way=1.0, coarse_fraction=0.3, anneal=1.0, anneal_fraction=0.0, **alone
        ),
    )

    want = [scan_distance(x, given.vertices), scan_distance(x, sharp.vertices)]
    got = chosen.diagnostics["candidate_scan_distances"]
    np.testing.assert_allclose(got, want, rtol=1e-12)
    spreads = [edge_spread(v, r.vertices, f) for r in (given, sharp)]
    np.testing.assert_allclose(chosen.diagnostics["candidate_edge_spreads"], spreads, rtol=1e-9)
    assert chosen.params["selection_margin"] == 0.06
    picks = set()
    for margin in (0.06, 0.0, 0.1):
        result = (
            chosen
            if margin == 0.06
            else fm.fit(
                v,
                f,
                x,
                iterations=30,
                prealign="none",
                params=dict(selection_margin=margin, **alone),
            )
        )
        k = selected(want, spreads, margin)
        assert result.diagnostics["schedule"] == ("given", "sharp")[k]
        np.testing.assert_array_equal(result.vertices, (given, sharp)[k].vertices)
        picks.add(k)
    assert picks == {0, 1}, "the margins tried should pick both schedules on this case"
    assert given.diagnostics["candidate_scan_distances"] == []
    with pytest.raises(fm.InvalidParameterError, match="selection_margin"):
        fm.fit(v, f, x, iterations=2, params=dict(selection_margin=-0.1))
    with pytest.raises(fm.InvalidParameterError, match="selection"):
        fm.fit(v, f, x, iterations=2, params=dict(selection="best"))


def test_rigid_sample_moves_the_template_rigidly(case):
    """rigid_sample drives the rigid phase by a vertex sample: a rigid-only fit keeps every
    pairwise distance (NumPy, 300 random pairs) and lands near the fit driven by every vertex,
    without equalling it; out-of-range values are refused by name."""
    v, f, x = case["template_vertices"], case["faces"], case["scan"]
    rigid_only = dict(
        iterations=8, rigid_fraction=1.0, coarse_fraction=0.0, selection="single", isometric_iterations=0
    )
    sampled = fm.fit(v, f, x, prealign="none", params=dict(rigid_sample=4, **rigid_only)).vertices
    full = fm.fit(v, f, x, prealign="none", params=dict(rigid_sample=1, **rigid_only)).vertices
    rng = np.random.default_rng(5)
    i, j = rng.integers(0, len(v), 300), rng.integers(0, len(v), 300)
    d_start = np.linalg.norm(v[i] - v[j], axis=1)
    d_fit = np.linalg.norm(sampled[i] - sampled[j], axis=1)
    np.testing.assert_allclose(d_fit, d_start, atol=1e-12)
    apart = np.linalg.norm(sampled - full, axis=1).max()
    moved = np.linalg.norm(full - v, axis=1).mean()
    assert 0 < apart < 0.2 * moved
    for bad in (0, 65):
        with pytest.raises(fm.InvalidParameterError, match="rigid_sample"):
            fm.fit(v, f, x, iterations=2, params=dict(rigid_sample=bad))
        with pytest.raises(fm.InvalidParameterError, match="coarse_sample"):
            fm.fit(v, f, x, iterations=2, params=dict(coarse_sample=bad))
    with pytest.raises(fm.InvalidParameterError, match="coarse_sample"):
        fm.fit(v, f, x, iterations=2, params=dict(coarse_sample=2, coarse_rings=2))


def test_rigid_scan_sample_strides_only_dense_scans(case):
    """The rigid phase's two-way pulls come from every s-th scan point only where the scan has
    more than 8 points per rigid-phase vertex (rigid_scan_sample=0, automatic): on the module's
    case (3000 points over 421 sampled vertices) that is every point, the same fit as
    rigid_scan_sample=1; on a dense scan it is a stride, which changes the fit but not its
    accuracy."""
    args = (case["template_vertices"], case["faces"], case["scan"])
    auto = fm.fit(*args, iterations=40)
    every = fm.fit(*args, iterations=40, params=dict(rigid_scan_sample=1))
    np.testing.assert_array_equal(auto.vertices, every.vertices)

    dense = fm.folded_sheet(nx=15, ny=15, scan_points=12000, noise=0.001)
    dargs = (dense["template_vertices"], dense["faces"], dense["scan"])

    def f_r(vertices):
        return fm.evaluate(*dargs[:2], vertices, dense["scan"], ground_truth=dense["ground_truth"])["f_R"]

    strided, full = fm.fit(*dargs), fm.fit(*dargs, params=dict(rigid_scan_sample=1))
    assert np.abs(strided.vertices - full.vertices).max() > 1e-9
    assert f_r(strided.vertices) < 0.5 * f_r(dense["template_vertices"])
    # No less accurate (here the strided fit is the closer one: 0.0260 against 0.0270).
    assert f_r(strided.vertices) < 1.05 * f_r(full.vertices)
    with pytest.raises(fm.InvalidParameterError, match="rigid_scan_sample"):
        fm.fit(*args, params=dict(rigid_scan_sample=65))


def test_coarse_scan_sample_halves_only_dense_scans(case):
    """The coarse phase sees every 2nd scan point only where the scan has at least 8 points
    per vertex (coarse_scan_sample=0, automatic): the module's case (3000 points, 1681
    vertices) is fitted as with coarse_scan_sample=1; dense scans are fitted differently, and
    as accurately on the whole (small templates' fits move either way by up to ~10 %:
    measured 0.92-1.13 on 20 such sheets, geometric mean 1.003)."""
    args = (case["template_vertices"], case["faces"], case["scan"])
    np.testing.assert_array_equal(
        fm.fit(*args, iterations=40).vertices,
        fm.fit(*args, iterations=40, params=dict(coarse_scan_sample=1)).vertices,
    )
    ratios = []
    for side, per_vertex in [(15, 18), (20, 10), (25, 12), (30, 8), (40, 10)]:
        dense = fm.folded_sheet(nx=side, ny=side, scan_points=side * side * per_vertex, noise=0.001)
        dargs = (dense["template_vertices"], dense["faces"], dense["scan"])

        def f_r(vertices, dense=dense, dargs=dargs):
            return fm.evaluate(*dargs[:2], vertices, dense["scan"], ground_truth=dense["ground_truth"])["f_R"]

        halved, full = fm.fit(*dargs), fm.fit(*dargs, params=dict(coarse_scan_sample=1))
        np.testing.assert_array_equal(
            halved.vertices,
            fm.fit(
                *dargs,
                params=dict(coarse_scan_sample=2),
            ).vertices,
        )
        assert np.abs(halved.vertices - full.vertices).max() > 1e-9
        assert f_r(halved.vertices) < 0.5 * f_r(dense["template_vertices"])
        ratios.append(f_r(halved.vertices) / f_r(full.vertices))
    assert max(ratios) < 1.2 and np.exp(np.log(ratios).mean()) < 1.05, ratios
    with pytest.raises(fm.InvalidParameterError, match="coarse_scan_sample"):
        fm.fit(*args, params=dict(coarse_scan_sample=65))


def test_rest_rigidity_keeps_edge_lengths_over_a_scan_hole(case):
    """The rest-shape rigidity (default 0.5) blends each FoldMatch update with the rigid
    placement of the vertex's template ring: over a hole cut out of the scan the fitted edge
    lengths stay closer to the template's (NumPy measure: spread of log length ratios), and the
    fit is no further from the truth; 0 is the update without it."""
    scan = case["scan"]
    center = case["ground_truth"][N * (N // 2) + N // 3]
    holed = scan[np.linalg.norm(scan - center, axis=1) > 0.15]
    v, f = case["template_vertices"], case["faces"]
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])

    def length(x):
        return np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1)

    def spread(vertices):
        return float(np.log(length(vertices) / length(v)).std())

    with_rigidity = fm.fit(v, f, holed)
    without = fm.fit(v, f, holed, params=dict(rest_rigidity=0.0))
    assert with_rigidity.params["rest_rigidity"] == 0.65
    assert spread(with_rigidity.vertices) < 0.8 * spread(without.vertices)
    truth = case["ground_truth"]
    assert rmse(with_rigidity.vertices, truth) < 1.05 * rmse(without.vertices, truth)
    with pytest.raises(fm.InvalidParameterError, match="rest_rigidity"):
        fm.fit(v, f, holed, params=dict(rest_rigidity=1.5))


def _tube(radius, around=64, rows=25):
    """An open tube along y (height 0.8), ``radius(y)`` its radius: vertices and faces."""
    y = np.repeat(np.linspace(0.0, 0.8, rows), around)
    t = np.tile(np.arange(around) * 2 * np.pi / around, rows)
    v = np.stack([radius(y) * np.cos(t), y, radius(y) * np.sin(t)], axis=1)
    j, i = np.meshgrid(np.arange(rows - 1), np.arange(around), indexing="ij")
    a = (j * around + i).ravel()
    b = (j * around + (i + 1) % around).ravel()
    f = np.concatenate([np.stack([a, b, b + around], 1), np.stack([a, b + around, a + around], 1)])
    return v, f.astype(np.int64)


def test_carry_unsupported_keeps_the_back_of_a_one_sided_scan():
    """A tube scanned from its front (x > 0) only: the default (``carry_unsupported`` 2) keeps
    the unscanned back in its place behind the front, closer to the truth than the fit with
    the setting off, which pulls it onto the front; the result reports it unsupported, and
    the verdict, which leaves the carried vertices out of its fit → scan distance, finds the
    fit ok."""
    v, f = _tube(lambda y: np.full_like(y, 0.3))
    truth, _ = _tube(lambda y: 0.3 * (1 + 0.25 * y))
    rng = np.random.default_rng(3)
    tri = truth[f]
    idx = rng.integers(0, len(f), 12000)
    u, w = rng.random((2, 12000, 1))
    flip = (u + w) > 1
    u, w = np.where(flip, 1 - u, u), np.where(flip, 1 - w, w)
    scan = tri[idx, 0] + u * (tri[idx, 1] - tri[idx, 0]) + w * (tri[idx, 2] - tri[idx, 0])
    scan = scan[scan[:, 0] > 0]
    back = v[:, 0] < -0.15
    attracted = fm.fit(v, f, scan, params={"carry_unsupported": 0.0})
    carried = fm.fit(v, f, scan)
    assert carried.params["carry_unsupported"] == 2.0 and attracted.params["carry_unsupported"] == 0.0
    assert rmse(carried.vertices[back], truth[back]) < 0.65 * rmse(attracted.vertices[back], truth[back])
    assert carried.vertices[back, 0].mean() < -0.15
    assert np.mean(~np.asarray(carried.support)[back]) > 0.9
    q = carried.quality
    everyone = float(np.mean(carried.residuals)) / q["scan_diagonal"]
    # The carried vertices count as unsupported, but the verdict's test of the share leaves
    # them out: about half of a tube seen from one side is unseen.
    assert 0.25 < q["carried_share"] <= q["unsupported_share"], q
    assert q["verdict"] == "ok", q
    assert q["fit_to_scan"] < 0.7 * everyone, (q["fit_to_scan"], everyone)
    # fm.assess knows nothing of what the fit carried: all vertices count.
    again = fm.assess(v, f, carried.vertices, scan)["quality"]
    assert math.isclose(again["fit_to_scan"], everyone, rel_tol=1e-9)
    assert again["carried_share"] == 0.0
    with pytest.raises(fm.InvalidParameterError, match="carry_unsupported"):
        fm.fit(v, f, scan, params={"carry_unsupported": -1.0})


def test_fast_preset_is_one_schedule_between_the_default_s_two(case):
    """preset="fast" runs one schedule: the default's parameters with the sharp candidate's
    phases and constant softening and a two-way weight of 3 (between the candidates' 1 and
    4.5), without the isometric refinement or the coherent candidate; the same fit as asking for
    those parameters, and
    not either candidate's fit."""
    v, f, x = case["template_vertices"], case["faces"], case["scan"]
    r = fm.fit(v, f, x, preset="fast", iterations=30)
    mine = {
        "selection": "single",
        "two_way": 3.0,
        "coarse_fraction": 0.3,
        "anneal": 1.0,
        "anneal_fraction": 0.0,
        "iterations": 30,
        "isometric_iterations": 0,
        "isometric_hold": 0.0,
        "coherent_gate": 0.0,
    }
    assert r.params == {**fm.DEFAULT_PARAMS, **mine}
    np.testing.assert_array_equal(r.vertices, fm.fit(v, f, x, params=mine).vertices)
    both = fm.fit(v, f, x, iterations=30)
    d = float(np.mean([np.sqrt(((r.vertices - p) ** 2).sum(1).min()) for p in x]))
    assert all(abs(c - d) > 1e-9 * d for c in both.diagnostics["candidate_scan_distances"])


def test_target_weights_mask_equals_the_masked_scan_and_bad_weights_are_refused():
    case = fm.folded_sheet(nx=15, ny=15, scan_points=600, noise=0.002)
    v, f, x = case["template_vertices"], case["faces"], case["scan"]
    mask = np.arange(len(x)) % 4 != 0
    masked = fm.fit(v, f, x, target_weights=mask, iterations=20)
    subset = fm.fit(v, f, x[mask], iterations=20)
    np.testing.assert_array_equal(masked.vertices, subset.vertices)
    plain = fm.fit(v, f, x, iterations=20)
    equal = fm.fit(v, f, x, target_weights=np.full(len(x), 2.5), iterations=20)
    np.testing.assert_array_equal(equal.vertices, plain.vertices)
    for bad, where in [
        (np.ones(3), "one weight per scan point"),
        (-np.ones(len(x)), "target_weights[0]"),
        (np.zeros(len(x)), "all zero"),
        (np.full(len(x), np.nan), "target_weights[0]"),
    ]:
        with pytest.raises(fm.errors.InvalidParameterError, match=re.escape(where)):
            fm.fit(v, f, x, target_weights=bad)
    with pytest.raises(fm.errors.InvalidInputError, match="target_weights"):
        fm.fit(v, f, x, target_weights=np.ones((len(x), 1)))


#: src/fit/mod.rs READING_MARGIN: the other reading's fit replaces the least turned one only when
#: it lies this much closer to the scan.
READING_MARGIN = 0.04


def _fitted_turned(name, kind, move="turn90"):
    """The real harness case `name` (`kind`: "mesh" or "points") fitted with the default as
    given and with its scan turned about the vertical by `move` (bench/prealign.py's): both
    results, the moved arrays, and f_R turned ÷ as given. Skips without ../shared/data."""
    from bench import cases, prealign

    why = cases.real_data_missing()
    if why:
        pytest.skip(why)
    case = next(c for c in cases.real_cases(kinds=(kind,)) if c.name == name)
    moved = prealign.moved(case, prealign.RIGID[move])
    base = fm.fit(case.template_vertices, case.faces, case.target)
    turned = fm.fit(moved["template_vertices"], moved["faces"], moved["target"])
    rms = lambda v, g: np.sqrt(((np.asarray(v) - g) ** 2).sum(1).mean())  # noqa: E731
    ratio = rms(turned.vertices, moved["ground_truth"]) / rms(base.vertices, case.ground_truth)
    return base, turned, moved, ratio


def test_a_garment_turned_90_degrees_is_not_fitted_back_to_front():
    """A real T-shirt scan turned 90° about the vertical: its two readings (±90°, front and back
    swapped) score alike rigidly, and the least turned one is back to front (f_R 0.37 against
    0.0098 unmoved). They are other shapes of the template (not its symmetric images), so both
    are fitted and the closer one kept (docs/method.md "Global pre-alignment")."""
    base, turned, _, ratio = _fitted_turned("vto-tshirt-arm-mesh", "mesh")
    assert ratio <= 1.25, ratio
    p = turned.diagnostics["prealign"]
    assert p["moved"] and p["fitted_readings"] == 2
    # The wrong reading's fit ended clearly farther from the scan (11 % on this case).
    assert p["reading_gap"] >= READING_MARGIN, p["reading_gap"]
    assert base.diagnostics["prealign"]["fitted_readings"] in (0, 1)
    assert base.diagnostics["prealign"]["reading_gap"] is None


def test_a_garment_whose_two_readings_tie_says_so():
    """The T-shirt's point scan turned 180° about the vertical: fitted front to front and back to
    front, the two fits lie within 2 % of each other's distance to the scan, and the least
    turned reading — back to front — is kept (f_R 0.37 against 0.011 unmoved: what no figure
    without ground truth tells apart, docs/method.md "Global pre-alignment"). The result says
    that its two readings tie (`reading_gap` below the margin), and the CLI prints a note."""
    _, turned, _, _ = _fitted_turned("vto-tshirt-0000-pts", "points", move="turn180")
    p = turned.diagnostics["prealign"]
    assert p["fitted_readings"] == 2
    assert abs(p["reading_gap"]) < READING_MARGIN, p["reading_gap"]


@pytest.mark.parametrize(
    ("name", "bound", "off_above"),
    [
        # The VTO T-shirt: 7.2× with the setting off (the back collapsed onto the front), 1.79×
        # without the border band (CARRY_BAND), 1.44× with it.
        ("vto-tshirt-0000-pts", 1.6, 4.0),
        # The penetrating skirt: 1.83× with the refinement's springs at their given weight,
        # 1.48× three times as stiff (CARRIED_SPRING_FACTOR), 1.23× with the border band,
        # 1.11× with no fit → scan match for the carried back in the refinement; 4.2× with the
        # setting off.
        ("skirt-penetrate-pts", 1.18, 3.0),
        # The small skirt: 5.6× without the border band, 4.4× with it, 3.6× with the carried
        # back unmatched in the refinement (issue 27's 2× not met); its back collapses (13×)
        # with the setting off.
        ("skirt-small-pts", 4.0, 8.0),
    ],
)
def test_the_back_of_a_real_garment_scanned_from_the_front_is_carried(name, bound, off_above):
    """A real garment as one camera rig on its front sees it (bench/front_scan.py): the default
    carries the unseen back and ends within `bound` × its fit of the whole scan (issue 27's
    figure: 2), far closer than with the setting off, and reports a fifth to two fifths of the
    vertices unsupported (docs/method.md "Partial scans")."""
    from bench import cases
    from bench.partial import half_scan

    why = cases.real_data_missing()
    if why:
        pytest.skip(why)
    case = next(c for c in cases.real_cases(kinds=("points",)) if c.name == name)
    half = half_scan(case)
    rms = lambda v: np.sqrt(((np.asarray(v) - case.ground_truth) ** 2).sum(1).mean())  # noqa: E731
    whole = rms(fm.fit(case.template_vertices, case.faces, case.target).vertices)
    carried = fm.fit(case.template_vertices, case.faces, half)
    attracted = fm.fit(case.template_vertices, case.faces, half, params={"carry_unsupported": 0.0})
    assert rms(carried.vertices) <= bound * whole, (rms(carried.vertices), whole)
    assert rms(attracted.vertices) > off_above * whole
    assert 0.15 < 1.0 - np.mean(carried.support) < 0.4


def test_a_wind_frame_blown_flat_and_turned_carries_nothing():
    """A DiffCloth wind frame blown nearly flat (``wind-150-pts``), its scan turned 90° about the
    vertical: the rigid phase leaves a fifth of the template a few units off the scan, over
    points its other layer explains — a region the one-sided rule would carry, which then let a
    wrong reading win (f_R 24× the unmoved fit's). Its depth behind the scanned side is too
    small for a garment's back (``CARRY_MIN_BEHIND``): nothing is carried and the fit is within
    1.25× of the unmoved one, as with the setting off."""
    _, turned, moved, ratio = _fitted_turned("wind-150-pts", "points")
    assert ratio <= 1.25, ratio
    off = fm.fit(
        moved["template_vertices"], moved["faces"], moved["target"], params={"carry_unsupported": 0.0}
    )
    np.testing.assert_array_equal(turned.vertices, off.vertices)


def test_the_scan_s_unit_does_not_change_the_similarity_fit():
    """The flattened DiffCloth T-shirt's scan in three units (×0.5, ×2, ×1000 of the template's)
    fitted with prealign="similarity": the same fit, up to the unit. The search starts the
    template's own orientation as it starts the principal-frame candidates (centroids and RMS
    radii matched); started where the template lay, at its own size, it placed the ×2 scan
    5° from the others and that fit ended 1.3× as far from the truth."""
    from bench import cases

    why = cases.real_data_missing()
    if why:
        pytest.skip(why)
    case = next(c for c in cases.real_cases(kinds=("mesh",)) if c.name == "tshirt-flattened-mesh")
    fits = {
        unit: fm.fit(
            case.template_vertices,
            case.faces,
            unit * case.target,
            target_faces=case.target_faces,
            prealign="similarity",
        )
        for unit in (0.5, 2.0, 1000.0)
    }
    for unit, r in fits.items():
        np.testing.assert_allclose(r.vertices / unit, fits[0.5].vertices / 0.5, rtol=0, atol=1e-9)
        assert r.diagnostics["prealign"]["searched"]


def test_the_similarity_s_scale_is_corrected_by_the_cloth_s_stretch():
    """The flattened DiffCloth T-shirt's scan given at half size: the similarity of its shape
    places the template at 0.84 of its size, and the fit from there stretched the cloth by
    about 23 %; scaled by that and fitted again, it ends within 1.25× of the fit of the scan as
    given (2.16× from the similarity's scale alone; docs/method.md "Global pre-alignment")."""
    from bench import cases, prealign

    why = cases.real_data_missing()
    if why:
        pytest.skip(why)
    case = next(c for c in cases.real_cases(kinds=("points",)) if c.name == "tshirt-flattened-pts")
    half = prealign.moved(case, prealign.SCALED["half"])
    base = fm.fit(case.template_vertices, case.faces, case.target)
    scaled = fm.fit(half["template_vertices"], half["faces"], half["target"], prealign="similarity")
    stretch = scaled.diagnostics["prealign"]["scale_stretch"]
    assert 1.03 < stretch <= 1.25, stretch
    rms = lambda v, g: np.sqrt(((np.asarray(v) - g) ** 2).sum(1).mean())  # noqa: E731
    # f_R is relative to the scan's diagonal: the half-size scan's truth is half as far.
    ratio = 2.0 * rms(scaled.vertices, half["ground_truth"]) / rms(base.vertices, case.ground_truth)
    assert ratio <= 1.25, ratio
    assert base.diagnostics["prealign"]["scale_stretch"] == 1.0
