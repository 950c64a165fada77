"""End-to-end performance figures of FoldMatch (docs/performance.md): wall time, time per
iteration, per-stage breakdown, peak memory and threads, for

(a) the paper-sized case (13,225 template vertices, 14,400 scan points) and the 2K/2.5K case
    of the small peer case, with the peers on the same cases in the same run (rustcpd, probreg CPD, pycpd,
    trimesh NRICP) and the loop-based NumPy implementation of ``tests/reference.py`` as the
    same-algorithm baseline;
(b) ≈100K template vertices on a ≈1M-point scan;
(c) a size sweep in M (1K…200K vertices, fixed scan, fixed K) and in N (fixed M and K), with
    the plot ``docs/figures/perf_scaling.png``;
(d) 1 vs 2 threads.

One command::

    .venv/bin/python -m bench.perf                 # full run (tens of minutes on 2 cores)
    .venv/bin/python -m bench.perf --quick         # small sizes only, < 2 minutes

It prints a table per section, writes the JSON (``--out``, default ``bench/out/perf.json``, or
``bench/out/perf_quick.json`` with ``--quick``), the figure, and rewrites the generated blocks
of ``docs/performance.md`` (``--no-docs`` leaves docs/ alone).

Every measurement runs in a fresh Python process (``python -m bench.perf --worker JOB``), so its peak
memory is its own: the child reports ``VmHWM`` from ``/proc/self/status`` (the peak resident
set of the whole process: interpreter, NumPy, the data and the method, Rust allocations
included) right after the method returns, and the same value before the call as a baseline.
Threads: the number requested, the most OS threads the process had while the method ran
(sampled every 20 ms) and the CPU time / wall time ratio (the cores actually kept busy).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import pathlib
import subprocess
import sys
import time
from typing import Any

from bench.perf_analysis import analyse
from bench.perf_docs import DOC, write_docs
from bench.perf_plan import describe, jobs_for, log, plan
from bench.perf_tables import figure, print_console
from bench.perf_worker import worker

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent

FIGURE = ROOT / "docs" / "figures" / "perf_scaling.png"
COMMAND_FULL = ".venv/bin/python -m bench.perf"
COMMAND_QUICK = ".venv/bin/python -m bench.perf --quick"


def run_job(job: dict[str, Any], timeout: float) -> dict[str, Any]:
    """Runs one job in a fresh process; returns its record (status ok / failed / timeout)."""
    rec = {k: v for k, v in job.items()}
    rec["loadavg_before"] = round(os.getloadavg()[0], 2)
    t0 = time.perf_counter()
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "bench.perf", "--worker", json.dumps(job)],
            cwd=ROOT,
            check=False,
            capture_output=True,
            text=True,
            timeout=timeout,
            env=env,
        )
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("PERF_RESULT ")]
        if lines:
            rec.update(json.loads(lines[-1][len("PERF_RESULT ") :]))
        else:
            tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
            rec.update(status="failed", error=f"exit {proc.returncode}: {' | '.join(tail)[:400]}")
    except subprocess.TimeoutExpired:
        rec.update(status="timeout", error=f"stopped after {timeout:.0f} s")
    rec["process_s"] = round(time.perf_counter() - t0, 2)
    return rec


def versions() -> dict[str, str]:
    from importlib import metadata

    out = {}
    for dist in (
        "foldmatch-rs",
        "numpy",
        "scipy",
        "rustcpd",
        "probreg",
        "pycpd",
        "trimesh",
        "matplotlib",
    ):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = "not installed"
    try:
        out["rustc"] = subprocess.run(
            ["rustc", "--version"], check=False, capture_output=True, text=True, timeout=10
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        out["rustc"] = "?"
    try:
        import importlib.util

        spec = importlib.util.find_spec("foldmatch_rs")
        pkg = pathlib.Path(spec.origin).parent if spec and spec.origin else ROOT / "python"
        so = next(pkg.glob("_foldmatch_rs*.so"))
        built = so.stat().st_mtime
        out["extension_built"] = datetime.datetime.fromtimestamp(built).isoformat(timespec="minutes")
        newer = [f for f in (ROOT / "src").rglob("*.rs") if f.stat().st_mtime > built]
        if newer:
            out["extension_stale"] = ", ".join(str(f.relative_to(ROOT)) for f in sorted(newer))
    except StopIteration:
        pass
    return out


def git_state() -> dict[str, Any]:
    def git(*args: str) -> str:
        try:
            return subprocess.run(
                ["git", *args], cwd=ROOT, check=False, capture_output=True, text=True, timeout=10
            ).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return ""

    return {
        "commit": git("rev-parse", "--short", "HEAD"),
        "dirty": bool(git("status", "--porcelain", "--untracked-files=no")),
    }


# ======================================================================================
# main
# ======================================================================================


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--quick", action="store_true", help="small sizes only (< 2 minutes)")
    ap.add_argument(
        "--out",
        type=pathlib.Path,
        default=None,
        help="JSON output (default bench/out/perf.json, perf_quick.json with --quick)",
    )
    ap.add_argument(
        "--no-docs", action="store_true", help="do not touch docs/performance.md and docs/figures/"
    )
    ap.add_argument(
        "--only",
        default="",
        help="comma-separated sections to run: peers, threads, sweep_m, sweep_n, large (default: all)",
    )
    ap.add_argument(
        "--from-json",
        type=pathlib.Path,
        default=None,
        help="measure nothing: print and rewrite the docs and figure from a saved JSON",
    )
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        worker(json.loads(args.worker))
        return 0
    if args.from_json:
        saved = json.loads(args.from_json.read_text())
        p = plan(saved["meta"]["quick"])
        p["cases"] = saved["cases"]
        a = analyse(saved["runs"], p)
        print_console(saved["runs"], a)
        if not args.no_docs:
            figure(saved["runs"], a, FIGURE, p["quick"])
            write_docs(saved["runs"], a, saved["meta"], p)
            log(f"wrote {FIGURE.relative_to(ROOT)} and {DOC.relative_to(ROOT)}")
        return 0

    from bench import harness  # the shared machine description (not needed by --worker processes)

    start = time.perf_counter()
    p = plan(args.quick)
    out = args.out or HERE / "out" / ("perf_quick.json" if args.quick else "perf.json")
    only = {s for s in args.only.split(",") if s}
    jobs = [j for j in jobs_for(p) if not only or j["section"] in only]
    meta: dict[str, Any] = {
        "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "command": (COMMAND_QUICK if args.quick else COMMAND_FULL) + (f" --only {args.only}" if only else ""),
        "quick": args.quick,
        "machine": harness.machine(),
        "versions": versions(),
        "git": git_state(),
        "load_start": os.getloadavg()[0],
        "plan": {k: v for k, v in p.items() if k != "cases"},
    }
    log(
        f"{len(jobs)} measurements, {'QUICK' if args.quick else 'full'} run, "
        f"{meta['machine'].get('nproc')} cores, load {meta['load_start']:.2f}"
    )
    recs = []
    for i, job in enumerate(jobs, 1):
        if job.get("skip"):
            rec = {**job, "status": "skipped"}
            log(f"({i}/{len(jobs)}) {describe(job)}: skipped")
        else:
            rec = run_job(job, job["timeout"])
            msg = (
                f"{rec.get('wall_s', 0):.2f} s, peak {rec.get('peak_rss_mb', 0):.0f} MB"
                if rec.get("status") == "ok"
                else f"{rec['status']}: {rec.get('error', '')}"
            )
            log(f"({i}/{len(jobs)}) {describe(job)}: {msg}")
        recs.append(rec)
    meta["load_end"] = os.getloadavg()[0]
    meta["duration_s"] = time.perf_counter() - start
    a = analyse(recs, p)
    print_console(recs, a)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(
        json.dumps(
            {"meta": meta, "cases": p["cases"], "runs": recs, "analysis": a},
            indent=1,
            default=float,
        )
    )
    log(f"wrote {out}")
    if not args.no_docs:
        figure(recs, a, FIGURE, args.quick)
        write_docs(recs, a, meta, p)
        log(f"wrote {FIGURE.relative_to(ROOT)} and {DOC.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
