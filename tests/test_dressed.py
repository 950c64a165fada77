"""bench/dressed_scans.py's dressed-body scans (issue 26): one case built from ../shared/data (the
ARCSim T-shirt frame 0000 on its body), checked for what a scanner would give: enough points,
labels that say which surface a point lies on, the skin under the shirt hidden, the stated
noise, and the same scan for the same seed."""

from __future__ import annotations

import pathlib
import zlib

import numpy as np
import pytest

from bench import cases, dressed_scans

REPO = pathlib.Path(__file__).resolve().parent.parent

SIGMA = dressed_scans.SCANNER["noise"]  # metres; the ARCSim source is in metres


def built_source(name: str, seed: int = 0) -> dict:
    """bench/dressed_scans.py's source ``name`` built afresh for scanner seed ``seed``; the test
    is skipped when ../shared/data is missing."""
    why = cases.real_data_missing()
    if why:
        pytest.skip(why)
    return dressed_scans.build_source(name, seed=seed, cache=False)


@pytest.fixture(scope="module")
def tshirt(request):
    built = built_source("tshirt-0000")
    return dressed_scans.load_source("tshirt-0000"), built


def boundary_vertices(f: np.ndarray) -> np.ndarray:
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(e, axis=0, return_counts=True)
    return np.unique(uniq[count == 1])


def test_scan_is_dense_and_labelled(tshirt):
    src, built = tshirt
    pts, lab = built["scan"], built["labels"]
    assert len(pts) >= 40_000
    assert len(lab) == len(pts) and set(np.unique(lab)) == {0, 1}
    assert built["meta"]["scan"]["cameras"] == 24
    # Each point lies on the surface its label names: closer to it than to the other one.
    bv, bf = src["body"]
    pick = np.random.default_rng(0).choice(len(pts), 15_000, replace=False)
    pts, lab = pts[pick], lab[pick]
    on_body = np.linalg.norm(pts - dressed_scans.closest_on_mesh(pts, bv, bf)[2], axis=1)
    on_shirt = np.linalg.norm(pts - dressed_scans.closest_on_mesh(pts, src["truth"], src["faces"])[2], axis=1)
    garment = lab > 0
    # ≤ 5σ from its own surface (isotropic noise: the normal component is N(0, σ²))
    assert np.mean(np.where(garment, on_shirt, on_body) < 5 * SIGMA) > 0.995
    assert np.mean(np.where(garment, on_shirt <= on_body, on_body <= on_shirt)) > 0.98
    # The noise is the stated one: RMS distance to the own surface ≈ σ.
    d = np.where(garment, on_shirt, on_body)
    assert 0.8 * SIGMA < np.sqrt(np.mean(d[d < 5 * SIGMA] ** 2)) < 1.3 * SIGMA
    # The template / starts are the source's, placed onto the truth.
    assert built["placed"].shape == built["truth"].shape == src["template"].shape
    assert dressed_scans.rms(built["placed"], built["truth"]) < dressed_scans.rms(
        built["unplaced"], built["truth"]
    )


def test_skin_under_the_shirt_is_not_scanned(tshirt):
    src, built = tshirt
    from scipy.spatial import cKDTree

    bv, bf = src["body"]
    gv, gf = src["truth"], src["faces"]
    # Body vertices the shirt covers: within 4 cm of it, more than 15 cm from its hem, collar
    # and cuffs (no camera looks through a 2 cm gap that far in).
    near = np.linalg.norm(bv - dressed_scans.closest_on_mesh(bv, gv, gf)[2], axis=1) < 0.04
    rim = gv[boundary_vertices(gf)]
    far_from_rim = cKDTree(rim).query(bv)[0] > 0.15
    hidden = near & far_from_rim
    assert hidden.sum() > 300  # the chest, the back, the belly
    body_pts = built["scan"][built["labels"] == 0]
    d_hidden = cKDTree(body_pts).query(bv[hidden])[0]
    assert (d_hidden > 0.015).all(), "a camera saw skin under the shirt"
    # ... while the uncovered skin (far from the shirt) is scanned nearly everywhere.
    exposed = ~near & (cKDTree(gv).query(bv)[0] > 0.10)
    assert exposed.sum() > 1000
    assert np.mean(cKDTree(body_pts).query(bv[exposed])[0] < 0.015) > 0.8
    # The garment mask is the scan's garment points, and the body-free scan drops the others.
    whole = dressed_scans.make_case("tshirt-0000", built, "whole")
    free = dressed_scans.make_case("tshirt-0000", built, "body-free")
    assert whole.mask.sum() == len(free.target) == built["meta"]["scan"]["garment_points"]
    assert (free.labels > 0).all()


