"""FoldMatch variants side by side on groups of harness cases (issue "Fidelity").

Each variant is a set of keyword arguments on top of the library defaults; each is fitted on
every case of the chosen groups and scored by the harness's metrics. Prints f_R / f_λ per case
and, per group, the medians of f_R, f_λ, f_H, f_E, f_F and scan→fit mean::

    .venv/bin/python -m bench.variants --groups real,small \\
        --variant 'no rigid={"rigid_fraction": 0}' --variant 'default={}'
    .venv/bin/python -m bench.variants --preset schedule --groups real,small,sheets,wind,paper
    .venv/bin/python -m bench.variants --preset placement
    .venv/bin/python -m bench.variants --preset margin --groups real,small,sheets,wind,paper
    .venv/bin/python -m bench.variants --preset pull --groups real,small,sheets,wind,paper

Groups: ``real`` (22 pre-placed real-garment cases), ``small`` / ``paper`` (generated, rotated
and offset), ``sheets`` (24 random sheets), ``wind`` (30 wind frames), ``dressed`` (6 scans of
dressed people, bench/dressed.py: whole scan, placed template; not in the default groups), ``sim``
(12 physically simulated cases, bench/sim_cases.py; not in the default groups). Results go to
``--out`` (JSON, one row per case and variant). Each variant is also scored against the
best peer of every case (``--peers``: by default a ``bench/compare.py`` run's
``bench/out/results.json`` if there is one, else ``bench/peer_figures.json``, which holds all
91 cases).
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time
from typing import Any

import numpy as np

from bench import cases as cases_mod
from bench import compare, harness, peers

HERE = pathlib.Path(__file__).resolve().parent

PRESETS: dict[str, list[tuple[str, dict[str, Any]]]] = {
    # Does the rigid phase help when the template is already placed? (docs/notes/method-history.md)
    "placement": [
        ("default (rigid 30 %, coarse 30 %)", {}),
        ("rigid 10 %, coarse 30 %", {"rigid_fraction": 0.1}),
        ("no rigid phase, coarse 30 %", {"rigid_fraction": 0.0}),
        ("no rigid phase, coarse 50 %", {"rigid_fraction": 0.0, "coarse_fraction": 0.5}),
    ],
    # The schedule grid behind the default of 2026-11-22 (docs/notes/method-history.md), one schedule per
    # fit; every setting spelled out.
    "schedule": [
        (
            name,
            {
                "two_way": tw,
                "rigid_fraction": rf,
                "coarse_fraction": cf,
                "anneal": an,
                "anneal_fraction": ai,
                "rings": rings,
                "selection": "single",
            },
        )
        for name, tw, rf, cf, an, ai, rings in [
            ("previous default (two-way 1, coarse 30 %, no annealing)", 1.0, 0.3, 0.3, 1.0, 0.0, 2),
            ("two-way 2, coarse 50 %, anneal ×3 over 60 % (given)", 2.0, 0.3, 0.5, 3.0, 0.6, 2),
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
    # Schedule selection (docs/notes/method-history.md): each schedule alone, and the default (both, keep
    # the fit closer to the scan); the last two as coarse-phase levels, for the record.
    "selection": [
        ("given schedule alone (two-way 2, coarse 50 %, annealed)", {"selection": "single"}),
        (
            "sharp schedule alone (two-way 1, coarse 30 %, constant ε)",
            {
                "selection": "single",
                "two_way": 1.0,
                "coarse_fraction": 0.3,
                "anneal": 1.0,
                "anneal_fraction": 0.0,
            },
        ),
        ("both, schedule selection (default)", {}),
        ("default + 2 coarse levels (8, 4 rings)", {"coarse_levels": 2}),
        ("default + 3 coarse levels (16, 8, 4 rings)", {"coarse_levels": 3, "coarse_rings": 16}),
    ],
    # Schedule selection's near-tie margin (docs/notes/method-history.md, eighth round): the previous rule
    # (0, the closer fit alone) first, so the per-case block compares every other value with it.
    "margin": [
        (
            f"selection_margin {m}"
            + (" (default)" if m == 0.06 else "")
            + (" (previous default)" if m == 0.0 else ""),
            {"selection_margin": m},
        )
        for m in (0.0, 0.03, 0.06, 0.1)
    ],
    # The two-way pulls summed by coverage (docs/notes/method-history.md, ninth round), at the rest-shape
    # rigidity they were measured with (0.5; the default is 0.65 since the same round): the
    # previous default (their mean, weight 3) first, so the per-case block compares every
    # other row with it.
    "pull": [
        (
            f"{pull}, two-way {w}"
            + {("mean", 3.0): " (previous default)", ("coverage", 4.5): " (the default's pull)"}.get(
                (pull, w), ""
            ),
            {"two_way_pull": pull, "two_way": w, "rest_rigidity": 0.5},
        )
        for pull, w in [
            ("mean", 3.0),
            ("mean", 4.5),
            ("coverage", 2.0),
            ("coverage", 3.0),
            ("coverage", 4.5),
            ("coverage", 6.0),
        ]
    ],
    # Rest-shape rigidity (docs/notes/method-history.md, seventh round; re-tuned in the ninth): the rule
    # before it (0) first, so the per-case block compares every other value with it.
    "rest": [
        (f"rest_rigidity {b}" + (" (default)" if b == 0.65 else ""), {"rest_rigidity": b})
        for b in (0.0, 0.3, 0.5, 0.6, 0.65, 0.7, 0.8)
    ],
}
METRICS = ("f_R", "f_lambda", "f_H", "f_E", "f_F", "s2f_mean_rel")


#: variants.py group → (bench/compare.py group that builds it, the cases' own group tag).
GROUPS = {
    "real": ("real", "real"),
    "small": ("small", "small"),
    "paper": ("paper", "paper"),
    "sheets": ("samples", "samples-sheet"),
    "wind": ("samples", "samples-wind"),
}


def group_cases(group: str) -> list[cases_mod.Case]:
    """The cases of a group, exactly as bench/compare.py builds them (``dressed``: the
    dressed-body scans of bench/dressed_scans.py, whole scan, placed template)."""
    if group == "dressed":
        from bench import dressed_scans

        return list(dressed_scans.dressed_cases())
    if group == "sim":  # the physically simulated cases of bench/sim_cases.py (docs/simulated.md)
        from bench import sim_cases

        return list(sim_cases.sim_cases())
    if group not in GROUPS:
        raise SystemExit(f"unknown group {group!r} ({', '.join(GROUPS)})")
    source, tag = GROUPS[group]
    built, notes = compare.build_cases(source)
    for note in notes:
        print(f"group {group}: {note}", file=sys.stderr)
    return [c for c in built if c.group == tag]


def parse_variant(text: str) -> tuple[str, dict[str, Any]]:
    name, sep, kw = text.partition("=")
    if not sep:
        raise SystemExit(f"--variant {text!r}: expected NAME=JSON")
    return name, json.loads(kw)


#: The best-peer figures of every harness case (``--save-peers``: docs/notes/comparison-full-run.md's per-case
#: tables merged with a bench/compare.py run for the random sheets and the wind frames, which
#: docs/notes/comparison-full-run.md does not print case by case): the peers' code and the cases are
#: deterministic, so the figures stand until either changes.
PEER_FIGURES = HERE / "peer_figures.json"
#: The same for the dressed-body cases (group ``dressed``), written by python -m bench.dressed --peers.
PEER_FIGURES_DRESSED = HERE / "peer_figures_dressed.json"
#: The same for the simulated cases (group ``sim``), written by python -m bench.sim --peers.
PEER_FIGURES_SIM = HERE / "peer_figures_sim.json"

#: Every compared method but FoldMatch's own two configurations (NRGa counts as a peer).
PEERS = [m for m in peers.METHODS if m not in ("foldmatch", "foldmatch_paper")]


def geo_mean(ratios: Any) -> float:
    """The geometric mean of positive ratios."""
    return float(np.exp(np.mean(np.log(list(ratios)))))


#: Per case, the best peer's figures the issue's criteria compare with: the lowest f_R, f_λ
#: and mean scan→fit distance (relative to the scan's diagonal) of any peer, and the truth's own
#: flipped-face fraction (NaN without ground truth).
Best = dict[str, dict[str, float]]

#: The columns of docs/notes/comparison-full-run.md's per-case tables read by
#: :func:`best_peers_from_markdown`.
_MD_COLUMNS = {"f_R": "f_R", "f_lambda": "f_λ", "s2f_mean_rel": "scan→fit mean", "f_F": "f_F"}


def _best(rows: list[dict[str, float]], truth_f_f: float) -> dict[str, float]:
    return {
        **{m: min(r[m] for r in rows) for m in ("f_R", "f_lambda", "s2f_mean_rel")},
        "truth_f_F": truth_f_f,
    }


def best_peers(results: pathlib.Path) -> Best:
    """Per case of a bench/compare.py run (its results.json): see :data:`Best`."""
    best = {}
    for cases in json.loads(results.read_text())["groups"].values():
        for c in cases:
            ok = [c["rows"][p] for p in PEERS if isinstance(c["rows"].get(p), dict) and "f_R" in c["rows"][p]]
            oracle = c["rows"].get("oracle") or {}
            if ok:
                best[c["name"]] = _best(ok, float(oracle.get("f_F", float("nan"))))
    return best


def best_peers_from_markdown(report: pathlib.Path) -> Best:
    """:data:`Best` read back from the per-case tables ("Every case, every metric") of a report
    that bench/compare.py generated (docs/notes/comparison-full-run.md), for a machine without
    its results.json:
    the peers' code and the cases are deterministic, so their rows stand until either changes.
    Figures are as printed there (4 significant digits)."""
    labels = {peers.METHODS[p]["label"]: p for p in PEERS}
    best: Best = {}
    case, header, rows, truth = None, None, [], float("nan")

    def close() -> None:
        if case is not None and rows:
            best[case] = _best(rows, truth)

    for line in report.read_text().splitlines():
        if line.startswith("<details><summary><b>"):
            close()
            case = line.split("<b>", 1)[1].split("</b>", 1)[0]
            header, rows, truth = None, [], float("nan")
        elif case is not None and line.startswith("| method |"):
            header = [c.strip() for c in line.strip("|").split("|")]
        elif case is not None and header and line.startswith("| "):
            cells = dict(zip(header, (c.strip() for c in line.strip("|").split("|"))))
            try:
                values = {m: float(cells[col]) for m, col in _MD_COLUMNS.items()}
            except (KeyError, ValueError):
                continue  # a skipped or failed run, or the separator row
            if cells["method"].startswith("oracle"):
                truth = values["f_F"]
            elif cells["method"] in labels:
                rows.append(values)
    close()
    return best


def verdict(row: dict[str, Any], best: dict[str, float]) -> dict[str, Any]:
    """One fit of a case against the best peer of the case, by the issue's criteria: the lowest
    f_R and the lowest f_λ of all methods (ties count as won), flipped faces within the truth's
    own f_F + 1 point (None without ground truth), a mean scan→fit distance no worse than the
    best peer's."""
    truth_f_f = best["truth_f_F"]
    return {
        "f_R": row["f_R"] <= best["f_R"],
        "f_lambda": row["f_lambda"] <= best["f_lambda"],
        "flips": None if truth_f_f != truth_f_f else row["f_F"] <= truth_f_f + 0.01,
        "s2f": row["s2f_mean_rel"] <= best["s2f_mean_rel"],
    }


