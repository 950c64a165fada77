"""The generated blocks of docs/performance.md, from a run of ``bench.perf``."""

from __future__ import annotations

import pathlib
from typing import Any

from bench import report
from bench.perf_analysis import fastest_peer, find, ok, thread_caveat
from bench.perf_plan import FAST_PRICE, LEVERS, STAGE_NAMES, STAGES, run_name
from bench.perf_tables import section_table, stage_table, table

DOC = pathlib.Path(__file__).resolve().parent.parent / "docs" / "performance.md"

DOC_TEMPLATE = """# Performance

Where FoldMatch's time goes, how it scales, and how it compares in speed with the methods a
user would pick instead, on one machine in one run. Every figure below comes from one run of

```sh
.venv/bin/python -m bench.perf            # full run (about 11 minutes on 2 idle cores)
.venv/bin/python -m bench.perf --quick    # small sizes only, < 2 minutes: a smoke test
```

which rewrites the blocks between the `BEGIN GENERATED` / `END GENERATED` markers (and
`docs/figures/perf_scaling.png`); the text around them is written by hand. The header says
which commit and machine the figures are of: wall times depend on the machine and its load,
so compare runs of one machine only. The per-stage micro-benchmarks are
`cargo bench --bench stages` (criterion, on the paper-sized case;
[benches/stages.rs](../benches/stages.rs)).

<!-- BEGIN GENERATED: header -->
<!-- END GENERATED: header -->

## Targets

Each target, what was wanted and what this run measured. "Paper-sized" is the paper's case:
a 115 × 115 sheet (13,225 template vertices) fitted to 14,400 scan points, 100 iterations.
"vs the fastest peer" divides the fastest peer's wall time by FoldMatch's on the same case,
and holds only where FoldMatch's f_λ is no worse; the note gives both methods' f_λ and f_R
and the ground truth's own f_λ.

<!-- BEGIN GENERATED: targets -->
<!-- END GENERATED: targets -->

## (a) The paper-sized case, and the peers on the same cases

For each method on each case: wall time, time per iteration, peak memory of the whole process,
threads, and the fit's quality by `fm.evaluate` against the ground truth. FoldMatch's rows
break the time down by stage (`diagnostics["stage_seconds"]`, scaled to the wall time).

<!-- BEGIN GENERATED: peers -->
<!-- END GENERATED: peers -->

## (b) ≈100K template vertices on a ≈1M-point scan

The peers cannot finish this case on the machine: they are capped (one iteration, an
address-space limit, a timeout), and their time per iteration is compared with FoldMatch's.

<!-- BEGIN GENERATED: large -->
<!-- END GENERATED: large -->

## (c) Scaling in M and N

Time per iteration and peak memory as the template grows (M, fixed scan) and as the scan grows
(N, fixed template), with the exponent of a power law fitted on the larger half of each sweep.

![time per iteration and peak memory vs M, time vs N](figures/perf_scaling.png)

<!-- BEGIN GENERATED: scaling -->
<!-- END GENERATED: scaling -->

## (d) 1 vs 2 threads

The same fits with 1 and 2 threads: the speed-up overall and per stage.

<!-- BEGIN GENERATED: threads -->
<!-- END GENERATED: threads -->

## Where a target is missed

For each missed target: where the time goes, and what would make each stage cheaper.

<!-- BEGIN GENERATED: missed -->
<!-- END GENERATED: missed -->

## How it is measured

* Each measurement is a fresh Python process (`python -m bench.perf --worker`): the case is
  generated (`fm.folded_sheet`, deterministic), then the method is timed
  (`time.perf_counter` around the call alone). Peak memory is the process's `VmHWM` right
  after the call (the whole process: interpreter, NumPy, data, Rust allocations); "baseline"
  is the same before the call.
* FoldMatch's runs, and the peers' on the paper-sized and small cases, are repeated (up to 3
  times within 20 s) and the best wall time is kept. The default's two candidate schedules
  run side by side, so their summed stage times exceed the wall time; "setup + final" is the
  rest of the wall time (the scan tree, curvature, rings, the accumulated wrinkle field, the
  schedule selection).
* Threads: asked (`fm.fit(threads=...)`; "all" = every core), the most OS threads seen during
  the call, and CPU time ÷ wall time ("busy": the cores actually kept busy).
* Peers use `bench/peers.py`'s adapters and tuned parameters; quality is `fm.evaluate` on the
  same ground truth. Dense CPD (pycpd, probreg) is skipped where its M×N arrays exceed 3 GiB.
* The NumPy reference (`tests/reference.py`, loops over vertices with `numpy.linalg`) runs a
  couple of iterations of the paper preset; its 100-iteration time is extrapolated.
* On a shared machine the 1-minute load average before every measurement is in the JSON
  (`loadavg_before`); a load above the core count inflates wall times and deflates the
  thread speed-up. A speed change between two builds is best judged by instruction counts
  (`RAYON_NUM_THREADS=1 valgrind --tool=callgrind target/profiling/examples/timing`) or by
  timing the two builds in alternation (`python3 -m bench.ab_timing OLD NEW --pairs 15`).
"""


