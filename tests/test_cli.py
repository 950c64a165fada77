"""The ``foldmatch`` command from Python: ``python -m foldmatch_rs`` and the ``foldmatch``
console script run the Rust CLI compiled into the extension (issue #3: one implementation)."""

from __future__ import annotations

import json
import os
import pathlib
import shutil
import subprocess
import sys

import foldmatch_rs as fm
import numpy as np
import pytest

ENV = {**os.environ, "FOLDMATCH_NO_PROGRESS": "1", "COLUMNS": "100"}


def run(*args: str, cwd: pathlib.Path, exe: tuple[str, ...] = (sys.executable, "-m", "foldmatch_rs")):
    return subprocess.run(
        [*exe, *args], check=False, cwd=cwd, env=ENV, capture_output=True, text=True, timeout=120
    )


def write_ply(path: pathlib.Path, vertices: np.ndarray, faces: np.ndarray | None = None) -> None:
    """A plain ASCII PLY (the test does not depend on trimesh)."""
    lines = [
        "ply",
        "format ascii 1.0",
        f"element vertex {len(vertices)}",
        "property double x",
        "property double y",
        "property double z",
    ]
    if faces is not None:
        lines += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
    lines.append("end_header")
    lines += [" ".join(repr(float(c)) for c in v) for v in vertices]
    if faces is not None:
        lines += ["3 " + " ".join(str(int(i)) for i in f) for f in faces]
    path.write_text("\n".join(lines) + "\n")


def write_labelled_ply(path: pathlib.Path, vertices: np.ndarray, labels: np.ndarray, name: str) -> None:
    """An ASCII PLY point cloud with a ``uchar`` per-vertex property (as segmenters write)."""
    lines = [
        "ply",
        "format ascii 1.0",
        f"element vertex {len(vertices)}",
        "property double x",
        "property double y",
        "property double z",
        f"property uchar {name}",
        "end_header",
    ]
    lines += [" ".join(repr(float(c)) for c in v) + f" {int(label)}" for v, label in zip(vertices, labels)]
    path.write_text("\n".join(lines) + "\n")


