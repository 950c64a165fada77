"""FoldMatch variants side by side on groups of harness cases (issue "Fidelity").

Each variant is a set of keyword arguments on top of the library defaults; each is fitted on
every case of the chosen groups and scored by the harness's metrics. Prints f_R / f_λ per case
and, per group, the medians of f_R, f_λ, f_H, f_E, f_F and scan→fit mean::

    .venv/bin/python bench/variants.py --groups real,small \\
        --variant 'no rigid={"rigid_fraction": 0}' --variant 'default={}'
    .venv/bin/python bench/variants.py --preset placement     # the schedule study of method.md

Groups: ``real`` (22 pre-placed real-garment cases), ``small`` / ``paper`` (generated, rotated
and offset), ``sheets`` (24 random sheets), ``wind`` (30 wind frames). Results go to
``--out`` (JSON, one row per case and variant).
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time
from typing import Any, Iterator

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import cases as cases_mod  # noqa: E402
import harness  # noqa: E402

PRESETS: dict[str, list[tuple[str, dict[str, Any]]]] = {
    # Does the rigid phase help when the template is already placed? (docs/method.md)
    "placement": [
        ("default (rigid 30 %, coarse 30 %)", {}),
        ("rigid 10 %, coarse 30 %", {"rigid_fraction": 0.1}),
        ("no rigid phase, coarse 30 %", {"rigid_fraction": 0.0}),
        ("no rigid phase, coarse 50 %", {"rigid_fraction": 0.0, "coarse_fraction": 0.5}),
    ],
    # The schedule grid behind the default of 2026-11-22 (docs/method.md); each on top of
    # the library defaults, so every setting is spelled out.
    "schedule": [
        (name, {"two_way": tw, "rigid_fraction": rf, "coarse_fraction": cf, "anneal": an,
                "anneal_fraction": ai, "rings": rings})
        for name, tw, rf, cf, an, ai, rings in [
            ("previous default (two-way 1, coarse 30 %, no annealing)", 1.0, 0.3, 0.3, 1.0, 0.0, 2),
            ("two-way 2, coarse 50 %, anneal ×3 over 60 % (default)", 2.0, 0.3, 0.5, 3.0, 0.6, 2),
            ("two-way 2, coarse 40 %, anneal ×3 over 60 %", 2.0, 0.3, 0.4, 3.0, 0.6, 2),
            ("two-way 1.5, coarse 50 %, anneal ×3 over 60 %", 1.5, 0.3, 0.5, 3.0, 0.6, 2),
            ("two-way 3, coarse 50 %, anneal ×3 over 60 %", 3.0, 0.3, 0.5, 3.0, 0.6, 2),
            ("two-way 2, coarse 50 %, anneal ×3 over 45 %", 2.0, 0.3, 0.5, 3.0, 0.45, 2),
            ("two-way 2, coarse 50 %, anneal ×3 over 80 %", 2.0, 0.3, 0.5, 3.0, 0.8, 2),
            ("two-way 2, rigid 20 %, coarse 50 %, anneal ×3", 2.0, 0.2, 0.5, 3.0, 0.6, 2),
            ("two-way 2, coarse 50 %, anneal ×2 over 60 %", 2.0, 0.3, 0.5, 2.0, 0.6, 2),
            ("two-way 2, coarse 50 %, anneal ×3, 3-ring", 2.0, 0.3, 0.5, 3.0, 0.6, 3),
        ]
    ],
}
METRICS = ("f_R", "f_lambda", "f_H", "f_E", "f_F", "s2f_mean_rel")


def group_cases(group: str) -> Iterator[cases_mod.Case]:
    if group in ("real", "wind"):
        why = cases_mod.real_data_missing()
        if why is not None:
            print(f"group {group} skipped: {why}", file=sys.stderr)
            return
        yield from (cases_mod.real_cases() if group == "real" else cases_mod.wind_samples())
    elif group in ("small", "paper"):
        yield from cases_mod.generated_cases(group)
    elif group == "sheets":
        yield from cases_mod.sheet_samples()
    else:
        raise SystemExit(f"unknown group {group!r} (real, small, paper, sheets, wind)")


def parse_variant(text: str) -> tuple[str, dict[str, Any]]:
    name, sep, kw = text.partition("=")
    if not sep:
        raise SystemExit(f"--variant {text!r}: expected NAME=JSON")
    return name, json.loads(kw)


def main() -> int:
    import foldmatch_rs as fm

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--groups", default="real,small")
    ap.add_argument("--variant", action="append", default=[], metavar="NAME=JSON")
    ap.add_argument("--preset", choices=sorted(PRESETS))
    ap.add_argument("--out", default=str(HERE / "out" / "variants.json"))
    args = ap.parse_args()
    variants = list(PRESETS[args.preset]) if args.preset else []
    variants += [parse_variant(v) for v in args.variant]
    if not variants:
        raise SystemExit("no variant: give --preset or --variant")
    groups = args.groups.split(",")
    rows = []
    print("| case | " + " | ".join(v for v, _ in variants) + " |")
    print("| :--- |" + " ---: |" * len(variants))
    for group in groups:
        for case in group_cases(group):
            arrays = harness.case_arrays(case)
            cells = []
            for name, kw in variants:
                t0 = time.perf_counter()
                r = fm.fit(case.template_vertices, case.faces, case.target,
                           target_faces=case.target_faces, **kw)
                seconds = time.perf_counter() - t0
                e = harness.evaluate(arrays, r.vertices)
                rows.append({"group": group, "case": case.name, "variant": name,
                             "seconds": seconds, **{m: e[m] for m in METRICS}})
                cells.append(f"{e['f_R']:.4f} / {e['f_lambda']:.3f}")
            print(f"| {case.name} | " + " | ".join(cells) + " |", flush=True)
    header = " | ".join(METRICS) + " | s"
    for group in groups:
        print(f"\nmedians, {group}: {header}")
        for name, _ in variants:
            sel = [r for r in rows if r["group"] == group and r["variant"] == name]
            if sel:
                cells = [f"{np.median([r[m] for r in sel]):.4f}" for m in METRICS]
                cells.append(f"{np.median([r['seconds'] for r in sel]):.2f}")
                print(f"  {name:<40} " + " | ".join(cells))
    pathlib.Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    pathlib.Path(args.out).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