def md_header(meta: dict[str, Any]) -> str:
    mc, v = meta["machine"], meta["versions"]
    lines = []
    if meta["quick"]:
        lines += [
            (
                "> **QUICK RUN** (`python -m bench.perf --quick`): small stand-in sizes, capped peers, "
                "one repetition. It checks that the pipeline works; **none of its figures is a "
                "measurement of the targets.** The full run is the command above."
            ),
            "",
        ]
    lines += [
        (
            f"* Run: {meta['date']}, `{meta['command']}`, {meta['duration_s'] / 60:.1f} min; "
            f"commit {meta['git']['commit']}"
            f"{' (+ uncommitted changes)' if meta['git']['dirty'] else ''}"
            f", extension built {v.get('extension_built', '?')}."
        ),
        (
            f"* Machine: {mc.get('Model name', '?')}, {mc.get('nproc')} cores "
            f"({mc.get('Thread(s) per core', '?')} thread per core"
            f"{', ' + mc['Hypervisor vendor'] + ' VM' if mc.get('Hypervisor vendor') else ''}), "
            f"{mc.get('memory_gib', '?')} GiB RAM, L2 {mc.get('L2 cache', '?')}, L3 "
            f"{mc.get('L3 cache', '?')}; {mc['platform']}."
        ),
        (
            f"* Load average (1 min) at start / end: {meta['load_start']:.2f} / "
            f"{meta['load_end']:.2f}"
            f" on {mc.get('nproc')} cores (shared machine)."
        ),
        *(
            [
                (
                    f"* **Warning:** {len(v['extension_stale'].split(', '))} file(s) of src/ "
                    f"were modified after the extension was built ({v['extension_stale']}; "
                    "by modification time): if their content changed, these figures are of "
                    "the code before the change (rebuild with `make build`)."
                )
            ]
            if v.get("extension_stale")
            else []
        ),
        "* Versions: "
        + ", ".join(f"{k} {val}" for k, val in v.items() if not k.startswith("extension"))
        + f", Python {mc['python']}.",
    ]
    return "\n".join(lines)


def md_targets(a: dict[str, Any]) -> str:
    rows = []
    for t in a["targets"]:
        met = {True: "✅ met", False: "❌ missed", None: "n/a (quick)"}[t["met"]]
        rows.append([t["name"], t["target"], t["value"], met, t["note"]])
    return table(["target", "wanted", "measured", "", "notes"], rows)


def md_peers(recs: list[dict[str, Any]], a: dict[str, Any], p: dict[str, Any]) -> str:
    parts = []
    for cname in ("paper", "small"):
        rs = [r for r in recs if r["section"] == "peers" and r["case_name"] == cname]
        if not rs:
            continue
        parts.append(f"### {p['cases'][cname]['label']}\n")
        parts.append(section_table(rs))
        parts.append("\nPer-stage breakdown (seconds over the whole fit, share of wall time):\n")
        parts.append(stage_table(rs, lambda r: f"{r['preset']} ({r['iterations']} it.)"))
        ref = next((r for r in rs if r["kind"] == "reference" and ok(r)), None)
        if ref:
            st = ref["stage_seconds"]
            parts.append(
                f"\nNumPy reference per iteration: k-NN {st['knn']:.3f} s, force "
                f"{st['nbody']:.3f} s, Eq. 4–8 {st['model']:.3f} s; setup "
                f"{ref['setup_s']:.2f} s.\n"
            )
        rows = []
        for x in a["ratios"].get(cname, []):
            q = ""
            if "other_f_lambda" in x:
                q = f"{x['ours_f_lambda']:.3f} vs {x['other_f_lambda']:.3f}" + (
                    " (ours ≤)" if x["ours_f_lambda"] <= x["other_f_lambda"] + 1e-3 else " (ours worse)"
                )
            name = "NumPy reference" if x["other"] == "reference" else x["other"]
            note = (
                "extrapolated to 100 iterations"
                if x.get("extrapolated")
                else ("peer capped" if x["capped"] else "")
            )
            if x.get("per_iteration_ratio"):
                note += f"; per iteration {x['per_iteration_ratio']:.0f}×"
            rows.append([f"FoldMatch {x['preset']}", name, f"{x['ratio']:.1f}×", q, note])
        if rows:
            parts.append("\nRatios (other's wall time ÷ FoldMatch's; > 1: FoldMatch faster):\n")
            parts.append(table(["ours", "other", "speed ratio", "f_λ ours vs other", "notes"], rows))
        parts.append("")
    return "\n".join(parts)


