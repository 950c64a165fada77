#!/usr/bin/env python
"""FoldMatch against the methods users would pick instead, on the same cases (issue 4,
docs/results.md).

One command regenerates docs/notes/comparison-full-run.md (its generated blocks), the figures in docs/figures/
and the JSON in bench/out/results.json::

    .venv/bin/python -m bench.compare --cases all          # the full run (hours on 2 cores)
    .venv/bin/python -m bench.compare --quick              # the CI case (< 1 min)

Groups (``--cases``, comma-separated): ``small`` (generated, ≈1.6K vertices, 3 shapes × 3 scan
variants), ``paper`` (the same at ≈13K vertices / 14.4K points), ``real`` (../shared/data, mesh
and point-cloud targets), ``samples`` (24 random folded sheets + 30 wind-sequence frames, for
the box plots), ``figures`` (f_λ per iteration, WVF per ring, overlays; needs the others' runs),
``all`` (every one of them). Methods (``--methods``): foldmatch, nrga, cpd_pycpd, cpd_probreg,
cpd_rustcpd, bcpd_probreg, nricp_amberg, nricp_sumner (default: all). A method that cannot be
imported, or a case too large for a dense method, is recorded as skipped with the reason.

Every (case, method) run is its own process (wall time of the method alone, peak RSS by
getrusage); finished runs are kept in ``--out``/runs and reused (``--force`` reruns).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import pathlib
import sys
import time
from typing import Any

import numpy as np

from bench import cases as cases_mod
from bench import harness, peers, report
from bench.harness import log

HERE = pathlib.Path(__file__).resolve().parent

REPO = HERE.parent
GROUPS = ["small", "paper", "real", "samples", "figures"]
QUICK_METHODS = [
    "foldmatch",
    "foldmatch_paper",
    "nrga",
    "cpd_pycpd",
    "cpd_rustcpd",
    "cpd_probreg",
    "bcpd_probreg",
    "nricp_amberg",
    "nricp_sumner",
]
GROUP_TITLES = {
    "quick": "CI case (17 × 17 sheet, 400 noisy points)",
    "small": "Generated cases, small (≈1.6K template vertices, 2K scan points; clean / noisy / holes)",
    "paper": "Generated cases, paper size (≈13K template vertices, 14.4K scan points; noisy / holes)",
    "real": "Real garments (../shared/data), mesh and point-cloud targets",
    "samples-sheet": "24 random folded sheets (box plots, Fig. 6 analogue)",
    "samples-wind": "30 wind-sequence frames, point-cloud targets (box plots)",
}
TRACE_CASES = ["vto-tshirt-0000-pts", "vto-tshirt-arm-pts"]
OVERLAY_CASES = [
    "shirt-small-noisy",
    "skirt-small-holes",
    "sheet-paper-noisy",
    "vto-tshirt-0000-pts",
    "tshirt-biFolded-pts",
    "skirt-penetrate-pts",
]


def build_cases(group: str) -> tuple[list[cases_mod.Case], list[str]]:
    """The cases of a group and the notes on what could not be built."""
    notes: list[str] = []
    if group == "quick":
        return [cases_mod.quick_case()], notes
    if group == "small":
        return list(cases_mod.generated_cases(group)), notes
    if group == "paper":  # the clean variant only at the small size (the paper sizes are slow)
        return list(cases_mod.generated_cases(group, ("noisy", "holes"))), notes
    if group in ("real", "samples"):
        out = list(cases_mod.sheet_samples()) if group == "samples" else []
        why = cases_mod.real_data_missing()
        if why:
            notes.append(f"real-data cases skipped: {why}")
            return out, notes
        out += list(cases_mod.wind_samples() if group == "samples" else cases_mod.real_cases())
        return out, notes
    raise ValueError(group)


def load_results(path: pathlib.Path) -> dict[str, Any]:
    if path.exists():
        return json.loads(path.read_text())
    return {"groups": {}, "notes": {}}


def save_json(path: pathlib.Path, data: Any) -> None:
    def clean(o: Any) -> Any:
        if isinstance(o, dict):
            return {k: clean(v) for k, v in o.items() if not str(k).startswith("_")}
        if isinstance(o, (list, tuple)):
            return [clean(v) for v in o]
        if isinstance(o, (np.floating, float)):
            f = float(o)
            return f if np.isfinite(f) else str(f)
        if isinstance(o, np.integer):
            return int(o)
        if isinstance(o, np.ndarray):
            return o.tolist()
        return o

    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(clean(data), indent=1))
    os.replace(tmp, path)


# ---- figures --------------------------------------------------------------------------------


def make_figures(
    runner: harness.Runner, results: dict, methods: list[str], figdir: pathlib.Path
) -> list[tuple[str, str]]:
    from bench import figures

    made: list[tuple[str, str]] = []
    groups = results["groups"]
    for g, fname in (
        ("samples-sheet", "fig6_boxplots_sheets.png"),
        ("samples-wind", "fig6_boxplots_wind.png"),
    ):
        if groups.get(g):
            p = figures.boxplots(
                groups[g], methods, figdir / fname, f"{GROUP_TITLES[g]}: every metric per method"
            )
            made.append(
                (
                    fname,
                    (
                        f"Box plots of every metric per method over the "
                        f"{len(groups[g])} cases of '{g}' (paper Fig. 6)."
                    ),
                )
            )
            log(f"figure {p}")
    if cases_mod.real_data_missing() is None:
        real = {c.name: c for c in cases_mod.real_cases()}
    else:
        real = {}
    gen = {c.name: c for c in cases_mod.generated_cases("small")}
    gen.update({c.name: c for c in cases_mod.generated_cases("paper", ("noisy",))})
    allc = {**gen, **real}

    # Fig. 4: f_λ (and f_R) per iteration, one template fitted to two scans.
    curves: dict[str, dict] = {}
    trace_methods = {
        "foldmatch": {"iterations": 200},
        "foldmatch_paper": {"iterations": 200},
        "nrga": {"iterations": 200},
        "cpd_rustcpd": {"maxiter": 200, "tol": 0.0},
        "nricp_amberg": {},
        "nricp_sumner": {},
    }
    for cname in TRACE_CASES:
        case = allc.get(cname)
        if case is None:
            continue
        arrays = harness.case_arrays(case)
        curves[cname] = {}
        for m, ov in trace_methods.items():
            if m not in methods:
                continue
            row = runner.run(case, m, trace=True, overrides=ov, tag="trace")
            tr = row.get("_trace")
            if tr is None:
                log(f"  trace {cname} {m}: {row.get('status')} {row.get('reason') or row.get('error')}")
                continue
            ev = [harness.evaluate(arrays, np.asarray(t, dtype=np.float64)) for t in tr]
            curves[cname][m] = {"f_lambda": [e["f_lambda"] for e in ev], "f_R": [e["f_R"] for e in ev]}
            log(f"  trace {cname} {m}: {len(tr) - 1} iterations, final f_lambda {ev[-1]['f_lambda']:.4f}")
        o = harness.evaluate(arrays, case.ground_truth)
        curves[cname]["oracle"] = {"f_lambda": [o["f_lambda"]], "f_R": [o["f_R"]]}
    if any(len(v) > 1 for v in curves.values()):
        figures.traces(
            curves,
            figdir / "fig4_flambda_per_iteration.png",
            "One smooth T-shirt template fitted to two wrinkled frames "
            "(5K noisy points): f_λ and f_R per iteration",
        )
        made.append(
            (
                "fig4_flambda_per_iteration.png",
                (
                    "f_λ (top) and f_R (bottom) per iteration (paper Fig. 4); FoldMatch and "
                    "NRGa 200 iterations, CPD (rustcpd) 200 EM iterations, NRICP per solve."
                ),
            )
        )
        results["traces"] = curves
        log("figure fig4")

    # Fig. 5: accumulated WVF magnitude for 1- to 4-ring neighborhoods.
    case = allc.get("vto-tshirt-0000-mesh") or allc.get("shirt-small-noisy")
    if case is not None and "foldmatch" in methods:
        import foldmatch_rs as fm

        fits = {}
        ringstats = {}
        arrays = harness.case_arrays(case)
        for n in (1, 2, 3, 4):
            r = fm.fit(
                case.template_vertices, case.faces, case.target, target_faces=case.target_faces, rings=n
            )
            fits[n] = (r.vertices, case.faces, r.wvf_accumulated_magnitude)
            e = harness.evaluate(arrays, r.vertices)
            ringstats[n] = {
                "f_R": e["f_R"],
                "f_lambda": e["f_lambda"],
                "f_F": e["f_F"],
                "wvf_acc_mag_p5_p95": np.percentile(r.wvf_accumulated_magnitude, [5, 95]).tolist(),
            }
        figures.rings(
            case.target,
            case.target_faces,
            fits,
            figdir / "fig5_wvf_rings.png",
            f"FoldMatch on {case.name}: accumulated wrinkle-field magnitude, "
            f"1- to 4-ring template neighborhoods",
            up=case.meta.get("up", 2),
        )
        results["rings"] = {"case": case.name, "stats": ringstats}
        made.append(
            (
                "fig5_wvf_rings.png",
                (
                    f"Accumulated WVF magnitude on the fitted mesh of {case.name} for 1-, 2-, "
                    f"3- and 4-ring neighborhoods (paper Fig. 5), shared color scale."
                ),
            )
        )
        log("figure fig5")

    # Before/after overlays.
    show = [
        m
        for m in (
            "foldmatch",
            "foldmatch_paper",
            "nrga",
            "cpd_rustcpd",
            "cpd_pycpd",
            "nricp_amberg",
            "nricp_sumner",
        )
        if m in methods
    ]
    for cname in OVERLAY_CASES:
        case = allc.get(cname)
        if case is None:
            continue
        fits, stats = {}, {}
        for m in show:
            if len(fits) >= 6:
                break
            if m == "cpd_pycpd" and "cpd_rustcpd" in fits:
                continue
            row = runner.run(case, m)
            if row.get("_fitted") is not None:
                fits[m] = row["_fitted"]
                stats[m] = harness.evaluate(harness.case_arrays(case), row["_fitted"])
        if fits:
            fname = f"overlay_{cname}.png"
            figures.overlay(case, fits, stats, figdir / fname, up=case.meta.get("up", 2))
            made.append(
                (
                    fname,
                    (
                        f"Before/after on {cname}: template and scan points, the "
                        f"truth, and each fit colored by its distance to the truth."
                    ),
                )
            )
            log(f"figure {fname}")
    return made


# ---- report ---------------------------------------------------------------------------------

SKELETON = """# FoldMatch against CPD, non-rigid ICP and NRGa

