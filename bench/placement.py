"""Does the default's rigid phase help when the template is already placed? (issue "Fidelity")

The harness (bench/compare.py) places every real template on its target by the least-squares
similarity to the ground truth; bench/fidelity.py fits the real templates from where their
files put them. This script runs FoldMatch variants of the phase schedule on the harness's
cases — the 22 real-garment cases (pre-placed) and the 9 small generated ones (rotated and
offset) — and prints f_R / f_λ per case and the medians per group::

    .venv/bin/python bench/placement.py [--out bench/out/placement.json]
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import cases as cases_mod  # noqa: E402
import harness  # noqa: E402

VARIANTS = [
    ("default (rigid 30 %, coarse 30 %)", {}),
    ("rigid 10 %, coarse 30 %", {"rigid_fraction": 0.1}),
    ("no rigid phase, coarse 30 %", {"rigid_fraction": 0.0}),
    ("no rigid phase, coarse 50 %", {"rigid_fraction": 0.0, "coarse_fraction": 0.5}),
]


def main() -> int:
    import foldmatch_rs as fm

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(HERE / "out" / "placement.json"))
    args = ap.parse_args()
    groups: dict[str, list] = {"real (pre-placed)": [], "generated small (misplaced)": []}
    if cases_mod.real_data_missing() is None:
        groups["real (pre-placed)"] = list(cases_mod.real_cases())
    groups["generated small (misplaced)"] = list(cases_mod.generated_cases("small"))
    rows = []
    print("| case | " + " | ".join(v for v, _ in VARIANTS) + " |")
    print("| :--- |" + " ---: |" * len(VARIANTS))
    for group, cs in groups.items():
        for case in cs:
            arrays = harness.case_arrays(case)
            cells = []
            for name, kw in VARIANTS:
                r = fm.fit(case.template_vertices, case.faces, case.target,
                           target_faces=case.target_faces, **kw)
                e = harness.evaluate(arrays, r.vertices)
                rows.append({"group": group, "case": case.name, "variant": name,
                             "f_R": e["f_R"], "f_lambda": e["f_lambda"], "f_F": e["f_F"]})
                cells.append(f"{e['f_R']:.4f} / {e['f_lambda']:.3f}")
            print(f"| {case.name} | " + " | ".join(cells) + " |", flush=True)
    print("\n| group | " + " | ".join(v for v, _ in VARIANTS) + " |")
    print("| :--- |" + " ---: |" * len(VARIANTS))
    for group in groups:
        cells = []
        for name, _ in VARIANTS:
            sel = [r for r in rows if r["group"] == group and r["variant"] == name]
            if sel:
                cells.append(f"{np.median([r['f_R'] for r in sel]):.4f} / "
                             f"{np.median([r['f_lambda'] for r in sel]):.3f}")
            else:
                cells.append("—")
        print(f"| median {group} | " + " | ".join(cells) + " |")
    pathlib.Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    pathlib.Path(args.out).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
