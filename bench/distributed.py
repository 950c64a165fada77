"""The Dask path against the local batch (issue 29): throughput in scans per second of
``foldmatch batch`` and of ``foldmatch_rs.distributed.fit_batch`` on a local cluster of 1 and 2
worker processes, on the same generated folder of scans, and the scheduling overhead per scan.

One command::

    .venv/bin/python bench/distributed.py              # 24 scans, about a minute on 2 cores
    .venv/bin/python bench/distributed.py --scans 8 --check 1.25

The local batch runs in this process through the extension's ``run_cli`` (``--jobs`` = its
default, one file per core up to 4, on one pool of every core). Each Dask run starts its
cluster first (the start time is printed, not counted: a cluster serves many batches), then
times ``fit_batch`` end to end: planning, submitting, the fits and writes on the workers, the
report. Every run's outputs are compared bit for bit with the local batch's.

Overheads per scan, both printed: the round trip of a task that does nothing (submit →
result, ``--noop`` tasks on the same cluster), and the run's wall time × workers minus the
summed per-file time the workers spent, divided by the scans (time a worker slot was not
fitting). ``--check RATIO`` exits with 1 when the 2-worker run takes more than RATIO × the
local batch's wall time.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import tempfile
import time

# This file's name is Dask's package name: keep bench/ off the path so `import distributed`
# finds Dask's (tests/ gives the PLY writer of the tests).
HERE = pathlib.Path(__file__).resolve().parent
sys.path[:] = [p for p in sys.path if pathlib.Path(p or ".").resolve() != HERE]
sys.path.insert(0, str(HERE.parent / "tests"))

import foldmatch_rs as fm
from foldmatch_rs import _foldmatch_rs as core
from foldmatch_rs import distributed as fmd
from test_cli import write_ply


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


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scans", type=int, default=24, help="scans in the folder (default 24)")
    ap.add_argument("--size", type=int, default=31, help="template vertices per side (default 31)")
    ap.add_argument("--points", type=int, default=4000, help="points per scan (default 4000)")
    ap.add_argument("--noop", type=int, default=200, help="no-op tasks timed per cluster (default 200)")
    ap.add_argument("--check", type=float, default=None, help="fail when 2 workers take > RATIO x local")
    args = ap.parse_args()
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    with tempfile.TemporaryDirectory(prefix="foldmatch-dask-bench-") as tmp:
        root = pathlib.Path(tmp)
        template, folder = make_folder(root, args.scans, args.size, args.points)
        print(
            f"{args.scans} scans of {args.points} points, template {args.size}x{args.size} "
            f"({args.size**2} vertices), default parameters, {cores} cores"
        )
        started = time.perf_counter()
        code = core.run_cli(
            ["foldmatch", "-q", "batch", str(template), str(folder), "-o", str(root / "local")]
        )
        local_wall = time.perf_counter() - started
        if code != 0:
            print(f"the local batch failed with exit code {code}", file=sys.stderr)
            return 1
        expected = outputs(root / "local")
        rows = [("local batch", local_wall, None, None)]
        for workers in (1, 2):
            t0 = time.perf_counter()
            with fmd.connect(None, workers=workers) as client:
                client.wait_for_workers(workers)
                start_seconds = time.perf_counter() - t0
                t0 = time.perf_counter()
                client.gather(client.map(noop, range(args.noop), pure=False))
                noop_ms = (time.perf_counter() - t0) / args.noop * 1e3
                out_dir = root / f"dask{workers}"
                t0 = time.perf_counter()
                report = fmd.fit_batch(template, folder, out_dir, client=client)
                wall = time.perf_counter() - t0
            if report["summary"]["ok"] != args.scans:
                print(f"{workers} workers: {report['summary']}", file=sys.stderr)
                return 1
            if outputs(out_dir) != expected:
                print(f"{workers} workers: outputs differ from the local batch's", file=sys.stderr)
                return 1
            busy = sum(f["total_seconds"] for f in report["files"])
            idle_ms = max(0.0, wall * workers - busy) / args.scans * 1e3
            rows.append(
                (
                    f"Dask, {workers} worker{'s' if workers > 1 else ''}",
                    wall,
                    start_seconds,
                    (noop_ms, idle_ms),
                )
            )
        print()
        print(f"{'run':<18} {'wall s':>7} {'scans/s':>8} {'x local':>8} {'cluster start s':>16} "
              f"{'no-op task ms':>14} {'idle slot ms/scan':>18}")  # fmt: skip
        for name, wall, start_seconds, overhead in rows:
            start = "" if start_seconds is None else f"{start_seconds:.1f}"
            noop_ms, idle_ms = ("", "") if overhead is None else (f"{overhead[0]:.1f}", f"{overhead[1]:.0f}")
            print(
                f"{name:<18} {wall:>7.2f} {args.scans / wall:>8.2f} {wall / local_wall:>8.2f} "
                f"{start:>16} {noop_ms:>14} {idle_ms:>18}"
            )
        print("\nEvery Dask run's outputs are the local batch's bit for bit.")
        ratio = rows[2][1] / local_wall
        print(
            json.dumps({"local_s": local_wall, "dask1_s": rows[1][1], "dask2_s": rows[2][1], "ratio2": ratio})
        )
        if args.check is not None and ratio > args.check:
            print(f"FAIL: 2 workers took {ratio:.2f}x the local batch (limit {args.check})", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
