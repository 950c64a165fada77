"""Judging a run of ``bench.perf``: ratios against the peers and the reference, the scaling
exponents, and each target met or missed."""

from __future__ import annotations

from typing import Any

import numpy as np

from bench.perf_plan import PEER_PRESETS, STAGES


def ok(r: dict[str, Any] | None) -> bool:
    return bool(r) and r.get("status") == "ok"


def find(recs: list[dict[str, Any]], **kw: Any) -> dict[str, Any] | None:
    for r in recs:
        if all(r.get(k) == v for k, v in kw.items()):
            return r
    return None


def power_fit(xs: list[float], ys: list[float]) -> float | None:
    """Slope of log y against log x (least squares)."""
    if len(xs) < 2:
        return None
    return float(np.polyfit(np.log(xs), np.log(ys), 1)[0])


def analyse(recs: list[dict[str, Any]], p: dict[str, Any]) -> dict[str, Any]:
    a: dict[str, Any] = {}
    # Ratios against the peers and the reference, per case.
    ratios: dict[str, list[dict[str, Any]]] = {}
    for cname in ("paper", "small"):
        rows = []
        for preset in PEER_PRESETS:
            ours = find(recs, section="peers", case_name=cname, kind="foldmatch", preset=preset)
            if not ok(ours):
                continue
            for r in recs:
                if r.get("section") != "peers" or r.get("case_name") != cname:
                    continue
                if r["kind"] == "peer" and ok(r):
                    capped = bool(r.get("overrides"))
                    rows.append(
                        {
                            "preset": preset,
                            "other": r["method"],
                            "other_wall": r["wall_s"],
                            "ratio": r["wall_s"] / ours["wall_s"],
                            "capped": capped,
                            "ours_f_lambda": ours["quality"]["f_lambda"],
                            "other_f_lambda": r["quality"]["f_lambda"],
                            "ours_f_R": ours["quality"]["f_R"],
                            "other_f_R": r["quality"]["f_R"],
                        }
                    )
                elif r["kind"] == "reference" and ok(r):
                    rows.append(
                        {
                            "preset": preset,
                            "other": "reference",
                            "other_wall": r["extrapolated_100_s"],
                            "ratio": r["extrapolated_100_s"] / ours["wall_s"],
                            "capped": True,
                            "extrapolated": True,
                            "per_iteration_ratio": r["per_iteration_s"] / ours["per_iteration_s"],
                        }
                    )
        ratios[cname] = rows
    a["ratios"] = ratios
    # Threads.
    th = {}
    for preset in ("default", "paper"):
        one = find(recs, section="threads", preset=preset, threads=1)
        two = find(recs, section="threads", preset=preset, threads=2)
        if ok(one) and ok(two):
            th[preset] = {
                "speedup": one["wall_s"] / two["wall_s"],
                "busy_2": two.get("cpu_per_wall"),
                "load_before_2": two.get("loadavg_before"),
                "stages": {
                    s: (
                        one["stage_seconds"][s] / two["stage_seconds"][s]
                        if two["stage_seconds"].get(s, 0) > 1e-4
                        else None
                    )
                    for s in STAGES + ["setup"]
                },
            }
    a["threads"] = th
    # Scaling exponents (time per iteration), on the larger half of the sweep.
    for key, xkey in (("sweep_m", "m"), ("sweep_n", "n")):
        pts = sorted(
            (r[xkey], r["per_iteration_s"], max(r["peak_rss_mb"] - r["baseline_rss_mb"], 1.0))
            for r in recs
            if r.get("section") == key and ok(r)
        )
        big = pts[len(pts) // 2 - (1 if len(pts) >= 4 else 0) :] if len(pts) >= 3 else pts
        a[key] = {
            "points": pts,
            "exponent": power_fit([q[0] for q in big], [q[1] for q in big]),
            "memory_exponent": power_fit([q[0] for q in big], [q[2] for q in big]),
            "fitted_on": [q[0] for q in big],
        }
    a["targets"] = targets(recs, a, p)
    return a


def fastest_peer(a: dict[str, Any], cname: str, preset: str) -> tuple[dict[str, Any] | None, bool]:
    """The ratio row (:func:`analyse`) of the fastest peer of FoldMatch `preset` on case `cname`,
    among the peers run in full if any, else among the capped ones; and whether it ran in full.
    (None, False) when no peer ran."""
    rows = [x for x in a["ratios"].get(cname, []) if x["other"] != "reference" and x["preset"] == preset]
    full = [x for x in rows if not x["capped"]]
    pool = full or rows
    return (min(pool, key=lambda x: x["other_wall"]) if pool else None), bool(full)


def targets(recs: list[dict[str, Any]], a: dict[str, Any], p: dict[str, Any]) -> list[dict]:
    quick = p["quick"]
    out = []

    def add(name, target, value, met, note=""):
        out.append({"name": name, "target": target, "value": value, "met": met, "note": note})

    for preset in PEER_PRESETS:
        r = find(recs, section="peers", case_name="paper", kind="foldmatch", preset=preset)
        if ok(r):
            add(
                f"paper-sized fit, {r['iterations']} iterations, preset {preset}",
                "≤ 1 s wall",
                f"{r['wall_s']:.2f} s",
                r["wall_s"] <= 1.0 and r["iterations"] >= 100,
            )
    ref = [x for x in a["ratios"].get("paper", []) if x["other"] == "reference" and x["preset"] == "paper"]
    if ref:
        add(
            "paper preset vs the NumPy reference (100 iterations, extrapolated)",
            "≥ 180×",
            f"{ref[0]['ratio']:.0f}×",
            ref[0]["ratio"] >= 180,
            "the reference here is loop-based, slower than a vectorized one",
        )
    r = find(recs, section="large", kind="foldmatch")
    if ok(r):
        add(
            f"large case ({r['m']:,} vertices, {r['n']:,} points), {r['iterations']} iterations",
            "≤ 30 s wall",
            f"{r['wall_s']:.1f} s",
            r["wall_s"] <= 30 and r["iterations"] >= 100,
        )
        add(
            "large case peak memory (whole process)",
            "≤ 2 GB",
            f"{r['peak_rss_mb']:.0f} MB",
            r["peak_rss_mb"] <= 2048,
        )
    elif r:
        add("large case", "≤ 30 s, ≤ 2 GB", r.get("status", "?"), False, r.get("error", ""))
    e = a["sweep_m"]["exponent"]
    if e is not None:
        add(
            "time per iteration vs M (fixed N, K)",
            "near-linear (exponent ≤ 1.15)",
            f"M^{e:.2f}",
            e <= 1.15,
            f"fitted on M = {', '.join(map(str, a['sweep_m']['fitted_on']))}",
        )
    me = a["sweep_m"]["memory_exponent"]
    if me is not None:
        add(
            "peak memory (− baseline) vs M, fixed N",
            "no O(M·N) (exponent ≤ 1.15)",
            f"M^{me:.2f}",
            me <= 1.15,
        )
    e = a["sweep_n"]["exponent"]
    if e is not None:
        add(
            "time per iteration vs N (fixed M, K)",
            "≈ N log N or better (exponent ≤ 1.2)",
            f"N^{e:.2f}",
            e <= 1.2,
        )
    for preset, t in a["threads"].items():
        add(
            f"1 → 2 threads, paper-sized, preset {preset}",
            "≥ 1.8×",
            f"{t['speedup']:.2f}×",
            t["speedup"] >= 1.8,
            thread_caveat(t),
        )
    for cname, preset in [(c, pr) for pr in ("default", "fast") for c in ("paper", "small")]:
        fastest, full = fastest_peer(a, cname, preset)
        if fastest is None:
            continue
        better = fastest["ours_f_lambda"] <= fastest["other_f_lambda"] + 1e-3
        note = (
            f"fastest peer {fastest['other']}: {fastest['other_wall']:.2f} s, f_λ "
            f"{fastest['other_f_lambda']:.3f} vs ours {fastest['ours_f_lambda']:.3f}; f_R "
            f"{fastest['other_f_R']:.4f} vs ours {fastest['ours_f_R']:.4f}"
        )
        oracle = oracle_of([r for r in recs if r.get("case_name") == cname and r["section"] == "peers"])
        if oracle:
            note += f"; the exact answer's own f_λ {oracle['f_lambda']:.4f}"
            if fastest["other_f_lambda"] < oracle["f_lambda"]:
                note += f" (the peer's, {fastest['other_f_lambda']:.4f}, is lower than the truth's)"
        if not full:
            note += " (peers capped: not a valid comparison)"
        add(
            f"vs the fastest peer, {cname} case, preset {preset}",
            "≥ 10× at equal or better f_λ",
            f"{fastest['ratio']:.1f}×",
            fastest["ratio"] >= 10 and better and full,
            note,
        )
    if quick:
        for t in out:
            t["note"] = ("quick run: small sizes, not the target's case. " + t["note"]).strip()
            t["met"] = None
    return out


def oracle_of(recs: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The ground truth's own metrics on these records' case (from a FoldMatch record)."""
    return next((r["oracle"] for r in recs if ok(r) and r.get("oracle")), None)


def thread_caveat(t: dict[str, Any]) -> str:
    """Why a low 1 → 2 thread figure may say more about the machine than the code."""
    busy = t.get("busy_2")
    if busy is None or busy >= 1.5:
        return ""
    return (
        f"the 2-thread run kept only {busy:.2f} cores busy (1-min load {t.get('load_before_2')} "
        "before it): either another process held a core, or the code ran serially"
    )
