"""foldmatch_rs.evaluate against an independent brute-force NumPy reference (SPEC §3).

The reference below is written for readability, not speed: every nearest-neighbour distance is
an O(N·M) broadcast, every face is classified with plain array arithmetic. Sizes are kept small
(a few hundred points) so that this stays fast.

Definitions (all in the user's units; Y template, Ŷ fitted, X target, G ground truth):
  f_H      = D_H(X, Ŷ) / D_H(X, Y), D_H the symmetric Hausdorff distance of point sets
             (0 when both are 0, +inf when only the denominator is 0)
  f_S/E/F  = fractions of non-degenerate template faces with area ratio area(Ŷ)/area(Y) < 0.02,
             > 2.0, and with n·n̂ < 0; a template face is degenerate when its area is
             <= 1e-12 · diag(bbox(Y))²; no evaluable face → 0 and left out of f_λ
  f_R      = sqrt(mean ‖Ŷ_i − G_i‖²) / diag(bbox(X)), None without ground truth
  f_lambda = mean of the available terms, named in f_lambda_terms
  chamfer  = ½ (scan_to_fit_mean + fit_to_scan_mean), point to point, not squared
"""

import math

import foldmatch_rs
import numpy as np
import pytest

TAU_S = 0.02
TAU_E = 2.0
DEGENERATE_AREA_REL = 1e-12

METRIC_KEYS = [
    "f_H",
    "f_S",
    "f_E",
    "f_F",
    "f_R",
    "f_lambda",
    "f_lambda_terms",
    "chamfer",
    "scan_to_fit_mean",
    "scan_to_fit_p95",
    "fit_to_scan_mean",
    "hausdorff_before",
    "hausdorff_after",
]
FLOAT_KEYS = [k for k in METRIC_KEYS if k not in ("f_R", "f_lambda_terms")]


# --------------------------------------------------------------------------------------------
# Reference implementation
# --------------------------------------------------------------------------------------------


def nearest_distances(a, b):
    """Distance from every row of `a` to the nearest row of `b` (brute force, O(len(a)·len(b)))."""
    diff = a[:, None, :] - b[None, :, :]
    return np.sqrt((diff**2).sum(axis=-1)).min(axis=1)


def hausdorff(a, b):
    """Symmetric Hausdorff distance between two point sets."""
    return max(nearest_distances(a, b).max(), nearest_distances(b, a).max())


def bbox_diagonal(points):
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


