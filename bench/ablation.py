"""Ablation of the readings chosen over the paper's literal text (docs/method.md, Eq. 2–8).

All variants start from ``preset="paper"`` (the default's additions are measured on the 91
harness cases by ``python -m bench.variants``).

Runs FoldMatch with each literal reading switched back on, one at a time, plus NRGa, on
generated cases with ground truth, and prints a Markdown table (and writes JSON).

    .venv/bin/python -m bench.ablation [--out bench/out/ablation.json]
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

import foldmatch_rs as fm
import numpy as np

VARIANTS = [
    ("paper preset (chosen readings)", {}),
    ("numerator: literal Yα − X", {"numerator": "literal"}),
    ("force: plain sum over K", {"summation": "sum"}),
    ("damping: −ηv as a force", {"damping_mode": "force"}),
    ("velocity not synced after update", {"velocity_sync": False}),
    (
        "all four literal N-body readings",
        {"numerator": "literal", "summation": "sum", "damping_mode": "force", "velocity_sync": False},
    ),
    ("Eq. 5: log-Euclidean mean", {"regularization": "log_euclidean"}),
    ("Eq. 5: no regularization", {"regularization": "none"}),
    ("Eq. 8 on the raw Eq. 4 gradient", {"rotation_source": "raw"}),
    ("Eq. 4 without normal completion", {"normal_completion": 0.0}),
    ("no curvature term (α = 1)", {"use_curvature": False}),
    ("1-ring", {"rings": 1}),
    ("3-ring", {"rings": 3}),
    ("NRGa (point-based baseline)", {"method": "nrga"}),
]

CASES = {
    "sheet 41×41, 3000-pt scan": dict(
        nx=41, ny=41, scan_points=3000, rotation_degrees=3.0, offset=(0, 0, 0.05)
    ),
    "sheet 41×41, 8° + offset, noisy": dict(nx=41, ny=41, scan_points=4000, noise=0.002),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="bench/out/ablation.json")
    args = ap.parse_args()
    rows = []
    for case_name, spec in CASES.items():
        c = fm.folded_sheet(**spec)
        oracle = fm.evaluate(
            c["template_vertices"], c["faces"], c["ground_truth"], c["scan"], c["ground_truth"]
        )
        ident = fm.evaluate(
            c["template_vertices"], c["faces"], c["template_vertices"], c["scan"], c["ground_truth"]
        )
        rows.append({"case": case_name, "variant": "identity (template as is)", **ident, "seconds": 0.0})
        rows.append({"case": case_name, "variant": "oracle (ground truth)", **oracle, "seconds": 0.0})
        for name, opts in VARIANTS:
            t = time.perf_counter()
            try:
                # Each literal reading is measured against the paper preset (the method as
                # printed, with the converging readings): the fidelity options are off.
                r = fm.fit(c["template_vertices"], c["faces"], c["scan"], preset="paper", params=opts)
                m = fm.evaluate(c["template_vertices"], c["faces"], r.vertices, c["scan"], c["ground_truth"])
                if not np.isfinite(r.vertices).all():
                    raise fm.NumericalError("non-finite")
            except fm.NumericalError as e:
                m = {"error": str(e)}
            rows.append({"case": case_name, "variant": name, **m, "seconds": time.perf_counter() - t})
    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(rows, indent=1, default=float))
    for case_name in CASES:
        print(f"\n**{case_name}** (100 iterations)\n")
        print("| variant | f_R | f_F | f_S | f_E | f_H | scan→fit mean | f_λ | s |")
        print("|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            if r["case"] != case_name:
                continue
            if "error" in r:
                print(f"| {r['variant']} | diverged | | | | | | | |")
                continue
            print(
                f"| {r['variant']} | {r['f_R']:.4f} | {r['f_F']:.3f} | {r['f_S']:.3f} | "
                f"{r['f_E']:.3f} | {r['f_H']:.3f} | {r['scan_to_fit_mean']:.4f} | "
                f"{r['f_lambda']:.3f} | {r['seconds']:.2f} |"
            )


if __name__ == "__main__":
    main()
