"""The README's picture: the current default fitted to a real garment scan, drawn by the
product's own renderer (`FitResult.preview`, the CLI's ``--preview``).

The case is the harness's ``vto-tshirt-0000-pts`` (../shared/data: the ARCSim T-shirt template
onto a noisy 8,000-point scan of a wrinkled draped frame, placed as the harness places it).
The picture has one column per view and three rows: the scan, the fit coloured by the
accumulated wrinkle-vector field, the fit coloured by its distance to the scan.

    python -m bench.readme_figure            # writes docs/figures/readme-fit.png
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import foldmatch_rs as fm

from bench.cases import real_cases, real_data_missing

CASE = "vto-tshirt-0000-pts"
OUT = pathlib.Path(__file__).resolve().parent.parent / "docs" / "figures" / "readme-fit.png"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=pathlib.Path, default=OUT)
    ap.add_argument("--size", type=int, default=320, help="edge of one panel in pixels")
    args = ap.parse_args()
    missing = real_data_missing()
    if missing:
        print(f"readme_figure: {missing}", file=sys.stderr)
        return 2
    case = next(c for c in real_cases(("points",)) if c.name == CASE)
    result = fm.fit(case.template_vertices, case.faces, case.target)
    result.preview(args.out, scan=case.target, size=args.size)
    print(f"{args.out}: {CASE}, {result.iterations} iterations")
    return 0


if __name__ == "__main__":
    sys.exit(main())
