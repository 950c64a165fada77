"""Global pre-alignment (issue "Any start, any coverage"; docs/method.md, "Global
pre-alignment"): harness cases with the scan moved the way real scans arrive, fitted with the
default, scored against the fit of the same scan in the template's frame.

Each case's scan (and its ground truth, the same way) is moved: given z-up instead of y-up
(``zup``), turned 90° and 180° about the vertical (``turn90``, ``turn180``: the person facing
the other way, where a garment nearly symmetric front to back fits as closely back to front,
docs/method.md), turned 60° about an oblique axis and shifted by one bounding-box diagonal
(``oblique60``); for ``prealign="similarity"`` also
scaled ×0.5 and ×2 about the origin (``half``, ``double``) and given in millimetres
(``mm``: ×1000). Every moved case is fitted with the default (rigid moves) or with
``prealign="similarity"`` (scale moves) and its f_R — measured in the moved scan's frame
against the moved truth; f_R is relative to the scan's diagonal, so it is unit-free — is
divided by the f_R of the default's fit of the unmoved scan. A ratio above ``--limit``
(1.25) fails. A template with exact rotational symmetries (a square sheet, a generated tube or
shirt: bench/symmetry.py) gives the same moved scan for each of its readings, so the ratio of
f_R up to them is printed beside a failure, and summarized apart::

    .venv/bin/python -m bench.prealign                       # tuning set: real + small
    .venv/bin/python -m bench.prealign --set held-out        # cases not tuned on
    .venv/bin/python -m bench.prealign --set sim             # the physically simulated cases
    .venv/bin/python -m bench.prealign --align-only          # the transforms alone, no fits
    .venv/bin/python -m bench.prealign --timing              # prealign="none" vs the default, placed scans

The tuning set is the harness groups ``real`` and ``small``; the held-out set is every third
wind frame of ``samples-wind`` and the first eight random sheets of ``samples-sheet``
(bench/cases.py), never looked at while choosing the constants of src/prealign/. Rows go to
``--out`` (JSON).
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from bench import cases as cases_mod
from bench import harness, symmetry, variants

HERE = pathlib.Path(__file__).resolve().parent

#: A move of the scan: (points, the unmoved scan's bounding-box diagonal vector, the up axis)
#: → moved points.
Move = Callable[[np.ndarray, np.ndarray, int], np.ndarray]


def _rotate(points: np.ndarray, axis: Any, degrees: float) -> np.ndarray:
    return points @ cases_mod.rotation_matrix(np.asarray(axis, float), degrees).T


def _zup(points: np.ndarray, diag: np.ndarray, up: int) -> np.ndarray:
    """The up axis becomes the next one (y-up → z-up): a quarter turn about the third."""
    axis = np.zeros(3)
    axis[(up + 2) % 3] = 1.0
    return _rotate(points, axis, 90.0)


def _about_vertical(degrees: float) -> Move:
    """A turn by `degrees` about the case's up axis."""

    def move(points: np.ndarray, diag: np.ndarray, up: int) -> np.ndarray:
        axis = np.zeros(3)
        axis[up] = 1.0
        return _rotate(points, axis, degrees)

    return move


def _oblique60(points: np.ndarray, diag: np.ndarray, up: int) -> np.ndarray:
    return _rotate(points, [1.0, 2.0, -1.5], 60.0) + diag


#: The rigid moves, fitted with the default.
RIGID: dict[str, Move] = {
    "zup": _zup,
    "turn90": _about_vertical(90.0),
    "turn180": _about_vertical(180.0),
    "oblique60": _oblique60,
}
#: The scale moves, fitted with ``prealign="similarity"``.
SCALED: dict[str, Move] = {
    "half": lambda p, d, u: 0.5 * p,
    "double": lambda p, d, u: 2.0 * p,
    "mm": lambda p, d, u: 1000.0 * p,
}


def tuning_cases() -> list[cases_mod.Case]:
    return variants.group_cases("real") + variants.group_cases("small")


