"""Where the default FoldMatch stands against the best peer of every harness case, now
(issue "Fidelity"): the generated block ``standing`` of docs/results.md.

Fits the library's default and the paper preset on the 91 harness cases (the groups of
bench/variants.py: real garments, small and paper-sized generated cases, random sheets, wind
frames; about two minutes on 2 cores) and scores each fit against the best peer of its case
(``bench/peer_figures.json``: the peers' code and the cases are deterministic, so their figures
stand until either changes) by the issue's four criteria: the lowest f_R, the lowest f_λ,
flipped faces within the truth's own f_F + 1 point, a mean scan→fit distance no worse than the
best peer's. The ground truth itself is scored beside them (the "exact answer": what the
criteria allow; on many cases the best peer's f_λ or scan→fit distance is below the truth's
own). Every case the default loses is listed with its ratios and the reason found (or "not
investigated"), those lost on f_R or f_λ in one table, on flips or scan→fit in another; every
case is in a folded table below them::

    .venv/bin/python -m bench.standing                   # rewrites the block in docs/results.md
    .venv/bin/python -m bench.standing --print           # prints it instead
    .venv/bin/python -m bench.standing --from-json F     # re-renders an earlier run's rows

The rows go to ``--out`` (JSON, as bench/variants.py writes them).
"""

from __future__ import annotations

import argparse
import datetime
import json
import pathlib
import re
import sys
from typing import Any

from bench import harness, report, variants

HERE = pathlib.Path(__file__).resolve().parent

GROUPS = ["real", "small", "paper", "sheets", "wind"]
#: The two configurations reported: the default, and the method as the paper prints it.
CONFIGS = [("default", {}), ("paper preset", {"preset": "paper"})]
CRITERIA = [
    ("f_R", "lowest f_R"),
    ("f_lambda", "lowest f_λ"),
    ("flips", "flips ≤ truth + 1 pt"),
    ("s2f", "scan→fit ≤ best peer"),
]
SHORT = {"f_R": "f_R", "f_lambda": "f_λ", "flips": "flips", "s2f": "scan→fit"}

#: Why the default loses a case, as found (the mechanism only: the measurements are lab notes,
#: docs/notes/method-history.md, which names the round that measured each):
#: (pattern on the case's name, the criteria whose loss the reason explains, the reason). The
#: first pattern that matches and explains the criterion in question gives the reason.
F_R, F_L, S2F, FLIPS = "f_R", "f_lambda", "s2f", "flips"
REASONS: list[tuple[str, frozenset[str], str]] = [
    (
        r"^tshirt-triFolded",
        frozenset({F_R, F_L}),
        "self-contact: three layers of cloth pressed together, which "
        "no nearest-point method separates (every method ends at f_R 0.21–0.25, the template as "
        "given at 0.24)",
    ),
    (
        r"holes$",
        frozenset({F_R, F_L}),
        "holes: a vertex over a hole is pulled to the hole's rim, where "
        "NRICP-Amberg's smoothness term fills it; robust weights that hold such vertices fix the "
        "holed cases but cost the real garments and the wind frames",
    ),
    (
        r"^wind-(150|250)-mesh",
        frozenset({F_R, S2F}),
        "large articulated motion still under way at the schedule's "
        "end: a region of the template lies on the scan but slid along it; more iterations "
        "(the `accurate` preset) resolve part of it",
    ),
    (
        r"^sheet-sample-04$",
        frozenset({F_R, F_L}),
        "the schedule's 80 iterations leave this sheet's fit under way (without the "
        "refinement f_R 0.0273 at 80 iterations, 0.0132 at 100; 100 iterations and the "
        "refinement 0.0099, the lowest of all methods): the default's 80 pay for the "
        "refinement's time, which gains more on the other cases (method.md, Isometric "
        "refinement)",
    ),
    (
        r"^wind-iter0-0[1-5]0-pts",
        frozenset({F_R, F_L, S2F}),
        "the template starts on the truth (early frames): Eq. "
        "2's mean over a boundary vertex's one-sided neighbours pulls the boundary inward "
        "(4r/3π for a half disc), leaving the scan's edge uncovered; releasing that pull fixes "
        "these frames but costs the random sheets",
    ),
    (
        r"^wind-iter0-(1[7-9]|2[01])0-pts",
        frozenset({F_R, F_L, S2F}),
        "curled frames: a boundary flap stays straight "
        "across the concave side of the curl, where the pulls of the two sides balance (f_H); "
        "more FoldMatch iterations resolve it",
    ),
    (
        r"^wind-",
        frozenset({F_R, S2F}),
        "large articulated motion (sleeves blown up), which CPD's one smooth "
        "displacement field over all points finds and attraction to the nearest points over "
        "the coarse phase's rigid pieces only partly make",
    ),
    (
        r"^sheet-sample-(00|07)$",
        frozenset({F_R}),
        "schedule selection: the sharp candidate's fit is "
        "nearer the truth but farther from the scan, so the other is kept (method.md, "
        "Schedule selection)",
    ),
    (
        r"^(tshirt-biFolded|vto-tshirt-0200)",
        frozenset({F_R}),
        "folding / articulated motion, as the wind frames: CPD's global field finds it",
    ),
    (
        r"^skirt-small-pts$",
        frozenset({F_R}),
        "the template starts on the truth: the fit barely moves it, "
        "where NRICP's stiffness holds it closer, as in the early wind frames",
    ),
    (
        r"^skirt-penetrate",
        frozenset({F_R}),
        "the truth passes through itself (its own f_F 11 %): the "
        "default's rest-shape rigidity keeps the skirt from following it, where the paper "
        "preset and NRGa, without it, follow it closer",
    ),
    (
        r"^skirt-small-(clean|noisy)$",
        frozenset({F_R, F_L}),
        "pleated tube skirt: f_R a little above "
        "NRICP-Amberg's; f_λ through f_H, a fit vertex farther off the scan than the truth's "
        "farthest",
    ),
    (
        r"^sheet-sample-(00|07)$",
        frozenset({FLIPS}),
        "a corner folded over in the kept "
        "candidate's fit (the truth has none): the fits that lose f_R by schedule "
        "selection (above)",
    ),
    (
        r"^tshirt-flattened-mesh$",
        frozenset({F_R, S2F}),
        "tangential sliding on the flat "
        "panels: most of the squared error lies along the surface (the fitted vertices lie "
        "nearer the truth's nearest vertex than their own places); nearest-point attraction "
        "carries no tangential information on flat cloth, "
        "where CPD's one coherent motion field keeps the panels' parametrization",
    ),
]