def against_peers(rows: list[dict[str, Any]], best: Best, source: str) -> None:
    """Per variant, the issue's criteria case by case: the cases where it has the lowest f_R /
    f_λ of all methods, where its flipped faces stay within the truth's + 1 point, and where
    its mean scan→fit distance is no worse than the best peer's; and the geometric mean over
    the cases of its f_R ÷ the best peer's (overall and in its worst group)."""
    groups = list(dict.fromkeys(r["group"] for r in rows))
    print(
        f"\nagainst the best peer of each case ({source}): wins f_R / f_λ / flips ≤ truth + "
        "1 pt / scan→fit ≤ best peer\n"
    )
    print("| variant | " + " | ".join(groups) + " | f_R ÷ best (geo. mean) | worst group | f_λ ÷ best |")
    print("| :--- |" + " ---: |" * (len(groups) + 3))
    for v in dict.fromkeys(r["variant"] for r in rows):
        sel = [r for r in rows if r["variant"] == v and r["case"] in best]
        if not sel:  # no case of the run has peer figures (e.g. group dressed before --peers)
            print(f"| {v} | " + " | ".join("— (no peer figures)" for _ in groups) + " | — | — | — |")
            continue
        cells = []
        for g in groups:
            gs = [(r, best[r["case"]]) for r in sel if r["group"] == g]
            if not gs:
                cells.append("— (no peer figures)")
                continue
            vs = [verdict(r, b) for r, b in gs]
            flips = [v["flips"] for v in vs if v["flips"] is not None]
            cells.append(
                f"{sum(v['f_R'] for v in vs)} / {sum(v['f_lambda'] for v in vs)} / "
                f"{sum(flips)} of {len(flips)} / "
                f"{sum(v['s2f'] for v in vs)} of {len(gs)}"
            )

        def geo(rs: list[dict[str, Any]], m: str) -> float:
            return geo_mean(r[m] / best[r["case"]][m] for r in rs)

        worst = max(
            geo([r for r in sel if r["group"] == g], "f_R")
            for g in groups
            if any(r["group"] == g for r in sel)
        )
        print(
            f"| {v} | "
            + " | ".join(cells)
            + f" | {geo(sel, 'f_R'):.3f} | {worst:.3f} | {geo(sel, 'f_lambda'):.3f} |"
        )


