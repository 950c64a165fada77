"""The Dask path against the local batch (issue 29): throughput in scans per second of
``foldmatch batch`` and of ``foldmatch_rs.distributed.fit_batch`` on a local cluster of 1 and 2
worker processes, on the same generated folder of scans, and the scheduling overhead per scan.

One command::

    .venv/bin/python -m bench.cluster              # 16 scans, 3 rounds: about 2 minutes on 2 cores
    .venv/bin/python -m bench.cluster --scans 8 --repeat 1 --check 1.25

The local batch runs in this process through the extension's ``run_cli`` (``--jobs`` = its
default, one file per core up to 4, on one pool of every core). The two local clusters are
started first (the start time is printed, not counted: a cluster serves many batches); each
Dask run times ``fit_batch`` end to end: planning, submitting, the fits and writes on the
workers, the report. The three runs alternate for ``--repeat`` rounds and the best wall time
of each is kept, so that the load of a shared machine does not decide the ratio. Every run's
outputs are compared bit for bit with the local batch's.

Overheads per scan, both printed: the round trip of a task that does nothing (submit →
result, ``--noop`` tasks on the same cluster), and the run's wall time × workers minus the
summed per-file time the workers spent, divided by the scans (time a worker slot was not
fitting). ``--check RATIO`` exits with 1 when the 2-worker run takes more than RATIO × the
local batch's wall time.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import pathlib
import shutil
import sys
import tempfile
import time

import foldmatch_rs as fm
from foldmatch_rs import _foldmatch_rs as core
from foldmatch_rs import distributed as fmd

from tests.test_cli import write_ply  # the tests' plain ASCII PLY writer


def make_folder(root: pathlib.Path, scans: int, size: int, points: int) -> tuple[pathlib.Path, pathlib.Path]:
    case = fm.folded_sheet(nx=size, ny=size)
    template = root / "template.ply"
    write_ply(template, case["template_vertices"], case["faces"])
    folder = root / "scans"
    folder.mkdir()
    for k in range(scans):
        c = fm.folded_sheet(
            nx=size,
            ny=size,
            scan_points=points,
            noise=0.002,
            seed=k + 1,
            fold_amplitude=0.04 + 0.04 * (k % 5) / 4,
            rotation_degrees=4.0 + k % 7,
        )
        write_ply(folder / f"scan{k:03d}.ply", c["scan"])
    return template, folder


def outputs(folder: pathlib.Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.glob("*.ply"))}


def noop(_k: int) -> None:
    return None


def local_batch(template: pathlib.Path, folder: pathlib.Path, out_dir: pathlib.Path) -> float:
    shutil.rmtree(out_dir, ignore_errors=True)
    started = time.perf_counter()
    code = core.run_cli(["foldmatch", "-q", "batch", str(template), str(folder), "-o", str(out_dir)])
    wall = time.perf_counter() - started
    if code != 0:
        raise SystemExit(f"the local batch failed with exit code {code}")
    return wall


def dask_batch(client, template, folder, out_dir, expected, workers) -> tuple[float, float]:
    """Wall time of ``fit_batch`` and the time a worker slot was not fitting, per scan."""
    shutil.rmtree(out_dir, ignore_errors=True)
    started = time.perf_counter()
    report = fmd.fit_batch(template, folder, out_dir, client=client)
    wall = time.perf_counter() - started
    if report["summary"]["ok"] != len(expected):
        raise SystemExit(f"{workers} workers: {report['summary']}")
    if outputs(out_dir) != expected:
        raise SystemExit(f"{workers} workers: outputs differ from the local batch's")
    busy = sum(f["total_seconds"] for f in report["files"])
    return wall, max(0.0, wall * workers - busy) / len(expected)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scans", type=int, default=16, help="scans in the folder (default 16)")
    ap.add_argument("--size", type=int, default=31, help="template vertices per side (default 31)")
    ap.add_argument("--points", type=int, default=4000, help="points per scan (default 4000)")
    ap.add_argument("--repeat", type=int, default=3, help="rounds of the three runs (default 3)")
    ap.add_argument("--noop", type=int, default=200, help="no-op tasks timed per cluster (default 200)")
    ap.add_argument("--check", type=float, default=None, help="fail when 2 workers take > RATIO x local")
    args = ap.parse_args()
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    with tempfile.TemporaryDirectory(prefix="foldmatch-dask-bench-") as tmp, contextlib.ExitStack() as stack:
        root = pathlib.Path(tmp)
        template, folder = make_folder(root, args.scans, args.size, args.points)
        print(
            f"{args.scans} scans of {args.points} points, template {args.size}x{args.size} "
            f"({args.size**2} vertices), default parameters, {cores} cores, best of {args.repeat} "
            "alternated rounds"
        )
        local_batch(template, folder, root / "local")
        expected = outputs(root / "local")
        clients, start_s, noop_ms = {}, {}, {}
        for workers in (1, 2):
            t0 = time.perf_counter()
            clients[workers] = stack.enter_context(fmd.connect(None, workers=workers))
            clients[workers].wait_for_workers(workers)
            start_s[workers] = time.perf_counter() - t0
            t0 = time.perf_counter()
            clients[workers].gather(clients[workers].map(noop, range(args.noop), pure=False))
            noop_ms[workers] = (time.perf_counter() - t0) / args.noop * 1e3
        walls: dict[str, list[float]] = {"local": [], 1: [], 2: []}
        idle: dict[int, list[float]] = {1: [], 2: []}
        for _ in range(args.repeat):
            walls["local"].append(local_batch(template, folder, root / "local"))
            for workers in (1, 2):
                out_dir = root / f"dask{workers}"
                wall, idle_s = dask_batch(clients[workers], template, folder, out_dir, expected, workers)
                walls[workers].append(wall)
                idle[workers].append(idle_s)
        local_wall = min(walls["local"])
        print()
        print(f"{'run':<18} {'wall s':>7} {'scans/s':>8} {'x local':>8} {'cluster start s':>16} "
              f"{'no-op task ms':>14} {'idle slot ms/scan':>18}")  # fmt: skip
        print(f"{'local batch':<18} {local_wall:>7.2f} {args.scans / local_wall:>8.2f} {1.0:>8.2f}")
        for workers in (1, 2):
            wall = min(walls[workers])
            name = f"Dask, {workers} worker{'s' if workers > 1 else ''}"
            print(
                f"{name:<18} {wall:>7.2f} {args.scans / wall:>8.2f} {wall / local_wall:>8.2f} "
                f"{start_s[workers]:>16.1f} {noop_ms[workers]:>14.1f} {min(idle[workers]) * 1e3:>18.0f}"
            )
        print("\nEvery Dask run's outputs are the local batch's bit for bit.")
        ratio = min(walls[2]) / local_wall
        print(json.dumps({"walls_s": {str(k): v for k, v in walls.items()}, "ratio_2_workers": ratio}))
        if args.check is not None and ratio > args.check:
            print(f"FAIL: 2 workers took {ratio:.2f}x the local batch (limit {args.check})", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