Regenerate with `.venv/bin/python -m bench.compare --cases all` (see bench/README.md). The
blocks between `BEGIN GENERATED` / `END GENERATED` markers are rewritten by that command; the
text around them is written by hand.
"""


def render_report(
    results: dict,
    methods: list[str],
    status: dict,
    command: str,
    figures_made: list[tuple[str, str]],
    figrel: str,
) -> dict[str, str]:
    blocks: dict[str, str] = {}
    v = results.get("versions", {})
    mach = results.get("machine", {})
    blocks["header"] = "\n".join(
        [
            f"Generated {results.get('date', '?')} by `{command}`.",
            "",
            (
                f"- Machine: {mach.get('Model name', '?')}, {mach.get('CPU(s)', mach.get('cpus'))} "
                f"CPUs ({mach.get('Hypervisor vendor', 'bare metal')} VM), "
                f"{mach.get('memory_gib', '?')} GiB RAM, {mach.get('platform', '')}; load average at "
                f"start {', '.join(f'{x:.1f}' for x in mach.get('loadavg_at_start', []))} "
                f"(the machine is shared: wall times are indicative, ±30 %)."
            ),
            "- Versions: " + ", ".join(f"{k} {val}" for k, val in v.items()) + ".",
            f"- Code: {results.get('code', '?')}.",
            "- FoldMatch parameters (`fm.DEFAULT_PARAMS`): `"
            + json.dumps(results.get("foldmatch_defaults", {}))
            + "`.",
            "- FoldMatch (paper preset) parameters (`fm.PAPER_PARAMS`): `"
            + json.dumps(results.get("foldmatch_paper_params", {}))
            + "`.",
        ]
    )
    rows = []
    for m in methods:
        spec = peers.METHODS[m]
        st = status.get(m)
        rows.append(
            [
                spec["label"],
                "skipped: " + st if st else "run",
                "`" + json.dumps(spec["params"]).replace("|", "/") + "`",
                spec["note"],
            ]
        )
    blocks["methods"] = report.table(
        ["method", "status here", "parameters", "notes"], rows, ["l", "l", "l", "l"]
    )
    groups = results["groups"]
    order = ["quick", "small", "paper", "real", "samples-sheet", "samples-wind"]
    summ, per_case = [], []
    for g in order:
        recs = groups.get(g)
        if not recs:
            continue
        summ += [
            f"### {GROUP_TITLES.get(g, g)}",
            "",
            (
                "Medians over the cases (peak RSS: maximum); ratios are medians of per-case "
                "ratios to FoldMatch."
            ),
            "",
            report.summary_table(recs, methods),
            "",
            report.wins_table(recs, methods),
            "",
        ]
        if g.startswith("samples"):
            continue
        per_case += [f"### {GROUP_TITLES.get(g, g)}", ""]
        for rec in recs:
            meta = rec.get("meta", {})
            desc = ", ".join(f"{k}={val}" for k, val in meta.items() if k not in ("source", "up"))
            per_case += [
                (
                    f"<details><summary><b>{rec['name']}</b> — M={rec['template_vertices']},"
                    f" N={rec['target_points']}{' (mesh target)' if rec['target_is_mesh'] else ''}"
                    f"</summary>"
                ),
                "",
                f"Source: {meta.get('source', '?')}; {desc}",
                "",
                report.case_table(rec, methods),
                "",
                "</details>",
                "",
            ]
    notes = results.get("notes", {})
    if notes:
        summ += ["Notes: " + "; ".join(f"{k}: {'; '.join(n)}" for k, n in notes.items() if n)]
    blocks["summary"] = "\n".join(summ) if summ else "_no groups run yet_"
    blocks["cases"] = "\n".join(per_case) if per_case else "_no groups run yet_"
    q = []
    for g in ("samples-sheet", "samples-wind"):
        if groups.get(g):
            q += [
                (
                    f"**{GROUP_TITLES[g]}**: third quartile (Q3) of every metric over the "
                    f"samples; ratios are to FoldMatch's Q3 (f_λ, f_R) and maximum (f_λ)."
                ),
                "",
                report.quantile_table(groups[g], methods, ["f_H", "f_S", "f_E", "f_F", "f_R", "f_lambda"]),
                "",
            ]
    blocks["paper-claims"] = "\n".join(q) if q else "_samples not run yet_"
    if figures_made:
        blocks["figures"] = "\n\n".join(f"![{n}]({figrel}/{n})\n\n*{cap}*" for n, cap in figures_made)
    return blocks


def print_summary(results: dict, methods: list[str]) -> None:
    for g, recs in results["groups"].items():
        if recs:
            print(f"\n## {GROUP_TITLES.get(g, g)}\n")
            print(report.summary_table(recs, methods))


# ---- main -----------------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "--cases",
        default="small",
        help="comma-separated groups: quick, small, paper, real, samples, figures, all (default: small)",
    )
    ap.add_argument(
        "--methods",
        default=",".join(peers.ALL_METHODS),
        help=f"comma-separated, from {', '.join(peers.ALL_METHODS)}",
    )
    ap.add_argument("--out", default=str(HERE / "out"), help="JSON and run cache (bench/out)")
    ap.add_argument(
        "--quick",
        action="store_true",
        help="the CI case: a tiny sheet, every method that imports; report and JSON "
        "under --out, docs/ untouched",
    )
    ap.add_argument(
        "--report",
        default=None,
        help="Markdown report to update (default docs/notes/comparison-full-run.md; with --quick "
        "OUT/results.md)",
    )
    ap.add_argument(
        "--figures-dir",
        default=None,
        help="where figures go (default docs/figures; with --quick OUT/figures)",
    )
    ap.add_argument("--no-report", action="store_true", help="only the JSON")
    ap.add_argument("--force", action="store_true", help="rerun cached runs")
    ap.add_argument("--timeout", type=float, default=1800, help="per run, seconds (1800)")
    args = ap.parse_args(argv)

    out = pathlib.Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    if args.quick:
        groups = ["quick"]
        default_methods = QUICK_METHODS
    else:
        groups = GROUPS if args.cases == "all" else [g.strip() for g in args.cases.split(",")]
        default_methods = peers.ALL_METHODS
    for g in groups:
        if g not in GROUPS + ["quick"]:
            ap.error(f"unknown case group {g!r}")
    methods = (
        [m.strip() for m in args.methods.split(",")]
        if args.methods != ",".join(peers.ALL_METHODS)
        else default_methods
    )
    for m in methods:
        if m not in peers.METHODS:
            ap.error(f"unknown method {m!r} (known: {', '.join(peers.METHODS)})")
    report_path = (
        pathlib.Path(args.report)
        if args.report
        else (out / "results.md" if args.quick else REPO / "docs" / "notes" / "comparison-full-run.md")
    )
    figdir = (
        pathlib.Path(args.figures_dir)
        if args.figures_dir
        else (out / "figures" if args.quick else REPO / "docs" / "figures")
    )

    import foldmatch_rs as fm

    status = harness.method_status(methods)
    for m in methods:
        if status.get(m):
            log(f"{m}: skipped everywhere: {status[m]}")
    results_path = out / ("results-quick.json" if args.quick else "results.json")
    results = load_results(results_path)
    results.update(
        date=datetime.datetime.now().isoformat(timespec="seconds"),
        machine=harness.machine(),
        versions=peers.versions(),
        foldmatch_defaults=fm.DEFAULT_PARAMS,
        foldmatch_paper_params=getattr(fm, "PAPER_PARAMS", None),
        code=harness.code_version(),
        methods={
            m: {
                "label": peers.METHODS[m]["label"],
                "params": peers.METHODS[m]["params"],
                "note": peers.METHODS[m]["note"],
                "status": "skipped" if status.get(m) else "available",
                "reason": status.get(m),
            }
            for m in methods
        },
        mesh_targets_for_nricp=status.get("_rtree") or "available",
    )
    runner = harness.Runner(out, timeout=args.timeout, force=args.force, status=status)
    t0 = time.time()
    for g in groups:
        if g == "figures":
            continue
        cs, notes = build_cases(g)
        results.setdefault("notes", {})[g] = notes
        for n in notes:
            log(n)
        log(f"group {g}: {len(cs)} cases × {len(methods)} methods")
        recs_by_group: dict[str, list] = {}
        for case in cs:
            rec = harness.run_case(runner, case, methods)
            recs_by_group.setdefault(case.group, []).append(rec)
            for sub, recs in recs_by_group.items():
                results["groups"][sub] = recs
            save_json(results_path, results)
    made: list[tuple[str, str]] = []
    if "figures" in groups:
        made = make_figures(runner, results, methods, figdir)
        results["figures"] = made
    elif results.get("figures"):
        made = [tuple(x) for x in results["figures"]]
    results["elapsed_s"] = round(time.time() - t0, 1)
    save_json(results_path, results)
    command = "python -m bench.compare " + " ".join(argv if argv is not None else sys.argv[1:])
    if not args.no_report:
        try:
            figrel = os.path.relpath(figdir, report_path.parent)
        except ValueError:
            figrel = str(figdir)
        blocks = render_report(results, methods, status, command.strip(), made, figrel)
        report.write_blocks(report_path, blocks, SKELETON)
        log(f"report {report_path}")
    print_summary(results, methods)
    log(f"JSON {results_path} ({time.time() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