#: A case lost on f_λ alone (its f_R the lowest of all) that no pattern names.
F_LAMBDA_ONLY = (
    "f_λ alone, through f_H (the symmetric Hausdorff distance: one scan corner "
    "or one boundary vertex); f_R is the lowest of all methods"
)


def reason(case: str, criterion: str) -> str | None:
    """Why the default loses `criterion` (one of :data:`CRITERIA`) on `case`: the first of
    :data:`REASONS` matching its name that explains that criterion, else None."""
    return next(
        (why for pat, explains, why in REASONS if criterion in explains and re.search(pat, case)), None
    )


def accuracy_reason(case: str, verdict: dict[str, Any]) -> str:
    """The reason for a case lost on f_R or f_λ (its :func:`variants.verdict`): for f_R where
    f_R is lost, else for f_λ; a loss of f_λ alone that no pattern names is
    :data:`F_LAMBDA_ONLY`; else "not investigated"."""
    if not verdict[F_R]:
        return reason(case, F_R) or "not investigated"
    return reason(case, F_L) or F_LAMBDA_ONLY


#: A scan→fit loss where the best peer lies closer to the scan than the exact answer does.
S2F_BELOW_TRUTH = (
    "the best peer lies closer to the scan than the exact answer ({peer}× its "
    "distance): it pulls vertices onto the noisy samples; ours is {ours}× the "
    "exact answer's"
)


def closeness_reason(case: str, ours: float, peer: float, truth: float | None) -> str:
    """The reason for a case lost on scan→fit (mean distances, relative): :data:`S2F_BELOW_TRUTH`
    where the exact answer (`truth`, None when unknown) is itself farther than the best peer,
    else the first of :data:`REASONS` that explains it, else "not investigated"."""
    if truth is not None and truth > peer:
        return S2F_BELOW_TRUTH.format(peer=f"{peer / truth:.2f}", ours=f"{ours / truth:.2f}")
    return reason(case, S2F) or "not investigated"


