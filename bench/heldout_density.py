"""Held-out check of the target-neighbourhood size on dense scans (docs/notes/method-history.md, "Thirteenth
round"): cases the harness does not have, where ρN exceeds `k_min` so ρ matters.

* every real garment pair of ``../shared/data`` as a 15,000-point noisy cloud (the harness
  uses 5,000, where K = 8 for either ρ), and
* 8 random folded sheets (81 × 81 vertices, seeds the harness does not use) on 15,000 points.

Each is fitted with the default and with the paper's neighbourhoods (ρ = 0.2 %, K ≤ 64);
prints f_R and f_λ per case and their geometric-mean ratios::

    .venv/bin/python -m bench.heldout_density

``--points`` and ``--against`` (the parameters the default is compared with, JSON) make it the
held-out check of other density-dependent options, e.g. the coarse phase's scan sample
(docs/notes/method-history.md, "Fourteenth round")::

    .venv/bin/python -m bench.heldout_density --points 60000 --against '{"coarse_scan_sample": 1}'

``--peers`` (comma-separated bench/peers.py methods, run in this process with their harness
parameters) scores the default, and the compared parameters, against those peers on the same
held-out cases: per case the lowest f_R and f_λ of the peers, and at the end how many cases
each configuration has the lowest f_R / f_λ of all (the harness's first two criteria on cases
nothing was tuned on)::

    .venv/bin/python -m bench.heldout_density --points 5000 --against '{"iterations": 150}' \
        --peers cpd_rustcpd,nricp_amberg
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import warnings

import numpy as np

from bench import cases as cases_mod
from bench import harness, peers

POINTS = 15_000
PAPER_NEIGHBOURHOODS = {"rho": 0.002, "k_max": 64}


def dense_cases(points: int = POINTS):
    if cases_mod.real_data_missing() is None:
        yield from cases_mod.real_cases(kinds=("points",), points=points)
    rng = np.random.default_rng(900)
    for i in range(8):
        v, f, gt = cases_mod.folded_sheet(
            81,
            seed=900 + i,
            fold_amplitude=float(rng.uniform(0.03, 0.10)),
            folds=float(rng.uniform(1.5, 4.0)),
            rotation_degrees=float(rng.uniform(0, 20)),
            offset=tuple(float(x) for x in rng.uniform(-0.05, 0.05, 3)),
        )
        pts = cases_mod.sample_surface(gt, f, points, rng)
        pts = pts + rng.normal(scale=0.002 * cases_mod.bbox_diagonal(gt), size=pts.shape)
        yield cases_mod.Case(f"dense-sheet-{i}", "heldout", v, f, pts, None, gt, {})


def main(argv: list[str] | None = None) -> int:
    import foldmatch_rs as fm

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--points", type=int, default=POINTS, help="scan points per case")
    ap.add_argument(
        "--against",
        default=json.dumps(PAPER_NEIGHBOURHOODS),
        help="JSON parameters the default is compared with (default: the paper's ρ, k_max)",
    )
    ap.add_argument(
        "--peers", default="", help="comma-separated bench/peers.py methods to score both against"
    )
    args = ap.parse_args(argv)
    against = json.loads(args.against)
    methods = [m for m in args.peers.split(",") if m]
    unknown = [m for m in methods if m not in peers.METHODS]
    if unknown:
        raise SystemExit(f"--peers: unknown {unknown} (known: {', '.join(peers.METHODS)})")
    for m in [m for m in methods if peers.missing_reason(m)]:
        print(f"--peers: {m} left out: {peers.missing_reason(m)}")
        methods.remove(m)
    ratios = []
    wins = {"against": [0, 0], "default": [0, 0]}
    print(
        f"{args.points:,} points; the default against {against}"
        + (f"; peers {', '.join(methods)}" if methods else "")
    )
    print(
        f"{'case':<26} {'K':>7}  {'f_R against → default':>24}  {'f_λ against → default':>24}"
        + ("  best peer f_R / f_λ" if methods else "")
    )
    for case in dense_cases(args.points):
        arrays = {
            "template_vertices": case.template_vertices,
            "faces": case.faces,
            "target": case.target,
            "ground_truth": case.ground_truth,
        }
        row = []
        for extra in (against, {}):
            settings = dict(extra)
            r = fm.fit(
                case.template_vertices,
                case.faces,
                case.target,
                preset=settings.pop("preset", None),
                params=settings,
            )
            e = harness.evaluate(arrays, np.asarray(r.vertices))
            row.append((e["f_R"], e["f_lambda"], r.diagnostics["target_neighbours"]))
        (ra, la, ka), (rb, lb, kb) = row
        ratios.append((rb / ra, lb / la))
        line = f"{case.name:<26} {ka:>3}→{kb:<3}  {ra:>10.4f} → {rb:<10.4f}  {la:>10.4f} → {lb:<10.4f}"
        if methods:
            best = peer_best(case, arrays, methods)
            for name, (f_r, f_l) in (("against", row[0][:2]), ("default", row[1][:2])):
                wins[name][0] += f_r <= best[0]
                wins[name][1] += f_l <= best[1]
            line += f"  {best[0]:.4f} / {best[1]:.4f}"
        print(line, flush=True)
    gm = [math.exp(sum(math.log(r[i]) for r in ratios) / len(ratios)) for i in (0, 1)]
    better = sum(r[0] < 1 for r in ratios)
    print(
        f"geometric mean, default ÷ against: f_R ×{gm[0]:.3f}, f_λ ×{gm[1]:.3f}; "
        f"f_R lower on {better} of {len(ratios)}"
    )
    if methods:
        for name, (w_r, w_l) in wins.items():
            print(f"{name}: the lowest f_R of all on {w_r} of {len(ratios)}, the lowest f_λ on {w_l}")
    return 0


def peer_best(case, arrays, methods: list[str]) -> tuple[float, float]:
    """The lowest f_R and f_λ of `methods` (importable) on `case`, each run in this process
    with its harness parameters; a method too large for the case is left out."""
    found = []
    m, n = len(case.template_vertices), len(case.target)
    for method in methods:
        spec = peers.METHODS[method]
        if peers.size_skip_reason(method, m, n):
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fitted, _, _ = spec["run"](
                case.template_vertices, case.faces, case.target, None, False, **spec["params"]
            )
        e = harness.evaluate(arrays, np.asarray(fitted, dtype=np.float64))
        found.append((e["f_R"], e["f_lambda"]))
    if not found:
        return math.inf, math.inf
    return min(f for f, _ in found), min(f for _, f in found)


if __name__ == "__main__":
    sys.exit(main())