def dressed_scan(scan: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The garment scan with one other point (0.3 above) after every third garment point, and
    the 0/1 garment mask."""
    others = scan[::3] + np.array([0.0, 0.0, 0.3])
    points = np.concatenate([scan, others])
    order = np.argsort(np.concatenate([np.arange(len(scan)), np.arange(len(others)) * 3 + 2.5]))
    mask = np.concatenate([np.ones(len(scan), bool), np.zeros(len(others), bool)])
    return points[order], mask[order]


@pytest.fixture
def case(tmp_path):
    c = fm.folded_sheet(nx=12, ny=12, scan_points=300)
    write_ply(tmp_path / "template.ply", c["template_vertices"], c["faces"])
    write_ply(tmp_path / "scan.ply", c["scan"])
    return c


def test_help_lists_the_subcommands_and_exit_codes(tmp_path):
    out = run("--help", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("Fit a garment template mesh onto 3D scans")
    for word in ("fit", "batch", "sequence", "eval", "demo", "Exit status:", "130"):
        assert word in out.stdout
    assert "Usage: foldmatch [OPTIONS] <COMMAND>" in out.stdout


def test_a_tiny_fit(tmp_path, case):
    out = run(
        "fit",
        "template.ply",
        "scan.ply",
        "-o",
        "out/fitted.ply",
        "--iterations",
        "3",
        "--report",
        "report.json",
        cwd=tmp_path,
    )
    assert out.returncode == 0, out.stderr
    assert out.stderr.startswith("fitted scan.ply -> out/fitted.ply (3 iterations, ")
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["status"] == "ok"
    assert report["iterations"] == 3
    assert report["metrics"]["scan_to_fit_mean"] > 0
    header = (tmp_path / "out" / "fitted.ply").read_bytes()[:500].decode("ascii", "replace")
    assert "property double wvf_magnitude" in header
    assert f"element vertex {len(case['template_vertices'])}" in header


def test_a_closed_stderr_loses_the_log_not_the_run(tmp_path, case):
    """`foldmatch fit ... 2>&1 | head`: once the reader has quit, writing the log fails; the fit
    still runs, writes its output and exits with its own status, not a panic's (101)."""
    read, write = os.pipe()
    os.close(read)
    try:
        out = subprocess.run(
            [sys.executable, "-m", "foldmatch_rs", "fit", "template.ply", "scan.ply", "-o", "fitted.ply"]
            + ["--iterations", "3"],
            check=False,
            cwd=tmp_path,
            env=ENV,
            stdout=subprocess.DEVNULL,
            stderr=write,
            timeout=120,
        )
    finally:
        os.close(write)
    assert out.returncode == 0
    assert (tmp_path / "fitted.ply").stat().st_size > 0


def test_errors_name_the_file_and_exit_with_1(tmp_path, case):
    out = run("fit", "template.ply", "missing.ply", "-o", "o.ply", cwd=tmp_path)
    assert out.returncode == 1
    assert out.stderr == "error: missing.ply: No such file or directory (os error 2)\n"
    assert not (tmp_path / "o.ply").exists()
    out = run("fit", "template.ply", cwd=tmp_path)
    assert out.returncode == 1
    assert "required arguments were not provided" in out.stderr


def test_batch_partial_failure_exit_code(tmp_path, case):
    scans = tmp_path / "scans"
    scans.mkdir()
    shutil.copy(tmp_path / "scan.ply", scans / "good.ply")
    (scans / "empty.ply").write_bytes(b"")
    out = run("-q", "batch", "template.ply", "scans", "-o", "out", "--iterations", "2", cwd=tmp_path)
    assert out.returncode == 2, out.stderr
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert {f["name"]: f["status"] for f in report["files"]} == {
        "empty.ply": "error",
        "good.ply": "ok",
    }


def test_console_script_runs_the_same_cli(tmp_path):
    script = shutil.which("foldmatch", path=str(pathlib.Path(sys.executable).parent))
    if script is None:
        pytest.skip("the foldmatch console script is not installed next to this Python")
    out = run("--version", cwd=tmp_path, exe=(script,))
    assert out.returncode == 0
    assert out.stdout == f"foldmatch {fm.__version__}\n"


def test_console_script_takes_scan_weights_saved_by_numpy(tmp_path, case):
    """``foldmatch fit --scan-weights`` with arrays written by ``numpy.save``: a 0/1 mask (bool,
    or uint8 of shape (N, 1)) gives the masked scan's output byte for byte; float32 weights are
    accepted; weights of the wrong length are refused with one clean line and exit status 1."""
    script = shutil.which("foldmatch", path=str(pathlib.Path(sys.executable).parent))
    exe = (script,) if script is not None else (sys.executable, "-m", "foldmatch_rs")
    points, mask = dressed_scan(case["scan"])
    assert mask.sum() == 300 and len(points) == 400 and not mask[-1] and mask[0]
    write_ply(tmp_path / "dressed.ply", points)
    write_ply(tmp_path / "garment.ply", points[mask])
    np.save(tmp_path / "mask.npy", mask)
    np.save(tmp_path / "mask_u8.npy", mask.astype(np.uint8).reshape(-1, 1))
    np.save(tmp_path / "confidence.npy", np.linspace(0.5, 1.5, len(points), dtype=np.float32))
    np.save(tmp_path / "short.npy", np.ones(len(points) - 1))

    def fit(scan: str, out: str, *extra: str) -> subprocess.CompletedProcess:
        return run(
            "-q", "fit", "template.ply", scan, "-o", out, "--iterations", "5", *extra,
            cwd=tmp_path, exe=exe,
        )  # fmt: skip

    assert fit("garment.ply", "plain.ply").returncode == 0
    out = fit("dressed.ply", "masked.ply", "--scan-weights", "mask.npy", "--report", "r.json")
    assert out.returncode == 0, out.stderr
    assert fit("dressed.ply", "masked_u8.ply", "--scan-weights", "mask_u8.npy").returncode == 0
    plain = (tmp_path / "plain.ply").read_bytes()
    assert (tmp_path / "masked.ply").read_bytes() == plain
    assert (tmp_path / "masked_u8.ply").read_bytes() == plain
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["scan_weights"] == {
        "source": "file",
        "file": "mask.npy",
        "points": 400,
        "zero_weight": 100,
    }
    out = fit("dressed.ply", "weighted.ply", "--scan-weights", "confidence.npy")
    assert out.returncode == 0, out.stderr

    out = fit("dressed.ply", "o.ply", "--scan-weights", "short.npy")
    assert out.returncode == 1
    assert out.stderr == (
        "error: short.npy (the weights of dressed.ply): parameter target_weights = 399 weights: "
        "need one weight per scan point (400)\n"
    )
    assert not (tmp_path / "o.ply").exists()

    # The same mask as a per-vertex PLY property.
    write_labelled_ply(tmp_path / "labelled.ply", points, mask, "label")
    out = fit("labelled.ply", "labelled_fit.ply", "--scan-weights-property", "label")
    assert out.returncode == 0, out.stderr
    assert (tmp_path / "labelled_fit.ply").read_bytes() == plain
