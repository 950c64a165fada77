"""Hostile inputs through Python (issue 31): the cases of ``tests/hostile/cases.json`` through
the CLI compiled into the extension, in this process (an abort would end the test run), and
hostile values of the Python API. Every result is a typed :class:`FoldMatchError` naming the
culprit, or a documented success; Ctrl-C interrupts a fit promptly."""

from __future__ import annotations

import _thread
import json
import os
import pathlib
import signal
import subprocess
import sys
import threading
import time

import foldmatch_rs as fm
import numpy as np
import pytest
from foldmatch_rs import _foldmatch_rs as core
from foldmatch_rs.errors import FoldMatchError, InvalidParameterError
from test_cli import write_ply

HOSTILE = pathlib.Path(__file__).resolve().parent / "hostile"
CASES = json.loads((HOSTILE / "cases.json").read_text())["cases"]


@pytest.fixture(scope="module")
def sheet() -> dict:
    return fm.folded_sheet(nx=15, ny=15, scan_points=400, noise=0.001)


@pytest.fixture(scope="module")
def folder(tmp_path_factory, sheet) -> pathlib.Path:
    d = tmp_path_factory.mktemp("hostile")
    write_ply(d / "template.ply", sheet["template_vertices"], sheet["faces"])
    write_ply(d / "scan.ply", sheet["scan"])
    os.symlink("/dev/zero", d / "zero.ply")
    os.symlink("/dev/urandom", d / "urandom.obj")
    return d


def resolve(name: str, d: pathlib.Path) -> pathlib.Path:
    special = {
        "@dev-zero": d / "zero.ply",
        "@dev-urandom": d / "urandom.obj",
        "@folder": HOSTILE / "files" / "folder.ply",
        "@missing": d / "missing.ply",
    }
    return special.get(name, HOSTILE / "files" / name)


@pytest.mark.skipif(sys.platform == "win32", reason="device files and symbolic links")
def test_hostile_cases_through_the_cli_in_process(folder, capfd):
    assert len(CASES) >= 40
    failures = []
    for c in CASES:
        out = folder / "out.ply"
        out.unlink(missing_ok=True)
        template = resolve(c["template"], folder) if "template" in c else folder / "template.ply"
        scan = resolve(c["scan"], folder) if "scan" in c else folder / "scan.ply"
        extra = [
            a.replace("{files}", str(HOSTILE / "files")).replace("{dev-zero}", str(folder / "zero.ply"))
            for a in c.get("args", []) + c.get("extra", [])
        ]
        argv = ["foldmatch", "fit", str(template), str(scan), "-o", str(out), *extra]
        code = core.run_cli(argv)
        captured = capfd.readouterr()
        text = captured.out + captured.err
        clean = "panicked" not in text and "RUST_BACKTRACE" not in text
        if c["expect"] == "ok":
            good = code == 0 and out.is_file()
        else:
            good = code == 1 and c["message"] in text and not out.exists()
        if not (good and clean):
            failures.append(f"{c['name']}: exit {code}, expected {c['message']!r}: {text}")
    assert not failures, "\n".join(failures)


def _fit(sheet: dict, threads=None, callback=None, **settings):
    return fm.fit(
        sheet["template_vertices"],
        sheet["faces"],
        sheet["scan"],
        threads=threads,
        callback=callback,
        params=settings,
    )


def _huge_snapshots(_sheet: dict):
    big = fm.folded_sheet(nx=40, ny=40)
    return _fit(big, iterations=10**6, snapshot_every=1)