def face_cross(vertices, faces):
    """(b − a) × (c − a) per face: the normal scaled by twice the area."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return np.cross(b - a, c - a)


def safe_ratio(num, den):
    if den > 0:
        return num / den
    return 0.0 if num == 0 else math.inf


def reference_metrics(template, faces, fitted, target, ground_truth=None):
    """Every metric of SPEC §3, computed the slow and obvious way."""
    hausdorff_before = hausdorff(target, template)
    hausdorff_after = hausdorff(target, fitted)
    f_h = safe_ratio(hausdorff_after, hausdorff_before)

    scan_to_fit = nearest_distances(target, fitted)
    fit_to_scan = nearest_distances(fitted, target)

    # Faces: drop degenerate template faces, then classify the rest.
    n_template = face_cross(template, faces)
    n_fitted = face_cross(fitted, faces)
    area_template = 0.5 * np.linalg.norm(n_template, axis=1)
    area_fitted = 0.5 * np.linalg.norm(n_fitted, axis=1)
    keep = area_template > DEGENERATE_AREA_REL * bbox_diagonal(template) ** 2
    ratio = area_fitted[keep] / area_template[keep]
    flipped = (n_template[keep] * n_fitted[keep]).sum(axis=1) < 0
    n_eval = int(keep.sum())
    if n_eval > 0:
        f_s = float(np.mean(ratio < TAU_S))
        f_e = float(np.mean(ratio > TAU_E))
        f_f = float(np.mean(flipped))
    else:
        f_s = f_e = f_f = 0.0

    f_r = None
    if ground_truth is not None:
        rmse = math.sqrt(np.mean(((fitted - ground_truth) ** 2).sum(axis=1)))
        f_r = safe_ratio(rmse, bbox_diagonal(target))

    terms = {"f_H": f_h}
    if n_eval > 0:
        terms.update(f_S=f_s, f_E=f_e, f_F=f_f)
    if f_r is not None:
        terms["f_R"] = f_r

    return {
        "f_H": f_h,
        "f_S": f_s,
        "f_E": f_e,
        "f_F": f_f,
        "f_R": f_r,
        "f_lambda": sum(terms.values()) / len(terms),
        "f_lambda_terms": list(terms),
        "chamfer": 0.5 * (scan_to_fit.mean() + fit_to_scan.mean()),
        "scan_to_fit_mean": scan_to_fit.mean(),
        "scan_to_fit_p95": np.percentile(scan_to_fit, 95),  # linear interpolation
        "fit_to_scan_mean": fit_to_scan.mean(),
        "hausdorff_before": hausdorff_before,
        "hausdorff_after": hausdorff_after,
    }


# --------------------------------------------------------------------------------------------
# Test data
# --------------------------------------------------------------------------------------------


def grid_mesh(rng, nx, ny):
    """A unit square in the xy-plane, (nx × ny) vertices with small z noise, two triangles/cell."""
    xs, ys = np.meshgrid(np.linspace(0, 1, nx), np.linspace(0, 1, ny))
    vertices = np.stack([xs.ravel(), ys.ravel(), rng.uniform(-0.02, 0.02, nx * ny)], axis=1)
    faces = []
    for j in range(ny - 1):
        for i in range(nx - 1):
            a = j * nx + i
            b, c, d = a + 1, a + nx, a + nx + 1
            faces += [[a, b, d], [a, d, c]]
    return vertices, np.array(faces, dtype=np.int64)


def random_case(seed, with_ground_truth):
    rng = np.random.default_rng(seed)
    template, faces = grid_mesh(rng, 10 + seed % 4, 8)
    # A degenerate face (repeated index) that must be excluded.
    faces = np.vstack([faces, [[0, 0, 1]]])
    # Noise large enough for expanded and flipped faces; snapping a few vertices onto a
    # neighbour collapses the faces on that edge.
    fitted = template + rng.uniform(-0.1, 0.1, template.shape)
    for k in (11, 23, 31):
        fitted[k] = fitted[k + 1]
    fitted = fitted @ np.diag([1.2, 0.9, 1.0]) + [0.05, -0.1, 0.2]
    target = rng.normal(scale=0.6, size=(300 + 17 * seed, 3))
    ground_truth = fitted + rng.normal(scale=0.05, size=fitted.shape) if with_ground_truth else None
    return template, faces, fitted, target, ground_truth


def call(template, faces, fitted, target, ground_truth=None):
    return foldmatch_rs.evaluate(template, faces, fitted, target, ground_truth=ground_truth)


def assert_metrics_close(got, want):
    for key in FLOAT_KEYS:
        np.testing.assert_allclose(got[key], want[key], rtol=1e-10, atol=1e-14, err_msg=key)
    if want["f_R"] is None:
        assert got["f_R"] is None
    else:
        np.testing.assert_allclose(got["f_R"], want["f_R"], rtol=1e-10, err_msg="f_R")
    assert list(got["f_lambda_terms"]) == want["f_lambda_terms"]


TRIANGLE = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
TRIANGLE_FACES = np.array([[0, 1, 2]], dtype=np.int64)


# --------------------------------------------------------------------------------------------
# Tests
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("with_ground_truth", [False, True])
def test_matches_reference_on_random_meshes(seed, with_ground_truth):
    template, faces, fitted, target, ground_truth = random_case(seed, with_ground_truth)
    want = reference_metrics(template, faces, fitted, target, ground_truth)
    got = call(template, faces, fitted, target, ground_truth)
    assert_metrics_close(got, want)
    # The case is not trivial: every face class occurs.
    assert 0 < want["f_S"] < 1 and 0 < want["f_E"] < 1 and 0 < want["f_F"] < 1


def test_returns_a_dict_with_every_key():
    template, faces, fitted, target, _ = random_case(0, False)
    got = call(template, faces, fitted, target)
    assert isinstance(got, dict)
    assert set(METRIC_KEYS) <= set(got)
    for key in FLOAT_KEYS:
        assert isinstance(got[key], float), key
    assert got["f_R"] is None
    assert all(isinstance(t, str) for t in got["f_lambda_terms"])


def test_accepts_uint32_faces_and_lists():
    template, faces, fitted, target, gt = random_case(1, True)
    want = call(template, faces, fitted, target, gt)
    got = call(template.tolist(), faces.astype(np.uint32), fitted.tolist(), target.tolist(), gt.tolist())
    assert_metrics_close(got, want)


def test_scaled_triangle_is_expanded():
    # Scaling by 3 multiplies the area by 9 > τ_E.
    got = call(TRIANGLE, TRIANGLE_FACES, 3.0 * TRIANGLE, TRIANGLE)
    assert (got["f_S"], got["f_E"], got["f_F"]) == (0.0, 1.0, 0.0)


def test_shrunk_triangle_is_collapsed():
    # Scaling by 0.1 multiplies the area by 0.01 < τ_S.
    got = call(TRIANGLE, TRIANGLE_FACES, 0.1 * TRIANGLE, TRIANGLE)
    assert (got["f_S"], got["f_E"], got["f_F"]) == (1.0, 0.0, 0.0)


def test_mirrored_triangle_is_flipped():
    mirrored = TRIANGLE * [-1.0, 1.0, 1.0]
    got = call(TRIANGLE, TRIANGLE_FACES, mirrored, TRIANGLE)
    assert (got["f_S"], got["f_E"], got["f_F"]) == (0.0, 0.0, 1.0)


def test_identical_fit_and_template():
    template, faces, _, target, _ = random_case(2, False)
    got = call(template, faces, template, target)
    assert (got["f_S"], got["f_E"], got["f_F"]) == (0.0, 0.0, 0.0)
    assert got["f_H"] == 1.0
    assert got["hausdorff_before"] == got["hausdorff_after"]
    assert list(got["f_lambda_terms"]) == ["f_H", "f_S", "f_E", "f_F"]
    assert got["f_lambda"] == pytest.approx(0.25)


def test_fit_onto_target_has_zero_distances():
    template, faces, _, _, _ = random_case(3, False)
    fitted = template + [0.0, 0.0, 0.5]
    got = call(template, faces, fitted, fitted)
    assert got["f_H"] == 0.0
    for key in ("chamfer", "scan_to_fit_mean", "scan_to_fit_p95", "fit_to_scan_mean", "hausdorff_after"):
        assert got[key] == 0.0, key
    assert got["hausdorff_before"] == pytest.approx(0.5, rel=1e-12)


def test_template_already_on_target():
    # D_H(X, Y) = 0: f_H = 0 when the fit stays, +inf when it moves away.
    got = call(TRIANGLE, TRIANGLE_FACES, TRIANGLE, TRIANGLE)
    assert got["f_H"] == 0.0
    got = call(TRIANGLE, TRIANGLE_FACES, TRIANGLE + [0.0, 0.0, 0.1], TRIANGLE)
    assert got["f_H"] == math.inf


def test_ground_truth_rmse_is_normalized_by_target_diagonal():
    target = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.3, 0.9, 0.1]])  # diagonal √3
    ground_truth = TRIANGLE + [2.0, 0.0, 0.0]
    fitted = ground_truth + [0.0, 0.3, 0.4]  # every vertex 0.5 away: RMSE 0.5
    got = call(TRIANGLE, TRIANGLE_FACES, fitted, target, ground_truth)
    assert got["f_R"] == pytest.approx(0.5 / math.sqrt(3.0), rel=1e-12)
    assert list(got["f_lambda_terms"])[-1] == "f_R"
    terms = [got[name] for name in got["f_lambda_terms"]]
    assert got["f_lambda"] == pytest.approx(sum(terms) / len(terms), rel=1e-12)
    got = call(TRIANGLE, TRIANGLE_FACES, ground_truth, target, ground_truth)
    assert got["f_R"] == 0.0


def test_degenerate_faces_are_excluded():
    vertices = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    fitted = vertices * [1.0, 10.0, 1.0]
    # [0,1,2] is collinear and [1,1,3] repeats an index: only [0,1,3] counts (area ×10).
    faces = np.array([[0, 1, 2], [1, 1, 3], [0, 1, 3]], dtype=np.int64)
    got = call(vertices, faces, fitted, vertices)
    assert (got["f_S"], got["f_E"], got["f_F"]) == (0.0, 1.0, 0.0)


@pytest.mark.parametrize(
    "faces",
    [np.zeros((0, 3), dtype=np.int64), np.array([[0, 1, 2], [1, 1, 3]], dtype=np.int64)],
    ids=["no-faces", "all-degenerate"],
)
def test_without_evaluable_faces_only_f_h_is_averaged(faces):
    vertices = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    target = vertices + [0.0, 0.0, 1.0]
    got = call(vertices, faces, vertices + [0.0, 0.0, 0.5], target)
    assert (got["f_S"], got["f_E"], got["f_F"]) == (0.0, 0.0, 0.0)
    assert list(got["f_lambda_terms"]) == ["f_H"]
    assert got["f_lambda"] == got["f_H"] == pytest.approx(0.5)


def test_shape_errors():
    template, faces, fitted, target, gt = random_case(4, True)
    with pytest.raises(ValueError):
        call(template, faces, fitted[:-1], target)  # one fitted vertex too few
    with pytest.raises(ValueError):
        call(template, faces, fitted, target, gt[:-1])  # ground truth too short
    with pytest.raises(ValueError):
        call(template, faces, fitted, target[:0])  # empty target
    with pytest.raises(ValueError):
        call(template, faces, fitted[:, :2], target)  # not (M, 3)
    bad_faces = faces.copy()
    bad_faces[0, 0] = len(template)
    with pytest.raises(ValueError):
        call(template, bad_faces, fitted, target)  # face index out of range
    bad = fitted.copy()
    bad[3, 1] = np.nan
    with pytest.raises(ValueError):
        call(template, faces, bad, target)  # NaN coordinate


def test_target_weights_leave_out_the_points_of_weight_zero():
    # The fit lies on the garment's points; 30 "body" points lie 0.5 above it. With the garment
    # mask as target_weights the figures are the garment's alone, as fm.fit measures them.
    template, faces, _, _, _ = random_case(5, False)
    fitted = template + [0.0, 0.0, 0.5]
    body = fitted[:30] + [0.0, 0.0, 0.5]
    scan = np.vstack([fitted, body])
    mask = np.r_[np.ones(len(fitted)), np.zeros(len(body))]
    garment = foldmatch_rs.evaluate(template, faces, fitted, fitted, ground_truth=fitted)
    for w in (mask, 3.0 * mask, mask.astype(bool), mask.astype(np.float32)):
        got = foldmatch_rs.evaluate(template, faces, fitted, scan, ground_truth=fitted, target_weights=w)
        assert got == garment
    whole = foldmatch_rs.evaluate(template, faces, fitted, scan, ground_truth=fitted)
    assert whole["scan_to_fit_mean"] > 0.0 and whole["target_diagonal"] > garment["target_diagonal"]
    for bad, match in (
        (mask[1:], "need one weight per scan point"),
        (np.where(mask > 0, 1.0, -1.0), r"target_weights\[{}\]".format(len(fitted))),
        (np.zeros(len(scan)), "all zero"),
    ):
        with pytest.raises(ValueError, match=match):
            foldmatch_rs.evaluate(template, faces, fitted, scan, target_weights=bad)