def md_large(recs: list[dict[str, Any]], p: dict[str, Any]) -> str:
    rs = [r for r in recs if r["section"] == "large"]
    if not rs:
        return "_(not run)_"
    out = [f"{p['cases']['large']['label']}.\n", section_table(rs), ""]
    out.append(stage_table(rs, lambda r: f"{run_name(r)} ({r['iterations']} it.)"))
    peers_ = [r for r in rs if r["kind"] == "peer" and ok(r) and r.get("per_iteration_s")]
    ours = next((r for r in rs if r["kind"] == "foldmatch" and ok(r)), None)
    if ours and peers_:
        out.append(
            "\nTime per iteration, peers (capped) vs FoldMatch: "
            + "; ".join(
                f"{r['method']} {r['per_iteration_s']:.1f} s = "
                f"{r['per_iteration_s'] / ours['per_iteration_s']:.0f}× FoldMatch's "
                f"{ours['per_iteration_s'] * 1000:.0f} ms"
                for r in peers_
            )
            + "."
        )
    return "\n".join(out)


def md_scaling(recs: list[dict[str, Any]], a: dict[str, Any]) -> str:
    out = []
    for key, var in (("sweep_m", "M"), ("sweep_n", "N")):
        rs = sorted(
            (r for r in recs if r["section"] == key),
            key=lambda r: (r["case"]["nx"], r["case"]["scan_points"]),
        )
        if not rs:
            continue
        rows = []
        for r in rs:
            if not ok(r):
                rows.append(
                    [
                        f"{r['case']['nx']}² / {r['case']['scan_points']:,}",
                        "—",
                        "—",
                        "—",
                        "—",
                        "—",
                        f"{r.get('status')}: {r.get('error', '')}",
                    ]
                )
                continue
            st = r["stage_seconds"]
            top = max(STAGES, key=lambda s: st.get(s, 0))
            rows.append(
                [
                    f"{r['m']:,}",
                    f"{r['n']:,}",
                    f"{r['target_neighbours']}",
                    f"{r['per_iteration_s'] * 1000:.1f}",
                    f"{r['per_iteration_s'] * 1e9 / r['m']:.0f}",
                    f"{r['peak_rss_mb']:.0f} ({r['peak_rss_mb'] - r['baseline_rss_mb']:.0f})",
                    f"{STAGE_NAMES[top]} {100 * st[top] / sum(st[s] for s in STAGES):.0f} %",
                ]
            )
        e = a[key]["exponent"]
        out.append(
            f"Sweep in {var} ({rs[0]['params']['iterations']} iterations each, preset "
            f"default, all threads; exponent of time per iteration fitted on the larger "
            f"half: {'—' if e is None else f'{var}^{e:.2f}'}):\n"
        )
        out.append(
            table(
                [
                    "M",
                    "N",
                    "K",
                    "ms / iteration",
                    "ns / iteration / vertex",
                    "peak RSS MB (− baseline)",
                    "largest stage",
                ],
                rows,
            )
        )
        out.append("")
    return "\n".join(out)


def md_threads(recs: list[dict[str, Any]], a: dict[str, Any]) -> str:
    rs = [r for r in recs if r["section"] == "threads"]
    if not rs:
        return "_(not run)_"
    out = [section_table(rs), ""]
    out.append(stage_table(rs, lambda r: f"{r['preset']}, {r['threads']} thr."))
    for preset, t in a["threads"].items():
        per = ", ".join(f"{STAGE_NAMES[s]} {v:.2f}×" for s, v in t["stages"].items() if v)
        out.append(f"\nSpeedup 1 → 2 threads, preset {preset}: **{t['speedup']:.2f}×** ({per}).")
        if thread_caveat(t):
            out.append(f"⚠ {thread_caveat(t).capitalize()}.")
    return "\n".join(out)


