"""Two builds of ``examples/timing`` timed in alternation (issue "Performance").

The 2-core VMs this project is measured on drift by up to a fifth in speed within an hour
(docs/performance.md, sixteenth round), more than most single speed changes. Runs of two
builds taken in alternation share the drift, so their pairwise ratio is the figure to trust;
callgrind's instruction counts (which do not drift) are the other. Usage::

    cargo build --profile profiling --example timing && cp target/profiling/examples/timing /tmp/timing_a
    # ... change the code ...
    cargo build --profile profiling --example timing && cp target/profiling/examples/timing /tmp/timing_b
    python3 -m bench.ab_timing /tmp/timing_a /tmp/timing_b --pairs 15
    python3 -m bench.ab_timing /tmp/timing_a /tmp/timing_b --pairs 15 --threads 1 -- 45 2500

Arguments after ``--`` go to both binaries (``[side] [scan] [preset] [json]``, see
examples/timing.rs). Prints each build's mean, median and best total wall time, how many pairs
the second build won, and the mean of the pairwise ratios (second ÷ first).
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys

TOTAL = re.compile(r"total ([0-9.]+)s")


def total_seconds(binary: str, args: list[str], threads: int | None) -> float:
    env = dict(os.environ)
    if threads:
        env["RAYON_NUM_THREADS"] = str(threads)
    out = subprocess.run([binary, *args], check=True, capture_output=True, text=True, env=env).stdout
    match = TOTAL.search(out)
    if match is None:
        raise SystemExit(f"{binary}: no 'total ...s' in its output:\n{out}")
    return float(match.group(1))


def main() -> None:
    argv = sys.argv[1:]
    passed: list[str] = []
    if "--" in argv:
        at = argv.index("--")
        argv, passed = argv[:at], argv[at + 1 :]
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("first", help="the baseline build of examples/timing")
    ap.add_argument("second", help="the build to compare with it")
    ap.add_argument("--pairs", type=int, default=15, help="alternating pairs (15)")
    ap.add_argument("--threads", type=int, default=None, help="RAYON_NUM_THREADS (all)")
    args = ap.parse_args(argv)
    if args.pairs < 1:
        raise SystemExit("--pairs must be at least 1")
    for binary in (args.first, args.second):
        if not (os.path.isfile(binary) and os.access(binary, os.X_OK)):
            raise SystemExit(f"{binary}: not an executable file (a build of examples/timing)")
    first: list[float] = []
    second: list[float] = []
    for _ in range(args.pairs):
        first.append(total_seconds(args.first, passed, args.threads))
        second.append(total_seconds(args.second, passed, args.threads))
    for name, walls in (("first ", first), ("second", second)):
        print(
            f"{name} mean {statistics.mean(walls):.3f} s  median {statistics.median(walls):.3f} s"
            f"  best {min(walls):.3f} s"
        )
    ratios = [b / a for a, b in zip(first, second)]
    won = sum(b < a for a, b in zip(first, second))
    print(
        f"second faster in {won} of {args.pairs} pairs; mean ratio second / first "
        f"{statistics.mean(ratios):.3f}"
    )


if __name__ == "__main__":
    main()
