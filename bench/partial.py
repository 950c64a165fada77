"""Partial scans: the default fit of a front-only half scan against its fit of the whole scan.

For every case of the chosen harness groups (bench/variants.py's; real garments and generated
cases), the scan is replaced by what one camera rig on the front sees of the true surface
(bench/front_scan.py), fitted with the default, and scored: f_R of the half-scan fit ÷ f_R of
the whole-scan fit (the issue's target: at most 2 on every case), and the template vertices
the fit reports without scan support (``FitResult.support``), beside the share of vertices the
camera rig could not see (the truth's vertices farther than 2 scan spacings from every scan
point). The cases are split by a hash of their name into a tuning half and a held-out half
(bench/verdict.py's split), reported separately: choices are made on the tuning half only.

    .venv/bin/python -m bench.partial                      # real,small
    .venv/bin/python -m bench.partial --groups real --variant '{"rest_rigidity": 0.8}'
    .venv/bin/python -m bench.partial --half '{"params": {"carry_unsupported": 2.0}}'  # one-sided halves
"""

from __future__ import annotations

import argparse
import hashlib
import json
import pathlib
from typing import Any

import numpy as np

from bench import variants
from bench.front_scan import front_scan
from bench.verdict import split_of

HERE = pathlib.Path(__file__).resolve().parent


def seen_vertices(truth: np.ndarray, scan: np.ndarray) -> np.ndarray:
    """Which of the truth's vertices lie within 2 scan spacings (the median distance between
    neighbouring scan points) of a scan point."""
    import foldmatch_rs as fm

    _, d2 = fm.knn(scan, scan, 2)
    spacing = float(np.median(np.sqrt(d2[:, 1])))
    _, d2 = fm.knn(scan, truth, 1)
    return np.sqrt(d2[:, 0]) <= 2 * spacing


def unseen_share(truth: np.ndarray, scan: np.ndarray) -> float:
    """Share of the truth's vertices farther than 2 scan spacings from every scan point."""
    return float(1 - np.mean(seen_vertices(truth, scan)))


def half_scan(case) -> np.ndarray:
    """What one camera rig on the front of `case` sees of its truth (bench/front_scan.py), at
    most as many points as its whole scan, the rig's noise drawn from the case's name."""
    up = int(case.meta.get("up", 1))
    seed = int(hashlib.sha256(case.name.encode()).hexdigest()[:8], 16)
    return front_scan(case.ground_truth, case.faces, up, seed, most=len(case.target))


def rows_of(
    groups: list[str], kw: dict[str, Any], half_kw: dict[str, Any] | None = None
) -> list[dict[str, Any]]:
    import foldmatch_rs as fm

    rows = []
    for group in groups:
        for case in variants.group_cases(group):
            if case.ground_truth is None:
                continue
            half = half_scan(case)
            whole = fm.fit(
                case.template_vertices, case.faces, case.target, target_faces=case.target_faces, **kw
            )
            part = fm.fit(case.template_vertices, case.faces, half, **(kw if half_kw is None else half_kw))
            f_whole = fm.evaluate(
                case.template_vertices, case.faces, whole.vertices, case.target, case.ground_truth
            )["f_R"]
            # f_R of both relative to the whole scan's diagonal (the same truth, one scale).
            f_half = fm.evaluate(
                case.template_vertices, case.faces, part.vertices, case.target, case.ground_truth
            )["f_R"]
            row = {
                "group": group,
                "case": case.name,
                "split": split_of(case.name),
                "f_R_whole": f_whole,
                "f_R_half": f_half,
                "ratio": f_half / f_whole,
                "unsupported": float(1 - np.mean(part.support)),
                "unseen": unseen_share(case.ground_truth, half),
                "verdict": part.quality["verdict"],
            }
            rows.append(row)
            print(
                f"| {case.name} | {row['split']} | {f_whole:.4f} | {f_half:.4f} "
                f"| {row['ratio']:.2f} | {row['unsupported']:.1%} | {row['unseen']:.1%} "
                f"| {row['verdict']} |",
                flush=True,
            )
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--groups", default="real,small")
    ap.add_argument("--variant", default="{}", help="keyword arguments of fm.fit (JSON)")
    ap.add_argument(
        "--half",
        default=None,
        help="keyword arguments of fm.fit for the half scans only (JSON; default: --variant's), e.g. "
        '\'{"params": {"carry_unsupported": 2.0}}\'',
    )
    ap.add_argument("--out", type=pathlib.Path, default=HERE / "out" / "partial.json")
    args = ap.parse_args()
    kw = json.loads(args.variant)
    print("| case | split | f_R whole | f_R half | half ÷ whole | unsupported | unseen | verdict |")
    print("| :--- | :--- | ---: | ---: | ---: | ---: | ---: | :--- |")
    half_kw = None if args.half is None else json.loads(args.half)
    rows = rows_of(args.groups.split(","), kw, half_kw)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"variant": kw, "half": half_kw, "rows": rows}, indent=1))
    print()
    for split in ("tune", "held-out"):
        part = [r for r in rows if r["split"] == split]
        if not part:
            continue
        ratios = np.array([r["ratio"] for r in part])
        print(
            f"{split}: {len(part)} cases, half ÷ whole median {np.median(ratios):.2f}, "
            f"max {ratios.max():.2f}, within 2×: {int((ratios <= 2).sum())} of {len(part)}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