# (call, the start of the message). Each must raise InvalidParameterError, quickly.
API_CASES = {
    "iterations=0": (lambda s: _fit(s, iterations=0), "parameter iterations = 0: must be in 1..=1000000"),
    "iterations=-1": (lambda s: _fit(s, iterations=-1), "parameter iterations = -1: "),
    "iterations=1e9": (lambda s: _fit(s, iterations=10**9), "parameter iterations = 1000000000: "),
    "iterations=1e30": (lambda s: _fit(s, iterations=10**30), "parameter iterations = "),
    "rho=nan": (lambda s: _fit(s, rho=float("nan")), "parameter rho = nan: must be a finite number"),
    "rho=inf": (lambda s: _fit(s, rho=float("inf")), "parameter rho = inf: must be a finite number"),
    "gravity=1e300": (lambda s: _fit(s, gravity=1e300), "parameter gravity = 1e300: must be in (0, 1e6]"),
    "snapshots 38 GB": (_huge_snapshots, "parameter snapshot_every = 1: 1000001 snapshots of 1600 vertices"),
    "k_max=1e9": (lambda s: _fit(s, k_max=10**9), "parameter k_min/k_max = 8/1000000000: "),
    "softening=-1": (lambda s: _fit(s, softening=-1.0), "parameter softening = -1: "),
    "threads=100000": (lambda s: _fit(s, threads=100000), "parameter threads = 100000: must be in 1..="),
    "threads=0": (lambda s: _fit(s, threads=0), "parameter threads = 0: must be in 1..="),
    "threads=-1": (lambda s: _fit(s, threads=-1), "parameter threads = -1: must be a whole number"),
    "threads=2**70": (lambda s: _fit(s, threads=2**70), "parameter threads = 1180591620717411303424: "),
    "knn k=-1": (lambda s: fm.knn(s["scan"], s["scan"], -1), "parameter k = -1: "),
    "knn k=1e20": (lambda s: fm.knn(s["scan"], s["scan"], 10**20), "parameter k = "),
    "knn k=0": (lambda s: fm.knn(s["scan"], s["scan"], 0), "parameter k = 0: "),
    "knn threads=-2": (lambda s: fm.knn(s["scan"], s["scan"], 3, threads=-2), "parameter threads = -2: "),
    "n_rings n=1e12": (lambda s: fm.n_rings(s["faces"], 10**12, 2), "parameter n_vertices = 1000000000000: "),
    "n_rings n=-1": (lambda s: fm.n_rings(s["faces"], -1, 2), "parameter n_vertices = -1: "),
    "n_rings rings=1e12": (
        lambda s: fm.n_rings(s["faces"], 225, 10**12),
        "parameter rings = 1000000000000: ",
    ),
    "n_rings rings=0": (lambda s: fm.n_rings(s["faces"], 225, 0), "parameter rings = 0: must be in 1..=8"),
    "gradients rings=100": (
        lambda s: fm.deformation_gradients(s["template_vertices"], s["ground_truth"], s["faces"], rings=100),
        "parameter rings = 100: must be in 1..=8",
    ),
    "sheet nx=ny=1e6": (
        lambda s: fm.folded_sheet(nx=10**6, ny=10**6),
        "parameter nx = 1000000: must be in 2..=10000",
    ),
    "sheet nx*ny": (
        lambda s: fm.folded_sheet(nx=5000, ny=5000),
        "parameter nx*ny = 25000000: must be at most 10000000",
    ),
    "sheet scan_points=1e10": (
        lambda s: fm.folded_sheet(scan_points=10**10),
        "parameter scan_points = 10000000000: ",
    ),
    "sheet nx=-3": (lambda s: fm.folded_sheet(nx=-3), "parameter nx = -3: "),
    "sheet seed=-1": (lambda s: fm.folded_sheet(seed=-1), "parameter seed = -1: "),
    "sheet width=nan": (lambda s: fm.folded_sheet(width=float("nan")), "parameter width = NaN: "),
}


@pytest.mark.parametrize("name", list(API_CASES))
def test_hostile_python_values_raise_invalid_parameter_error(sheet, name):
    call, message = API_CASES[name]
    started = time.perf_counter()
    with pytest.raises(InvalidParameterError) as info:
        call(sheet)
    assert time.perf_counter() - started < 2.0
    text = str(info.value)
    assert text.startswith(message), text
    assert "{" not in text  # the parameter alone, never the whole JSON object
    assert isinstance(info.value, FoldMatchError) and isinstance(info.value, ValueError)


def test_a_hostile_value_that_is_a_documented_success(sheet):
    # The largest allowed thread count (named by the error of one more) works, and gives the
    # same fit as the default.
    with pytest.raises(InvalidParameterError) as info:
        _fit(sheet, threads=10**6)
    most = int(str(info.value).split("1..=")[1].split()[0])
    assert most >= 4
    a = _fit(sheet, iterations=3, threads=most)
    b = _fit(sheet, iterations=3)
    np.testing.assert_array_equal(a.vertices, b.vertices)


# ---- Ctrl-C -------------------------------------------------------------------------------

INTERRUPTED_FIT = """
import sys, time, foldmatch_rs as fm
s = fm.folded_sheet(nx=25, ny=25, scan_points=2000)
print("started", flush=True)
t = time.perf_counter()
try:
    fm.fit(s["template_vertices"], s["faces"], s["scan"], iterations=1000000)
except KeyboardInterrupt:
    print(f"interrupted after {time.perf_counter() - t:.2f} s", flush=True)
    sys.exit(3)
print("not interrupted", flush=True)
"""


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT")
def test_ctrl_c_interrupts_a_fit_without_a_callback():
    """A real SIGINT (Ctrl-C) during `fm.fit` (no callback, 10⁶ iterations: hours) raises
    KeyboardInterrupt within a second."""
    child = subprocess.Popen(
        [sys.executable, "-c", INTERRUPTED_FIT], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert child.stdout is not None
    assert child.stdout.readline().strip() == "started"
    time.sleep(1.0)
    sent = time.perf_counter()
    child.send_signal(signal.SIGINT)
    out, err = child.communicate(timeout=30)
    elapsed = time.perf_counter() - sent
    assert child.returncode == 3, (out, err)
    assert "interrupted after" in out
    assert elapsed < 2.0, f"{elapsed:.2f} s to stop"


@pytest.mark.parametrize("kwargs", [{"threads": 2}, {"callback": lambda info: None}])
def test_ctrl_c_interrupts_a_fit_in_a_pool_or_with_a_callback(sheet, kwargs):
    """As above, in this process (`_thread.interrupt_main` is a Ctrl-C as Python sees it), with
    a pool of its own (the fit runs on a worker thread) or a callback."""
    timer = threading.Timer(0.3, _thread.interrupt_main)
    started = time.perf_counter()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            _fit(sheet, iterations=1000000, **kwargs)
    finally:
        timer.cancel()
    assert time.perf_counter() - started < 3.0
