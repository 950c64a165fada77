"""The default and the peers on the physically simulated cases (issue 28; docs/simulated.md).

    .venv/bin/python -m bench.sim                      # the default on every case, beside the peers' figures
    .venv/bin/python -m bench.sim --scenes sphere,box  # some scenes
    nice .venv/bin/python -m bench.sim --peers         # run the peers, write bench/peer_figures_sim.json
    .venv/bin/python -m bench.sim --store-tiny         # regenerate bench/data/sim-sphere-tiny.npz
    .venv/bin/python -m bench.sim --json rows.json     # keep the rows (--from-json rows.json: reprint)

Prints per case: the default's f_R and flipped-face share f_F, the truth's own f_F, every
peer's f_R (bench/peer_figures_sim.json, written by ``--peers``: each peer run in its own
process as bench/compare.py runs them, cached in ``bench/out/sim/peers``, the dense ones
skipped above their size limits as everywhere in the harness) and the default's f_R ÷ the best
peer's. The cases are bench/sim_cases.py's (group ``sim`` of bench/variants.py and
bench/standing.py); the simulated states are bench/sim_cloth.py's cache, simulated on the
first run when Newton is installed (``pip install -r bench/requirements-sim.txt``).
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
from bench import sim_cases, sim_cloth

HERE = pathlib.Path(__file__).resolve().parent
#: The peers' figures on the simulated cases (best peer per case, as bench/peer_figures.json,
#: plus every method's figures), written by ``--peers``, read by bench/variants.py.
PEER_FIGURES = HERE / "peer_figures_sim.json"
OUT = sim_cloth.OUT


def run_peers(
    cases: list[cases_mod.Case], methods: list[str], timeout: float, force: bool, cached_only: bool = False
) -> dict[str, Any]:
    """Every method of ``methods`` on every case (bench/harness.py's runner, one process per
    run, cached); writes ``bench/out/sim/peers/results.json`` and :data:`PEER_FIGURES`.
    ``cached_only``: collect the runs already in the cache, start none."""
    from bench import compare, harness, peers, variants

    out = OUT / "peers"
    out.mkdir(parents=True, exist_ok=True)
    status = harness.method_status(methods)
    runner = harness.Runner(out, timeout=timeout, force=force, status=status)
    results: dict[str, Any] = {
        "groups": {"sim": []},
        "machine": harness.machine(),
        "versions": peers.versions(),
        "code": harness.code_version(),
    }
    path = out / "results.json"
    for case in cases:
        harness.log(f"{case.name}: {case.sizes}")
        ran = [m for m in methods if (out / "runs" / case.name / f"{m}.npz.json").is_file()]
        results["groups"]["sim"].append(harness.run_case(runner, case, ran if cached_only else methods))
        compare.save_json(path, results)
    old = json.loads(PEER_FIGURES.read_text()) if PEER_FIGURES.is_file() else {}
    merged: dict[str, dict[str, Any]] = old.get("methods", {})
    for rec in results["groups"]["sim"]:
        per = merged.setdefault(rec["name"], {})
        for m, r in rec["rows"].items():
            if r.get("status") == "ok":
                per[m] = {k: r.get(k) for k in ("f_R", "f_F", "f_lambda", "s2f_mean_rel", "wall_s")}
                per[m]["status"] = "ok"
            elif per.get(m, {}).get("status") != "ok":  # a run of other methods keeps these
                per[m] = {"status": r.get("status"), "why": r.get("reason") or r.get("error")}
    best = {}
    for name, per in merged.items():
        ok = [per[m] for m in variants.PEERS if per.get(m, {}).get("status") == "ok"]
        if ok:
            best[name] = {k: min(x[k] for x in ok) for k in ("f_R", "f_lambda", "s2f_mean_rel")}
            best[name]["truth_f_F"] = per.get("oracle", {}).get("f_F", float("nan"))
    figures = {
        "about": "per simulated case (bench/sim_cases.py), the lowest f_R, f_lambda and "
        f"s2f_mean_rel of the peers ({', '.join(variants.PEERS)}) and the truth's f_F (`cases`, "
        "read by bench/variants.py); every method's figures (`methods`, merged over runs: a "
        "run of some methods or scenes keeps the others' figures); written by "
        "nice .venv/bin/python -m bench.sim --peers",
        "code": results["code"],
        "cases": best,
        "methods": merged,
    }
    PEER_FIGURES.write_text(json.dumps(figures, indent=1, sort_keys=True, default=str) + "\n")
    harness.log(f"wrote {PEER_FIGURES}")
    return figures


def fit_default(case: cases_mod.Case) -> dict[str, Any]:
    """The library default on one case, and the truth scored as a fit."""
    import foldmatch_rs as fm

    from bench import harness

    arrays = harness.case_arrays(case)
    t0 = time.perf_counter()
    r = fm.fit(case.template_vertices, case.faces, case.target, target_faces=case.target_faces)
    seconds = time.perf_counter() - t0
    e = harness.evaluate(arrays, r.vertices)
    truth = harness.evaluate(arrays, case.ground_truth)
    return {
        "case": case.name,
        "seconds": seconds,
        "f_R": e["f_R"],
        "f_F": e["f_F"],
        "truth_f_F": truth["f_F"],
    }


def render(rows: list[dict[str, Any]], figures: dict[str, Any]) -> str:
    from bench import peers, report

    methods = [m for m in peers.METHODS if m not in ("foldmatch", "foldmatch_paper")]
    per = figures.get("methods", {})
    ran = [m for m in methods if any(per.get(r["case"], {}).get(m, {}).get("status") == "ok" for r in rows)]
    header = ["case", "default f_R", "f_F", "truth f_F"] + [peers.METHODS[m]["label"] for m in ran]
    header += ["÷ best peer", "s"]
    body = []
    for r in rows:
        pc = per.get(r["case"], {})
        cells = [r["case"], f"{r['f_R']:.4f}", f"{100 * r['f_F']:.1f} %", f"{100 * r['truth_f_F']:.1f} %"]
        ok = {m: pc[m]["f_R"] for m in ran if pc.get(m, {}).get("status") == "ok"}
        for m in ran:
            x = pc.get(m, {})
            cells.append(f"{x['f_R']:.4f}" if x.get("status") == "ok" else str(x.get("status", "—")))
        best = min(ok.values()) if ok else float("nan")
        cells += [f"{r['f_R'] / best:.2f}" if ok else "—", f"{r['seconds']:.1f}"]
        body.append(cells)
    wins = sum(
        1
        for r in rows
        if per.get(r["case"])
        and all(
            r["f_R"] <= x["f_R"] for m, x in per[r["case"]].items() if m in ran and x.get("status") == "ok"
        )
    )
    flips = sum(1 for r in rows if r["f_F"] <= r["truth_f_F"] + 0.01)
    ratios = [
        r["f_R"] / min(x["f_R"] for m, x in per[r["case"]].items() if m in ran and x.get("status") == "ok")
        for r in rows
        if any(x.get("status") == "ok" for m, x in per.get(r["case"], {}).items() if m in ran)
    ]
    lines = [report.table(header, body, "l" + "r" * (len(header) - 1)), ""]
    if ratios:
        geo = float(np.exp(np.mean(np.log(ratios))))
        lines.append(
            f"default lowest f_R on {wins}/{len(ratios)} cases; f_R ÷ best peer (geo. mean) {geo:.3f}; "
            f"flipped faces within the truth's + 1 point on {flips}/{len(rows)}"
        )
    return "\n".join(lines)


def preview(scenes: tuple[str, ...], path: pathlib.Path) -> None:
    """One PNG of the rest meshes (top row) and the simulated states (bottom row)."""
    import matplotlib.pyplot as plt

    from bench import render

    fig = plt.figure(figsize=(3 * len(scenes), 6))
    for k, name in enumerate(scenes):
        sim = sim_cloth.simulate_cached(sim_cloth.SCENES[name])
        for row, (v, title) in enumerate(((sim.rest, f"{name}: rest"), (sim.final, f"{name}: simulated"))):
            ax = fig.add_subplot(2, len(scenes), row * len(scenes) + k + 1, projection="3d")
            render.draw_mesh(ax, v, sim.faces, elev=25, azim=-60)
            render.frame_axes(ax, v)
            ax.set_title(title, fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    plt.close(fig)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default=",".join(sim_cloth.SCENES), help=", ".join(sim_cloth.SCENES))
    ap.add_argument(
        "--peers", action="store_true", help="run the peers and write bench/peer_figures_sim.json"
    )
    ap.add_argument("--methods", default="", help="--peers: comma-separated (default: every peer)")
    ap.add_argument("--timeout", type=float, default=900, help="--peers: per run, seconds")
    ap.add_argument("--force", action="store_true", help="--peers: rerun cached runs")
    ap.add_argument("--cached-peers", action="store_true", help="--peers: collect cached runs, start none")
    ap.add_argument("--store-tiny", action="store_true", help="regenerate bench/data/sim-sphere-tiny.npz")
    ap.add_argument("--json", metavar="FILE", help="write the default's rows")
    ap.add_argument("--from-json", metavar="FILE", help="print the table of an earlier run's rows (--json)")
    ap.add_argument("--preview", metavar="PNG", help="draw the rest and simulated meshes and exit")
    args = ap.parse_args()
    if args.store_tiny:
        r = sim_cases.store_tiny()
        print(
            f"wrote {sim_cases.TINY}: {r.info['edge_ratio_p01_p50_p99']} edge ratios, {r.info['seconds']} s"
        )
        return 0
    scenes = tuple(args.scenes.split(","))
    unknown = [s for s in scenes if s not in sim_cloth.SCENES]
    if unknown:
        raise SystemExit(f"unknown scenes {unknown} ({', '.join(sim_cloth.SCENES)})")
    if args.from_json:
        figures = json.loads(PEER_FIGURES.read_text()) if PEER_FIGURES.is_file() else {}
        print(render(json.loads(pathlib.Path(args.from_json).read_text()), figures))
        return 0
    if args.preview:
        preview(scenes, pathlib.Path(args.preview))
        print(f"wrote {args.preview}")
        return 0
    cases = list(sim_cases.sim_cases(scenes))
    if args.peers:
        from bench import variants

        methods = args.methods.split(",") if args.methods else list(variants.PEERS)
        run_peers(cases, methods, args.timeout, args.force, args.cached_peers)
    rows = []
    for case in cases:
        rows.append(fit_default(case))
        r = rows[-1]
        print(
            f"{case.name:22s} {case.sizes:18s} f_R {r['f_R']:.4f}  f_F {100 * r['f_F']:.1f} %  "
            f"truth f_F {100 * r['truth_f_F']:.1f} %  {r['seconds']:.1f} s",
            flush=True,
        )
    figures = json.loads(PEER_FIGURES.read_text()) if PEER_FIGURES.is_file() else {}
    print()
    print(render(rows, figures))
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