def against_first(rows: list[dict[str, Any]]) -> None:
    """Case by case against the first variant: per group, the geometric mean of each other
    variant's f_R, f_λ and f_H ÷ the first's, the cases it lowers f_R on, and the mean f_F."""
    variants = list(dict.fromkeys(r["variant"] for r in rows))
    if len(variants) < 2:
        return
    first = {r["case"]: r for r in rows if r["variant"] == variants[0]}
    groups = list(dict.fromkeys(r["group"] for r in rows)) + ["all"]
    print(
        f"\ncase by case against {variants[0]!r}: geometric mean of f_R / f_λ / f_H ratios, "
        "cases with a lower f_R, mean f_F (first → variant)\n"
    )
    print("| variant | " + " | ".join(groups) + " |")
    print("| :--- |" + " ---: |" * len(groups))

    def geo(rs: list[dict[str, Any]], m: str) -> float:
        return geo_mean(r[m] / first[r["case"]][m] for r in rs)

    for v in variants[1:]:
        cells = []
        for g in groups:
            rs = [r for r in rows if r["variant"] == v and r["case"] in first and g in ("all", r["group"])]
            lower = sum(r["f_R"] < first[r["case"]]["f_R"] for r in rs)
            f_f = [np.mean([x["f_F"] for x in sel]) for sel in ([first[r["case"]] for r in rs], rs)]
            cells.append(
                f"{geo(rs, 'f_R'):.3f} / {geo(rs, 'f_lambda'):.3f} / {geo(rs, 'f_H'):.3f}, "
                f"{lower} of {len(rs)}, f_F {f_f[0]:.4f} → {f_f[1]:.4f}"
            )
        print(f"| {v} | " + " | ".join(cells) + " |")


