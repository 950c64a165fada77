"""Console tables and the scaling figure of a run of ``bench.perf``."""

from __future__ import annotations

import json
import math
import pathlib
from typing import Any

import numpy as np

from bench.perf_analysis import ok, oracle_of
from bench.perf_plan import STAGE_NAMES, STAGES, describe, log, run_name

#: Table columns holding text (left-aligned); the others are numbers (right-aligned).
TEXT_COLUMNS = {
    "method",
    "stage",
    "target",
    "wanted",
    "notes",
    "ours",
    "other",
    "",
    "f_λ ours vs other",
}


def table(header: list[str], rows: list[list[str]]) -> str:
    sep = [":---" if i == 0 or h in TEXT_COLUMNS else "---:" for i, h in enumerate(header)]
    lines = ["| " + " | ".join(header) + " |", "| " + " | ".join(sep) + " |"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def f_s(v: float | None, digits: int = 2) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "—"
    if v >= 100:
        return f"{v:.0f}"
    if v >= 0.1 or digits == 0:
        return f"{v:.{digits}f}"
    return f"{v:.3g}"


def label(r: dict[str, Any]) -> str:
    if r["kind"] == "foldmatch":
        return f"FoldMatch ({run_name(r)})"
    if r["kind"] == "reference":
        return "NumPy reference (tests/reference.py)"
    from bench import peers

    return peers.METHODS[r["method"]]["label"]


def status_note(r: dict[str, Any]) -> str:
    if r.get("skip"):
        return "skipped: " + r["skip"]
    if r.get("status") != "ok":
        return f"{r.get('status')}: {r.get('error', '')}"
    notes = []
    if r["kind"] == "reference":
        notes.append(
            f"{r['iterations']} iteration(s) run, 100 extrapolated (setup "
            f"{r['setup_s']:.1f} s + 100 × per-iteration)"
        )
    if r["kind"] == "peer":
        if r.get("overrides"):
            notes.append(f"capped: {json.dumps(r['overrides'])}")
        if r.get("low_rank_method") == "pivoted_cholesky":
            notes.append("pivoted-Cholesky low-rank kernel")
    if r["kind"] in ("foldmatch", "peer") and len(r.get("walls_s", [])) > 1:
        notes.append("best of " + ", ".join(f"{w:.2f}" for w in r["walls_s"]) + " s")
    return "; ".join(notes)


def section_table(recs: list[dict[str, Any]]) -> str:
    rows = []
    oracle = oracle_of(recs)
    if oracle:
        rows.append(
            ["exact answer (the ground truth itself)"]
            + ["—"] * 5
            + [f"{oracle['f_lambda']:.3f}", f"{oracle['f_R']:.4f}"]
            + [f"f_H {oracle['f_H']:.3f} (noise, boundary)"]
        )
    for r in recs:
        q = r.get("quality") or {}
        good = r.get("status") == "ok" and not r.get("skip")
        wall = r.get("extrapolated_100_s") if r["kind"] == "reference" else r.get("wall_s")
        rows.append(
            [
                label(r),
                f_s(wall) if good else "—",
                str(r.get("iterations", "—")) if good else "—",
                f_s(1000 * r["per_iteration_s"], 1) if good and r.get("per_iteration_s") else "—",
                f_s(r.get("peak_rss_mb"), 0) if good else "—",
                (f"{r.get('threads') or 'all'} / {r.get('os_threads', '?')} / {r.get('cpu_per_wall', 0):.2f}")
                if good
                else "—",
                f"{q['f_lambda']:.3f}" if q else "—",
                f"{q['f_R']:.4f}" if q and q.get("f_R") is not None else "—",
                status_note(r),
            ]
        )
    return table(
        [
            "method",
            "wall (s)",
            "iterations",
            "ms / iteration",
            "peak RSS (MB)",
            "threads: asked / OS / busy",
            "f_λ",
            "f_R",
            "notes",
        ],
        rows,
    )


def stage_table(recs: list[dict[str, Any]], name_of) -> str:
    recs = [r for r in recs if ok(r) and r["kind"] == "foldmatch"]
    if not recs:
        return "_(no FoldMatch run completed)_"
    header = ["stage"] + [name_of(r) for r in recs]
    rows = []
    for s in STAGES + ["setup"]:
        cells = []
        for r in recs:
            v = r["stage_seconds"].get(s, 0.0)
            share = 100 * v / r["wall_s"] if r["wall_s"] else 0
            cells.append(f"{v:.3f} s ({share:.0f} %)")
        rows.append([STAGE_NAMES[s]] + cells)
    rows.append(["**total wall**"] + [f"**{r['wall_s']:.3f} s**" for r in recs])
    return table(header, rows)


def print_console(recs: list[dict[str, Any]], a: dict[str, Any]) -> None:
    print()
    for sec in ("peers", "threads", "sweep_m", "sweep_n", "large"):
        rs = [r for r in recs if r["section"] == sec]
        if not rs:
            continue
        print(f"== {sec} ==")
        for r in rs:
            if r.get("skip"):
                print(f"  {describe(r):60s} skipped ({r['skip'][:70]}…)")
                continue
            if r.get("status") != "ok":
                print(f"  {describe(r):60s} {r.get('status')}: {r.get('error', '')[:80]}")
                continue
            q = r.get("quality", {})
            flam = f"{q['f_lambda']:.3f}" if q else "—"
            wall = r.get("extrapolated_100_s", r.get("wall_s"))
            extra = "  (100 it. extrapolated)" if r["kind"] == "reference" else ""
            per = r.get("per_iteration_s")
            print(
                f"  {describe(r):60s} wall {wall:8.2f} s  "
                f"{1000 * per if per else float('nan'):8.1f} "
                f"ms/it  peak {r['peak_rss_mb']:7.0f} MB  thr {r.get('os_threads', '?'):>2} "
                f"busy {r.get('cpu_per_wall', 0):.2f}  f_λ {flam}"
                f"{extra}"
            )
            if r["kind"] == "foldmatch":
                st = r["stage_seconds"]
                print("      " + "  ".join(f"{s} {st.get(s, 0):.3f}" for s in STAGES + ["setup"]))
    print("\n== targets ==")
    for t in a["targets"]:
        met = {True: "met", False: "MISSED", None: "n/a"}[t["met"]]
        print(f"  {t['name']:70s} {t['target']:38s} {t['value']:>10s}  {met}")


def figure(recs: list[dict[str, Any]], a: dict[str, Any], path: pathlib.Path, quick: bool) -> None:
    try:
        import matplotlib
    except ImportError:  # bench/requirements-full.txt; the tables are written without it
        log(f"matplotlib is not installed (bench/requirements-full.txt): {path.name} not redrawn")
        return

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6))
    sm = sorted((r for r in recs if r["section"] == "sweep_m" and ok(r)), key=lambda r: r["m"])
    sn = sorted((r for r in recs if r["section"] == "sweep_n" and ok(r)), key=lambda r: r["n"])
    ax = axes[0]
    if sm:
        ms = np.array([r["m"] for r in sm], float)
        tot = np.array([r["per_iteration_s"] for r in sm]) * 1000
        ax.loglog(ms, tot, "o-", lw=2, color="k", label="time per iteration")
        for s in ("knn", "two_way", "nbody", "regularize", "update"):
            ys = np.array([r["stage_seconds"][s] / r["iterations"] for r in sm]) * 1000
            if np.all(ys > 0):
                ax.loglog(ms, ys, ".--", lw=1, label=STAGE_NAMES[s])
        ax.loglog(ms, tot[-1] * ms / ms[-1], ":", color="grey", label="∝ M (linear)")
        e = a["sweep_m"]["exponent"]
        ax.set_title(
            f"time per iteration vs M (N = {sm[0]['n']:,}, K fixed)"
            + (f": ∝ M^{e:.2f}" if e is not None else ""),
            fontsize=10,
        )
        ax.set_xlabel("template vertices M")
        ax.set_ylabel("ms per iteration (preset default)")
        ax.legend(fontsize=7)
        ax = axes[1]
        mem = np.array([r["peak_rss_mb"] for r in sm])
        base = np.array([r["baseline_rss_mb"] for r in sm])
        ax.loglog(ms, mem, "o-", color="C3", label="peak RSS (process)")
        ax.loglog(ms, np.maximum(mem - base, 1), "s--", color="C1", label="peak − baseline")
        ax.axhline(2048, color="grey", ls=":", label="2 GB")
        ax.set_title("peak memory vs M", fontsize=10)
        ax.set_xlabel("template vertices M")
        ax.set_ylabel("MB")
        ax.legend(fontsize=7)
    ax = axes[2]
    if sn:
        ns = np.array([r["n"] for r in sn], float)
        tot = np.array([r["per_iteration_s"] for r in sn]) * 1000
        ax.loglog(ns, tot, "o-", lw=2, color="k", label="time per iteration")
        for s in ("knn", "two_way", "nbody"):
            ys = np.array([r["stage_seconds"][s] / r["iterations"] for r in sn]) * 1000
            if np.all(ys > 0):
                ax.loglog(ns, ys, ".--", lw=1, label=STAGE_NAMES[s])
        ax.loglog(ns, tot[0] * ns / ns[0], ":", color="grey", label="∝ N")
        e = a["sweep_n"]["exponent"]
        ax.set_title(
            f"time per iteration vs N (M = {sn[0]['m']:,}, K fixed)"
            + (f": ∝ N^{e:.2f}" if e is not None else ""),
            fontsize=10,
        )
        ax.set_xlabel("scan points N")
        ax.set_ylabel("ms per iteration")
        ax.legend(fontsize=7)
    from matplotlib.ticker import NullFormatter

    for ax in axes:
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.yaxis.set_minor_formatter(NullFormatter())
    if quick:
        fig.suptitle("QUICK RUN (small sizes): a smoke test, not the measurement", color="C3")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