def render(rows: list[dict[str, Any]], best: variants.Best, source: str, stamp: str) -> str:
    """The block's markdown: the criteria per configuration and group (and, where the rows
    have them, for the exact answer itself: what the criteria allow), the default's cases lost
    on f_R or f_λ and those lost on flips or scan→fit with their reasons, every case folded."""
    configs = [c for c in dict.fromkeys(r["variant"] for r in rows) if c != variants.EXACT]
    groups = list(dict.fromkeys(r["group"] for r in rows))
    scored = [(r, best[r["case"]], variants.verdict(r, best[r["case"]])) for r in rows if r["case"] in best]
    truth = {r["case"]: r for r in rows if r["variant"] == variants.EXACT}
    out = [stamp, ""]
    header = ["configuration", "criterion"] + groups + ["all"]
    body = []
    for c in configs + ([variants.EXACT] if truth else []):
        mine = [s for s in scored if s[0]["variant"] == c]
        for key, name in CRITERIA:
            cells = []
            for g in groups + ["all"]:
                vs = [v[key] for r, _, v in mine if g in ("all", r["group"]) and v[key] is not None]
                cells.append(f"{sum(vs)} of {len(vs)}")
            body.append([c, name] + cells)
        # The exact answer's f_R is 0, and so is its f_λ where the scan is its own mesh: no
        # ratios.
        for key, name in (
            ("f_R", "f_R ÷ best peer (geo. mean)"),
            ("f_lambda", "f_λ ÷ best peer (geo. mean)"),
        ):
            if c == variants.EXACT:
                continue
            cells = []
            for g in groups + ["all"]:
                ratios = [r[key] / b[key] for r, b, _ in mine if g in ("all", r["group"])]
                cells.append(f"{variants.geo_mean(ratios):.3f}")
            body.append([c, name] + cells)
    out += [report.table(header, body, ["l", "l"] + ["r"] * (len(groups) + 1)), ""]
    if truth:
        out += [
            f"The rows of the **{variants.EXACT}** score the ground truth itself as a fit "
            "(the oracle): what the criteria allow. Where the truth does not meet a "
            "criterion, the best peer beats the exact answer on it (a lower f_λ or scan→fit "
            "distance than the truth's own).",
            "",
        ]

    def truth_cell(case: str, key: str, digits: int) -> str:
        t = truth.get(case)
        return "—" if t is None else f"{t[key]:.{digits}f}"

    default = [s for s in scored if s[0]["variant"] == configs[0]]
    lost = [s for s in default if not (s[2]["f_R"] and s[2]["f_lambda"])]
    lost.sort(key=lambda s: -max(s[0]["f_R"] / s[1]["f_R"], s[0]["f_lambda"] / s[1]["f_lambda"]))
    out += [
        f"**Cases the {configs[0]} loses on f_R or f_λ: {len(lost)} of {len(default)}**, "
        "largest loss first (ratio = ours ÷ the best peer's; > 1: lost):",
        "",
    ]
    out.append(
        report.table(
            [
                "case",
                "group",
                "f_R ours / best",
                "ratio",
                "f_λ ours / best",
                "ratio",
                "exact answer's f_λ",
                "reason found",
            ],
            [
                [
                    r["case"],
                    r["group"],
                    f"{r['f_R']:.4f} / {b['f_R']:.4f}",
                    report.ratio(r["f_R"], b["f_R"]),
                    f"{r['f_lambda']:.3f} / {b['f_lambda']:.3f}",
                    report.ratio(r["f_lambda"], b["f_lambda"]),
                    truth_cell(r["case"], "f_lambda", 3),
                    accuracy_reason(r["case"], v),
                ]
                for r, b, v in lost
            ],
            ["l", "l", "r", "r", "r", "r", "r", "l"],
        )
    )
    other = [s for s in default if s[2]["s2f"] is False or s[2]["flips"] is False]
    other.sort(key=lambda s: -s[0]["s2f_mean_rel"] / s[1]["s2f_mean_rel"])
    below_truth = sum(
        1
        for r, b, v in other
        if not v["s2f"] and r["case"] in truth and truth[r["case"]]["s2f_mean_rel"] > b["s2f_mean_rel"]
    )
    out += [
        "",
        f"**Cases the {configs[0]} loses on flips or scan→fit: {len(other)} of "
        f"{len(default)}**, largest scan→fit loss first; on {below_truth} of them the best "
        "peer's scan→fit distance is below the exact answer's own:",
        "",
    ]

    def other_reasons(r: dict[str, Any], b: dict[str, float], v: dict[str, Any]) -> str:
        parts = []
        if not v["s2f"]:
            t = truth.get(r["case"])
            parts.append(
                "scan→fit: "
                + closeness_reason(
                    r["case"], r["s2f_mean_rel"], b["s2f_mean_rel"], None if t is None else t["s2f_mean_rel"]
                )
            )
        if v["flips"] is False:
            parts.append("flips: " + (reason(r["case"], FLIPS) or "not investigated"))
        return "; ".join(parts)

    out.append(
        report.table(
            [
                "case",
                "group",
                "scan→fit ours / best",
                "ratio",
                "exact answer's scan→fit",
                "f_F ours / truth",
                "reason found",
            ],
            [
                [
                    r["case"],
                    r["group"],
                    f"{r['s2f_mean_rel']:.5f} / {b['s2f_mean_rel']:.5f}",
                    report.ratio(r["s2f_mean_rel"], b["s2f_mean_rel"]),
                    truth_cell(r["case"], "s2f_mean_rel", 5),
                    f"{r['f_F']:.3f} / {b['truth_f_F']:.3f}",
                    other_reasons(r, b, v),
                ]
                for r, b, v in other
            ],
            ["l", "l", "r", "r", "r", "r", "l"],
        )
    )
    out += ["", "<details><summary>Every case (default, paper preset, best peer)</summary>", ""]
    by_case: dict[str, dict[str, dict[str, Any]]] = {}
    for r, b, v in scored:
        by_case.setdefault(r["case"], {})[r["variant"]] = {**r, "verdict": v, "best": b}
    rows_md = []
    for case, per in by_case.items():
        d = per[configs[0]]
        b = d["best"]
        cells = [case, d["group"]]
        for c in configs:
            x = per.get(c)
            cells.append("—" if x is None else f"{x['f_R']:.4f} / {x['f_lambda']:.3f}")
        cells += [
            f"{b['f_R']:.4f} / {b['f_lambda']:.3f}",
            truth_cell(case, "f_lambda", 3),
            f"{d['f_F']:.3f} / {b['truth_f_F']:.3f}",
            f"{d['s2f_mean_rel']:.4f} / {b['s2f_mean_rel']:.4f} / " + truth_cell(case, "s2f_mean_rel", 4),
            ", ".join(SHORT[k] for k, _ in CRITERIA if d["verdict"][k]) or "none",
        ]
        rows_md.append(cells)
    out.append(
        report.table(
            ["case", "group"]
            + [f"{c}: f_R / f_λ" for c in configs]
            + [
                "best peer: f_R / f_λ",
                "exact answer: f_λ",
                "f_F default / truth",
                "scan→fit default / best peer / exact answer",
                "default wins",
            ],
            rows_md,
            ["l", "l"] + ["r"] * (len(configs) + 4) + ["l"],
        )
    )
    out += ["", "</details>", "", f"Peers' figures: `{source}`."]
    return "\n".join(out)