def summary(rows: list[dict[str, Any]]) -> None:
    """Medians per group: one markdown table of f_R / f_λ (variants × groups), then every
    metric per group."""
    groups = list(dict.fromkeys(r["group"] for r in rows))
    variants = list(dict.fromkeys(r["variant"] for r in rows))

    def med(v: str, g: str, m: str) -> float:
        return float(np.median([r[m] for r in rows if r["variant"] == v and r["group"] == g]))

    print("\nmedian f_R / f_λ per group\n")
    print("| variant | " + " | ".join(groups) + " |")
    print("| :--- |" + " ---: |" * len(groups))
    for v in variants:
        print(
            f"| {v} | "
            + " | ".join(f"{med(v, g, 'f_R'):.4f} / {med(v, g, 'f_lambda'):.3f}" for g in groups)
            + " |"
        )
    for g in groups:
        print(f"\nmedians, {g}: " + " | ".join(METRICS) + " | s")
        for v in variants:
            cells = [f"{med(v, g, m):.4f}" for m in METRICS] + [f"{med(v, g, 'seconds'):.2f}"]
            print(f"  {v:<52} " + " | ".join(cells))
    against_first(rows)


def load_best(names: list[str] | None) -> tuple[Best, str]:
    """The best-peer figures of the files `names` (merged, a later file's cases replacing an
    earlier's; see ``--peers``), and a label naming them. None: ``bench/out/results.json`` if a
    bench/compare.py run left one, else :data:`PEER_FIGURES`, else docs/notes/comparison-full-run.md; and
    :data:`PEER_FIGURES_DRESSED` when present."""
    if names is None:
        json_run = HERE / "out" / "results.json"
        full_run = HERE.parent / "docs" / "notes" / "comparison-full-run.md"
        fallback = PEER_FIGURES if PEER_FIGURES.is_file() else full_run
        names = [str(json_run if json_run.is_file() else fallback)]
        if PEER_FIGURES_DRESSED.is_file():  # python -m bench.dressed --peers (group ``dressed``)
            names.append(str(PEER_FIGURES_DRESSED))
        if PEER_FIGURES_SIM.is_file():  # python -m bench.sim --peers (group ``sim``)
            names.append(str(PEER_FIGURES_SIM))
    best: Best = {}
    for name in names:
        peers_file = pathlib.Path(name)
        if not peers_file.is_file():
            raise SystemExit(f"--peers {peers_file}: no such file")
        if peers_file.suffix == ".md":
            best.update(best_peers_from_markdown(peers_file))
        elif "groups" in (data := json.loads(peers_file.read_text())):
            best.update(best_peers(peers_file))
        else:
            best.update(data["cases"])
    return best, " + ".join(names)