def held_out_cases() -> list[cases_mod.Case]:
    wind = [c for c in cases_mod.wind_samples()][::3]
    sheets = list(cases_mod.sheet_samples())[:8]
    return wind + sheets


def variants_sim_cases() -> list[cases_mod.Case]:
    """The physically simulated cases (z up), never tuned on here."""
    return variants.group_cases("sim")


def up_axis(case: cases_mod.Case) -> int:
    """The vertical of a case: the real garments are y-up (bench/cases.py); the generated
    skirt, shirt and sheet are z-up (the sheet's normal)."""
    return int(case.meta.get("up", 2))


def moved(case: cases_mod.Case, move: Move) -> dict[str, np.ndarray]:
    """The case's arrays with the scan and the truth moved by `move`; the template as is."""
    lo, hi = case.target.min(0), case.target.max(0)
    up = up_axis(case)
    out = harness.case_arrays(case)
    out["target"] = np.ascontiguousarray(move(case.target, hi - lo, up))
    if case.ground_truth is not None:
        out["ground_truth"] = np.ascontiguousarray(move(case.ground_truth, hi - lo, up))
    return out


def fit_f_r(
    case: cases_mod.Case, arrays: dict[str, np.ndarray], perms: list[np.ndarray], **kw: Any
) -> tuple[float, float, float]:
    """f_R of a fit of `arrays`, its f_R up to the template's symmetries `perms`
    (bench/symmetry.py) and its seconds."""
    import foldmatch_rs as fm

    t0 = time.perf_counter()
    r = fm.fit(
        arrays["template_vertices"], arrays["faces"], arrays["target"], target_faces=case.target_faces, **kw
    )
    seconds = time.perf_counter() - t0
    f_r = harness.evaluate(arrays, r.vertices)["f_R"]
    diagonal = cases_mod.bbox_diagonal(arrays["target"])
    return f_r, symmetry.f_r_up_to(r.vertices, arrays["ground_truth"], diagonal, perms), seconds


def rotation_error(case: cases_mod.Case, arrays: dict[str, np.ndarray], motion: str) -> dict:
    """How far fm.prealign's transform puts the template's vertices from where the moved
    placement would (RMS, relative to the scan's diagonal), and whether it searched."""
    import foldmatch_rs as fm

    a = fm.prealign(arrays["template_vertices"], arrays["target"], motion=motion)
    placed = arrays["template_vertices"] @ (a["scale"] * a["rotation"]).T + a["translation"]
    truth = arrays["ground_truth"]
    diag = cases_mod.bbox_diagonal(arrays["target"])
    # The unmoved placement, moved: the scan's move applied to the given template.
    return {
        "searched": a["searched"],
        "scale": a["scale"],
        "identity_rel": a["identity_score"] / diag,
        "score_rel": a["score"] / diag,
        "rms_to_truth_rel": float(np.sqrt(((placed - truth) ** 2).sum(1).mean()) / diag),
    }


def run(cases: list[cases_mod.Case], align_only: bool, limit: float) -> list[dict[str, Any]]:
    rows = []
    moves = [(n, m, "rigid") for n, m in RIGID.items()]
    moves += [(n, m, "similarity") for n, m in SCALED.items()]
    print("| case | unmoved f_R | " + " | ".join(n for n, _, _ in moves) + " |")
    print("| :--- | ---: |" + " ---: |" * len(moves))
    for case in cases:
        if case.ground_truth is None:
            continue
        base = harness.case_arrays(case)
        row: dict[str, Any] = {"case": case.name, "group": case.group}
        if align_only:
            row["unmoved"] = rotation_error(case, base, "rigid")
            cells = [f"{row['unmoved']['rms_to_truth_rel']:.4f}"]
            for name, move, motion in moves:
                row[name] = rotation_error(case, moved(case, move), motion)
                cells.append(f"{row[name]['rms_to_truth_rel']:.4f}")
        else:
            perms = symmetry.symmetries(case.template_vertices)
            row["symmetries"] = len(perms)
            f0, f0_sym, s0 = fit_f_r(case, base, perms)
            row["unmoved"] = {"f_R": f0, "f_R_sym": f0_sym, "seconds": s0}
            cells = [f"{f0:.4f}"]
            for name, move, motion in moves:
                kw = {} if motion == "rigid" else {"prealign": "similarity"}
                f, f_sym, s = fit_f_r(case, moved(case, move), perms, **kw)
                ratio, ratio_sym = f / f0, f_sym / f0_sym
                row[name] = {
                    "f_R": f,
                    "ratio": ratio,
                    "f_R_sym": f_sym,
                    "ratio_sym": ratio_sym,
                    "seconds": s,
                    "pass": ratio <= limit,
                }
                cell = f"{ratio:.2f}" + ("" if ratio <= limit else " ✗")
                if len(perms) > 1 and ratio > limit:
                    cell += f" ({ratio_sym:.2f})"
                cells.append(cell)
        rows.append(row)
        label = case.name if row.get("symmetries", 1) == 1 else f"{case.name} ({row['symmetries']} readings)"
        print(f"| {label} | " + " | ".join(cells) + " |", flush=True)
    return rows