def test_same_seed_same_scan_other_seed_other_scan(tshirt):
    src, built = tshirt
    # The case's scan seed is a fixed function of its name and --seed (not Python's hash()).
    assert built["meta"]["scan"]["seed"] == zlib.crc32(b"tshirt-0000/0")
    # The scanner (a smaller rig, for speed): the same seed gives the same points and labels,
    # another seed other cameras, noise and holes.
    small = {**dressed_scans.SCANNER, "rings": 1, "azimuths": 4}
    meshes = [(*src["body"], 0), (src["truth"], src["faces"], 1)]
    a, b, c = (dressed_scans.scan(meshes, 1.0, seed, settings=small) for seed in (5, 5, 6))
    assert np.array_equal(a.points, b.points) and np.array_equal(a.labels, b.labels)
    assert a.info["hole_centres"] != c.info["hole_centres"]
    assert len(a.points) != len(c.points) or not np.array_equal(a.points, c.points)


def test_transfer_between_identical_bodies_is_the_identity(tshirt):
    src, _ = tshirt
    bv, bf = src["body"]
    rng = np.random.default_rng(3)
    pts = bv[rng.choice(len(bv), 200)] + rng.normal(scale=0.02, size=(200, 3))
    assert np.allclose(dressed_scans.transfer_to_body(pts, (bv, bf), (bv, bf), 1.0), pts, atol=1e-9)
    # A rigidly moved and scaled body carries the points along (offsets scaled by `scale`).
    r = cases.rotation_matrix([0.2, 1.0, 0.1], 30.0)
    moved = bv @ r.T + [0.1, 0.2, 0.3]
    out = dressed_scans.transfer_to_body(pts, (bv, bf), (moved, bf), 1.0)
    assert np.allclose(out, pts @ r.T + [0.1, 0.2, 0.3], atol=1e-9)


def test_the_default_fits_the_shirt_of_a_dressed_scan_almost_as_without_the_body(tshirt):
    """Issue 26's figure on the tuning scan: the default's whole-scan fit (garment refit and
    cut on) within 1.25× of its fit of the same scan without the body points, and within 0.8×
    of the placed template's error; without the refit it is not (1.46×). As before the isometric
    refinement (100 iterations without it), the garment cut brings it within 1.1×, where the
    refit alone ends 1.16×."""
    import foldmatch_rs as fm

    _, built = tshirt
    tpl, faces, scan, labels, truth = (built[k] for k in ("placed", "faces", "scan", "labels", "truth"))
    whole = fm.fit(tpl, faces, scan)
    free = fm.fit(tpl, faces, scan[labels > 0])
    once = fm.fit(tpl, faces, scan, params={"garment_refit": 0.0})
    rms = dressed_scans.rms
    assert 0 < whole.diagnostics["garment_refit_points"] < len(scan)
    assert free.diagnostics["garment_refit_points"] == once.diagnostics["garment_refit_points"] == 0
    # Taken for a dressed scan (set for the garment passes) only where the body is there and
    # the passes are on; such a fit never gets the coherent candidate (CPD would draw the
    # template onto the body too).
    assert whole.diagnostics["dressed"]
    assert not free.diagnostics["dressed"] and not once.diagnostics["dressed"]
    assert whole.diagnostics["coherent"] is None
    # The fit's own segmentation: the points of its last pass, nearly all the shirt's and
    # nearly no skin (measured 99.7 % of the shirt, 0.7 % skin); none without a refit.
    taken = whole.garment_points
    assert taken.dtype == np.uint32 and len(taken) == whole.diagnostics["garment_refit_points"]
    assert np.all(np.diff(taken.astype(np.int64)) > 0) and taken[-1] < len(scan)
    assert np.mean(labels[taken] == 0) < 0.02
    assert np.isin(np.flatnonzero(labels > 0), taken).mean() > 0.98
    assert len(free.garment_points) == len(once.garment_points) == 0
    ratio = rms(whole.vertices, truth) / rms(free.vertices, truth)
    assert ratio <= 1.25, ratio
    assert rms(whole.vertices, truth) <= 0.8 * rms(tpl, truth)
    assert rms(once.vertices, truth) / rms(free.vertices, truth) > 1.25
    assert ratio <= 1.1, ratio
    plain = {"isometric_iterations": 0, "iterations": 100}
    free, cut = fm.fit(tpl, faces, scan[labels > 0], params=plain), fm.fit(tpl, faces, scan, params=plain)
    uncut = fm.fit(tpl, faces, scan, params={"garment_cut": 0.0, **plain})
    assert rms(cut.vertices, truth) / rms(free.vertices, truth) <= 1.1
    assert rms(uncut.vertices, truth) / rms(free.vertices, truth) > 1.1


def test_a_roughly_placed_garment_in_a_dressed_scan_is_not_moved_elsewhere():
    """The pre-alignment in a scene larger than the garment (docs/method.md "Global
    pre-alignment"): the T-shirt template turned by 10° and shifted by 5 % of its diagonal on the
    held-out scan (seed 1) lies on the scan just too far to count as placed, and the search's
    best two-sided score — mostly the body's points — was 52° away (the fit then ended 200 mm
    off). A placement elsewhere is taken only when the template itself lies on the scan at
    least twice as close there."""
    import foldmatch_rs as fm

    built = built_source("tshirt-0000", seed=1)
    got = fm.prealign(built["unplaced"], built["scan"], motion="rigid")
    assert got["searched"]
    assert np.allclose(got["rotation"], np.eye(3)) and np.allclose(got["translation"], 0.0)