#: The variant name of the rows :func:`fit_rows` adds for the ground truth itself.
EXACT = "exact answer"


def fit_rows(
    groups: list[str], variants: list[tuple[str, dict[str, Any]]], truth: bool = False
) -> list[dict[str, Any]]:
    """Every variant (name, keyword arguments of ``fm.fit``) fitted on every case of
    `groups`: one row per case and variant (group, case, variant, seconds and :data:`METRICS`),
    each case's f_R / f_λ printed as a markdown row as it comes. With `truth`, also a row
    named :data:`EXACT` per case that has a ground truth: the truth itself scored as a fit
    (the "oracle", seconds 0)."""
    import foldmatch_rs as fm

    rows = []
    print("| case | " + " | ".join(v for v, _ in variants) + " |")
    print("| :--- |" + " ---: |" * len(variants))
    for group in groups:
        for case in group_cases(group):
            arrays = harness.case_arrays(case)
            cells = []
            for name, kw in variants:
                t0 = time.perf_counter()
                settings = dict(kw)
                r = fm.fit(
                    case.template_vertices,
                    case.faces,
                    case.target,
                    target_faces=case.target_faces,
                    preset=settings.pop("preset", None),
                    params=settings,
                )
                seconds = time.perf_counter() - t0
                e = harness.evaluate(arrays, r.vertices)
                rows.append(
                    {
                        "group": group,
                        "case": case.name,
                        "variant": name,
                        "seconds": seconds,
                        **{m: e[m] for m in METRICS},
                    }
                )
                cells.append(f"{e['f_R']:.4f} / {e['f_lambda']:.3f}")
            if truth and case.ground_truth is not None:
                e = harness.evaluate(arrays, case.ground_truth)
                rows.append(
                    {
                        "group": group,
                        "case": case.name,
                        "variant": EXACT,
                        "seconds": 0.0,
                        **{m: e[m] for m in METRICS},
                    }
                )
            print(f"| {case.name} | " + " | ".join(cells) + " |", flush=True)
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--groups", default="real,small")
    ap.add_argument("--variant", action="append", default=[], metavar="NAME=JSON")
    ap.add_argument("--preset", choices=sorted(PRESETS))
    ap.add_argument("--out", default=str(HERE / "out" / "variants.json"))
    ap.add_argument("--from-json", metavar="FILE", help="print the summary of an earlier run")
    ap.add_argument(
        "--peers",
        metavar="FILE",
        action="append",
        default=None,
        help="the peers to score against: a bench/compare.py results.json, or the "
        "report it generated (docs/notes/comparison-full-run.md, its per-case "
        "tables); repeat "
        "to merge several (a later file's cases replace an earlier's); "
        "default bench/out/results.json if present, else bench/peer_figures.json, "
        "else docs/notes/comparison-full-run.md",
    )
    ap.add_argument(
        "--save-peers",
        metavar="FILE",
        help="write the merged best-peer figures (JSON, per case) and exit; "
        "bench/peer_figures.json is read by default when present",
    )
    args = ap.parse_args()
    best, source = load_best(args.peers)
    if args.save_peers:
        pathlib.Path(args.save_peers).write_text(
            json.dumps(
                {
                    "about": "per case, the lowest f_R, f_lambda and s2f_mean_rel of the peers "
                    f"({', '.join(PEERS)}) and the truth's f_F; written by "
                    "python -m bench.variants --save-peers from " + source,
                    "cases": best,
                },
                indent=1,
                sort_keys=True,
            )
            + "\n"
        )
        return 0

    def report(rows: list[dict[str, Any]]) -> None:
        summary(rows)
        against_peers(rows, best, source)

    if args.from_json:
        report(json.loads(pathlib.Path(args.from_json).read_text()))
        return 0
    variants = list(PRESETS[args.preset]) if args.preset else []
    variants += [parse_variant(v) for v in args.variant]
    if not variants:
        raise SystemExit("no variant: give --preset or --variant")
    rows = fit_rows(args.groups.split(","), variants)
    report(rows)
    pathlib.Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    pathlib.Path(args.out).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
