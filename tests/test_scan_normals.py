"""Scan normals (`target_normals=`, `foldmatch fit --scan-normals`): a scanner's own normals as
the planes of the final isometric refinement (docs/guide.md "Scan normals")."""

from __future__ import annotations

import pathlib

import foldmatch_rs as fm
import numpy as np
import pytest
from test_cli import run, write_ply


def _vertex_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    n = np.zeros_like(v)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    for k in range(3):
        np.add.at(n, f[:, k], fn)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


@pytest.fixture(scope="module")
def case():
    """A folded sheet scanned with noise, and each scan point's normal: the truth's vertex
    normal nearest it (what a scanner's normal estimates)."""
    c = fm.folded_sheet(nx=25, ny=17, scan_points=2500, noise=0.004, seed=5, fold_amplitude=0.12)
    truth, scan = c["ground_truth"], c["scan"]
    nearest = np.argmin(((scan[:, None, :] - truth[None, :, :]) ** 2).sum(-1), axis=1)
    c["normals"] = _vertex_normals(truth, c["faces"])[nearest]
    return c


def _f_r(c, **kw) -> tuple[float, np.ndarray]:
    r = fm.fit(c["template_vertices"], c["faces"], c["scan"], **kw)
    v = np.asarray(r.vertices)
    return float(np.sqrt(((v - c["ground_truth"]) ** 2).sum(1).mean())), v


def test_the_scan_s_normals_are_the_refinement_s_planes(case):
    """Right normals fit as well as the planes the fit estimates itself; normals turned into the
    surface (each replaced by a tangent) pull the vertices along the sheet and fit worse (8 %); the
    normals' sign does not matter (a plane is the same either way)."""
    plain, _ = _f_r(case)
    right, fitted = _f_r(case, target_normals=case["normals"])
    tangent = np.cross(case["normals"], [0.3, 0.5, 0.81])
    wrong, _ = _f_r(case, target_normals=tangent)
    flipped, fitted_flipped = _f_r(case, target_normals=-case["normals"])
    assert right <= 1.05 * plain, (right, plain)
    assert wrong > 1.05 * right, (wrong, right)
    np.testing.assert_allclose(fitted_flipped, fitted, atol=1e-9)
    assert flipped == pytest.approx(right, rel=1e-9)


def test_bad_normals_are_refused_naming_the_row(case):
    n = case["normals"].copy()
    with pytest.raises(fm.InvalidInputError, match="one per scan point"):
        fm.fit(case["template_vertices"], case["faces"], case["scan"], target_normals=n[:-1])
    n[7] = 0.0
    with pytest.raises(fm.InvalidParameterError, match=r"target_normals\[7\]"):
        fm.fit(case["template_vertices"], case["faces"], case["scan"], target_normals=n)


def _write_ply_with_normals(path: pathlib.Path, points: np.ndarray, normals: np.ndarray) -> None:
    lines = ["ply", "format ascii 1.0", f"element vertex {len(points)}"]
    lines += [f"property double {a}" for a in ("x", "y", "z", "nx", "ny", "nz")]
    lines.append("end_header")
    lines += [" ".join(repr(float(c)) for c in (*p, *n)) for p, n in zip(points, normals)]
    path.write_text("\n".join(lines) + "\n")


def test_the_file_s_own_normals_are_read_with_true(case, tmp_path):
    """``target_normals=True`` takes a PLY scan's ``nx ny nz``: the same fit as passing them; a
    file without normals is refused with a message that says so."""
    _write_ply_with_normals(tmp_path / "scan.ply", case["scan"], case["normals"])
    tv, f = case["template_vertices"], case["faces"]
    from_file = fm.fit(tv, f, tmp_path / "scan.ply", target_normals=True, iterations=10)
    given = fm.fit(tv, f, case["scan"], target_normals=case["normals"], iterations=10)
    np.testing.assert_allclose(from_file.vertices, given.vertices, atol=1e-12)
    write_ply(tmp_path / "bare.ply", case["scan"])
    with pytest.raises(fm.InvalidInputError, match="no vertex normals"):
        fm.fit(tv, f, tmp_path / "bare.ply", target_normals=True)


def test_the_cli_uses_the_scan_s_normals_when_asked(case, tmp_path):
    """`foldmatch fit --scan-normals`: with a PLY's normals the fit is the Python one's; a scan
    without normals fails with exit status 1, naming the file."""
    write_ply(tmp_path / "template.ply", case["template_vertices"], case["faces"])
    _write_ply_with_normals(tmp_path / "scan.ply", case["scan"], case["normals"])
    write_ply(tmp_path / "bare.ply", case["scan"])
    out = run("fit", "template.ply", "scan.ply", "-o", "fit.ply", "--scan-normals", "--ascii", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    fitted = fm.fit(case["template_vertices"], case["faces"], case["scan"], target_normals=case["normals"])
    lines = (tmp_path / "fit.ply").read_text().splitlines()
    start = lines.index("end_header") + 1
    rows = lines[start : start + len(fitted.vertices)]
    got = np.array([[float(x) for x in line.split()[:3]] for line in rows])
    np.testing.assert_allclose(got, fitted.vertices, atol=1e-9)
    out = run("fit", "template.ply", "bare.ply", "-o", "fit2.ply", "--scan-normals", cwd=tmp_path)
    assert out.returncode == 1
    assert "bare.ply" in out.stderr and "no vertex normals" in out.stderr