def summarize(rows: list[dict[str, Any]], limit: float) -> None:
    names = [*RIGID, *SCALED]
    for key, title in (
        ("ratio", "cases within {limit}× of the unmoved fit"),
        (
            "ratio_sym",
            "the same, f_R up to the template's exact symmetries (bench/symmetry.py: the readings "
            "no scan can tell apart; the figure in parentheses above)",
        ),
    ):
        print(f"\nper move: {title.format(limit=limit)}, worst ratio, geometric mean\n")
        print("| move | within | worst | geo. mean |")
        print("| :--- | ---: | ---: | ---: |")
        for n in names:
            ratios = [r[n][key] for r in rows if n in r and key in r[n]]
            if not ratios:
                continue
            within = sum(x <= limit for x in ratios)
            mean = variants.geo_mean(ratios)
            print(f"| {n} | {within} of {len(ratios)} | {max(ratios):.2f} | {mean:.3f} |")


def timing(cases: list[cases_mod.Case], repeats: int) -> None:
    """The default (rigid pre-alignment) against ``prealign="none"`` on the placed scans, in
    alternation (the machine's drift cancels): per case the median of the pairwise ratios."""
    print("| case | none s | default s | ratio (median of pairs) |")
    print("| :--- | ---: | ---: | ---: |")
    for case in cases:
        arrays = harness.case_arrays(case)
        identity = [np.arange(len(case.template_vertices))]
        pairs = []
        for _ in range(repeats):
            _, _, a = fit_f_r(case, arrays, identity, prealign="none")
            _, _, b = fit_f_r(case, arrays, identity)
            pairs.append((a, b))
        a, b = np.median([p[0] for p in pairs]), np.median([p[1] for p in pairs])
        ratio = float(np.median([q / p for p, q in pairs]))
        print(f"| {case.name} | {a:.3f} | {b:.3f} | {ratio:.3f} |", flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--set",
        choices=("tuning", "held-out", "sim"),
        default="tuning",
        help="sim: the physically simulated cases (bench/sim_cases.py, docs/simulated.md)",
    )
    ap.add_argument("--cases", help="only the cases whose name contains one of these (comma-separated)")
    ap.add_argument(
        "--align-only",
        action="store_true",
        help="no fits: how far fm.prealign's transform puts the template from the "
        "truth (RMS ÷ scan diagonal), unmoved and per move",
    )
    ap.add_argument(
        "--timing", action="store_true", help='time prealign="none" against the default on the placed scans'
    )
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--limit", type=float, default=1.25)
    ap.add_argument("--out", default=str(HERE / "out" / "prealign.json"))
    args = ap.parse_args()
    cases = {"tuning": tuning_cases, "held-out": held_out_cases, "sim": variants_sim_cases}[args.set]()
    if args.cases:
        keys = args.cases.split(",")
        cases = [c for c in cases if any(k in c.name for k in keys)]
    if args.timing:
        timing(cases, args.repeats)
        return 0
    rows = run(cases, args.align_only, args.limit)
    if not args.align_only:
        summarize(rows, args.limit)
    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