def stamp_line(from_json: str | None = None) -> str:
    """The block's first line: when, from which code (:func:`harness.code_version`: the commit,
    whether the tree differs from it, when the extension was built) and from what."""
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    code = harness.code_version()
    if from_json:
        return (
            f"_Re-rendered {now} ({code}) by `.venv/bin/python -m bench.standing "
            f"--from-json {pathlib.Path(from_json).name}` (the fits of an earlier run)._"
        )
    return (
        f"_Generated {now} ({code}) by `.venv/bin/python -m bench.standing` "
        "(the 91 harness cases, the library's current default and paper preset)._"
    )


def _relative(name: str) -> str:
    path = pathlib.Path(name).resolve()
    return str(path.relative_to(HERE.parent)) if path.is_relative_to(HERE.parent) else name


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--groups", default=",".join(GROUPS))
    ap.add_argument("--out", default=str(HERE / "out" / "standing.json"))
    ap.add_argument("--from-json", metavar="FILE", help="render an earlier run's rows")
    ap.add_argument(
        "--peers",
        metavar="FILE",
        action="append",
        default=None,
        help="as python -m bench.variants --peers (default bench/peer_figures.json)",
    )
    ap.add_argument("--print", action="store_true", help="print the block, leave docs alone")
    ap.add_argument("--results", default=str(HERE.parent / "docs" / "results.md"))
    args = ap.parse_args()
    best, source = variants.load_best(args.peers)
    source = " + ".join(_relative(s) for s in source.split(" + "))
    if args.from_json:
        rows = json.loads(pathlib.Path(args.from_json).read_text())
    else:
        rows = variants.fit_rows(args.groups.split(","), CONFIGS, truth=True)
        pathlib.Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        pathlib.Path(args.out).write_text(json.dumps(rows, indent=1))
    block = render(rows, best, source, stamp_line(args.from_json))
    if args.print:
        print(block)
        return 0
    path = pathlib.Path(args.results)
    path.write_text(report.replace_block(path.read_text(), "standing", block))
    print(f"wrote the 'standing' block of {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