def test_each_garment_of_two_ends_near_its_fit_alone():
    """Issue 26's two-garment figure (the held-out case of bench/dressed.py): a shirt + skirt
    template on one dressed-body scan, each garment fitted on its own (docs/method.md "Several
    garments"); the shirt ends within 1.25× of its fit alone onto its own garment's points
    (measured 1.08×; 1.70× when the garments were fitted together, 1.20× when each garment's
    passes took their points again by the placed template, and the bound here is 1.15), and the
    whole template closer to the truth than as placed."""
    import foldmatch_rs as fm

    built = built_source("two-garment")
    tpl, faces, scan, labels, truth, parts = (
        built[k] for k in ("placed", "faces", "scan", "labels", "truth", "template_labels")
    )
    rms = dressed_scans.rms
    whole = fm.fit(tpl, faces, scan)
    assert len(whole.diagnostics["components"]) == 2
    assert rms(whole.vertices, truth) < 0.8 * rms(tpl, truth)
    # Each garment's points, taken together (measured: 99.9 % of both, 0.4 % skin).
    taken = whole.garment_points
    assert np.all(np.diff(taken.astype(np.int64)) > 0)
    for garment in (1, 2):
        assert np.isin(np.flatnonzero(labels == garment), taken).mean() > 0.98
    assert np.mean(labels[taken] == 0) < 0.02
    shirt = np.flatnonzero(parts == 1)
    remap = np.full(len(tpl), -1)
    remap[shirt] = np.arange(len(shirt))
    shirt_faces = remap[faces[np.all(parts[faces] == 1, axis=1)]]
    alone = fm.fit(tpl[shirt], shirt_faces, scan[labels == 1])
    ratio = rms(whole.vertices[shirt], truth[shirt]) / rms(alone.vertices, truth[shirt])
    assert ratio <= 1.15, ratio


def test_a_garment_mask_on_a_two_garment_scan_fits_as_the_body_removed():
    """Points of weight 0 are removed (docs/method.md "Scan weights"): the two-garment template
    fitted onto the whole scan with the garment mask as ``target_weights`` ends exactly where
    its fit of the body-free scan does, unplaced start included (the garments' free edges were
    judged on the masked body's points too: 22.2 against 21.4 mm)."""
    import foldmatch_rs as fm

    built = built_source("two-garment")
    faces, scan, labels = built["faces"], built["scan"], built["labels"]
    garment = labels > 0
    for start in ("placed", "unplaced"):
        tpl = built[start]
        masked = fm.fit(tpl, faces, scan, target_weights=garment.astype(np.float64))
        removed = fm.fit(tpl, faces, scan[garment])
        np.testing.assert_allclose(masked.vertices, removed.vertices, rtol=0, atol=1e-9)


def test_eight_landmarks_halve_the_bent_over_frames_error():
    """Issue 27's landmark figure on the bent-over T-shirt frame 0200 (`python -m
    bench.landmarks`): with 8 landmarks (farthest-point template vertices, targets the truth plus
    the scanner's noise) the default's f_R on the whole dressed scan falls below half its f_R
    without them, and the landmark vertices end within the scan's noise of their targets."""
    from bench import landmarks

    built = built_source("tshirt-0200")
    row = landmarks.fit_case("tshirt-0200", built, "placed", 8, None, {}, 0, lambda _: None)
    assert row["ratio"] < 0.5, row["ratio"]
    assert row["landmark_gap_with"]["max"] <= row["noise_rms_length"], row["landmark_gap_with"]


def test_the_penetrating_skirt_of_a_dressed_scan_fits_as_without_the_body():
    """The Garment-Pattern-Generator skirt that penetrates its body (a tuning case of
    bench/dressed.py, placed start): the default's whole-scan fit no farther from the truth than
    its fit of the same scan without the body points (measured 0.89; 0.94 with the points past
    the free hem at one point's weight). The garment passes keep the pull of the scan past the
    skirt's free hem, which brings the skirt down from the torso's skin over its sunk waist
    (without it: 1.05); its first fit ends with the isometric
    refinement, so that the garment refit and cut are seeded by a fit whose slides are undone
    (without it: 1.22; docs/method.md "Scans of dressed people", "Free edges"). And within issue
    26's 0.8 of the placed template's own error (measured 0.77): its garment passes leave the
    skirt unstretched, and their refinement holds only where the scan has no points (0.92 with
    the hold everywhere; docs/method.md "Isometric refinement", unstretched garments)."""
    import foldmatch_rs as fm

    built = built_source("skirt-penetrate")
    tpl, faces, scan, labels, truth = (built[k] for k in ("placed", "faces", "scan", "labels", "truth"))
    whole = fm.fit(tpl, faces, scan)
    free = fm.fit(tpl, faces, scan[labels > 0])
    assert 0 < whole.diagnostics["garment_refit_points"] < len(scan)
    ratio = dressed_scans.rms(whole.vertices, truth) / dressed_scans.rms(free.vertices, truth)
    assert ratio <= 1.0, ratio
    to_start = dressed_scans.rms(whole.vertices, truth) / dressed_scans.rms(tpl, truth)
    assert to_start <= 0.8, to_start