def md_missed(recs: list[dict[str, Any]], a: dict[str, Any], quick: bool) -> str:
    missed = [t for t in a["targets"] if t["met"] is False]
    out = []
    if quick:
        out.append(
            "_Quick run: no target is judged. The profile below is of the quick "
            "stand-in for the paper-sized case._\n"
        )
    elif not missed:
        return "Every target is met."
    else:
        out.append(
            "Missed: "
            + "; ".join(f"{t['name']} ({t['value']}, wanted {t['target']})" for t in missed)
            + ".\n"
        )
    for preset in ("default", "paper"):
        r = find(recs, section="peers", case_name="paper", kind="foldmatch", preset=preset)
        if not ok(r):
            continue
        st = r["stage_seconds"]
        order = sorted(STAGES + ["setup"], key=lambda s: -st.get(s, 0))
        need = r["wall_s"] / 1.0
        to_go = f"reaching 1 s needs {need:.2f}× overall" if need > 1 else "within 1 s"
        out.append(
            f"**Paper-sized, preset {preset}: {r['wall_s']:.2f} s** "
            f"({r['per_iteration_s'] * 1000:.1f} ms per iteration); {to_go}. Largest stages: "
            + ", ".join(
                f"{STAGE_NAMES[s]} {st[s]:.2f} s ({100 * st[s] / r['wall_s']:.0f} %)" for s in order[:4]
            )
            + "."
        )
        out.append("")
    th = a["threads"].get("default")
    if th:
        worst = sorted(((s, v) for s, v in th["stages"].items() if v), key=lambda x: x[1])[:3]
        out.append(
            f"**Threads:** {th['speedup']:.2f}× from 1 to 2 threads; the stages that "
            "scale worst: "
            + ", ".join(f"{STAGE_NAMES[s]} {v:.2f}×" for s, v in worst)
            + " (a stage near 1× is serial or memory-bound; a loaded machine also lowers "
            "every figure)." + (f" ⚠ {thread_caveat(th).capitalize()}." if thread_caveat(th) else "") + "\n"
        )
    large = find(recs, section="large", kind="foldmatch")
    if ok(large):
        st = large["stage_seconds"]
        order = sorted(STAGES + ["setup"], key=lambda s: -st.get(s, 0))
        out.append(
            f"**Large case: {large['wall_s']:.1f} s, {large['peak_rss_mb']:.0f} MB.** "
            "Largest stages: "
            + ", ".join(
                f"{STAGE_NAMES[s]} {st[s]:.1f} s ({100 * st[s] / large['wall_s']:.0f} %)" for s in order[:4]
            )
            + ".\n"
        )
    # Levers for the stages that dominate any of the profiles above.
    heavy: list[str] = []
    for r in [
        find(recs, section="peers", case_name="paper", kind="foldmatch", preset=pr)
        for pr in ("default", "paper")
    ] + [large]:
        if ok(r):
            st = r["stage_seconds"]
            for s in sorted(STAGES + ["setup"], key=lambda s: -st.get(s, 0))[:3]:
                if s not in heavy:
                    heavy.append(s)
    fast = md_fast_closing(recs, a)
    if fast:
        out += [fast, ""]
    if heavy:
        out.append("What would close it, stage by stage (largest first):\n")
        out += [f"* {LEVERS[s]}." for s in heavy]
    return "\n".join(out)


#: How md_fast_closing names the cases.
CASE_NAMES = {"paper": "paper-sized case", "small": "small peer case"}


def md_fast_closing(recs: list[dict[str, Any]], a: dict[str, Any]) -> str:
    """What the fast preset (one schedule) measures against the time targets in this run, and
    its price in accuracy: the option that closes them without new code."""
    parts = []
    for cname in ("paper", "small"):
        fast = find(recs, section="peers", case_name=cname, kind="foldmatch", preset="fast")
        default = find(recs, section="peers", case_name=cname, kind="foldmatch", preset="default")
        if not (ok(fast) and ok(default)):
            continue
        x, full = fastest_peer(a, cname, "fast")
        text = (
            f"{CASE_NAMES[cname]} {fast['wall_s']:.2f} s ({fast['wall_s'] / default['wall_s']:.2f}× "
            f"the default's {default['wall_s']:.2f} s), f_R {fast['quality']['f_R']:.4f} / f_λ "
            f"{fast['quality']['f_lambda']:.3f} (default {default['quality']['f_R']:.4f} / "
            f"{default['quality']['f_lambda']:.3f})"
        )
        if full:
            text += (
                f", {x['ratio']:.1f}× faster than {x['other']} (f_λ {x['ours_f_lambda']:.3f} vs "
                f"{x['other_f_lambda']:.3f})"
            )
        parts.append(text)
    if not parts:
        return ""
    return (
        '**The fast preset** (`preset="fast"`: one schedule instead of the default\'s two, '
        "no second run to compare), the trade of accuracy for time a user can make today, "
        "measured in this run: " + "; ".join(parts) + "; " + FAST_PRICE + "."
    )


def write_docs(
    recs: list[dict[str, Any]], a: dict[str, Any], meta: dict[str, Any], p: dict[str, Any]
) -> None:
    text = DOC.read_text() if DOC.exists() else DOC_TEMPLATE
    blocks = {
        "header": md_header(meta),
        "targets": md_targets(a),
        "peers": md_peers(recs, a, p),
        "large": md_large(recs, p),
        "scaling": md_scaling(recs, a),
        "threads": md_threads(recs, a),
        "missed": md_missed(recs, a, p["quick"]),
    }
    for name, body in blocks.items():
        text = report.replace_block(text, name, body)
    DOC.parent.mkdir(parents=True, exist_ok=True)
    DOC.write_text(text)
