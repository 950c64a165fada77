"""Markdown tables for docs/notes/comparison-full-run.md, and the generated-block mechanism: the harness
rewrites only the text between ``<!-- BEGIN GENERATED: name -->`` and
``<!-- END GENERATED: name -->``, so the hand-written analysis around the blocks survives a
regeneration."""

from __future__ import annotations

import math
import pathlib
import re
from collections.abc import Iterable
from typing import Any

import numpy as np

from bench import peers

NAMES = {
    "f_R": "f_R",
    "s2f_mean_rel": "scan→fit mean",
    "s2f_p95_rel": "scan→fit p95",
    "chamfer_rel": "Chamfer",
    "f_H": "f_H",
    "f_S": "f_S",
    "f_E": "f_E",
    "f_F": "f_F",
    "f_lambda": "f_λ",
    "wall_s": "time (s)",
    "peak_rss_mb": "peak RSS (MB)",
}
REF = ("identity", "oracle")


def label(method: str) -> str:
    if method == "identity":
        return "identity"
    if method == "oracle":
        return "oracle (truth)"
    return peers.METHODS[method]["label"]


def fmt(v: Any, key: str = "") -> str:
    if v is None:
        return "—"
    if isinstance(v, float) and (math.isnan(v) or math.isinf(v)):
        return "inf" if isinstance(v, float) and math.isinf(v) else "—"
    if key == "wall_s":
        return f"{v:.2f}" if v < 100 else f"{v:.0f}"
    if key == "peak_rss_mb":
        return f"{v:.0f}"
    if key in ("f_S", "f_E", "f_F"):
        return f"{v:.3f}"
    return f"{v:.4f}"


def table(header: list[str], rows: list[list[str]], align: list[str] | None = None) -> str:
    align = align or (["l"] + ["r"] * (len(header) - 1))
    sep = ["---:" if a == "r" else ":---" for a in align]
    lines = ["| " + " | ".join(header) + " |", "| " + " | ".join(sep) + " |"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def replace_block(text: str, name: str, body: str) -> str:
    begin, end = f"<!-- BEGIN GENERATED: {name} -->", f"<!-- END GENERATED: {name} -->"
    block = f"{begin}\n{body.rstrip()}\n{end}"
    pat = re.compile(re.escape(begin) + r".*?" + re.escape(end), re.DOTALL)
    if pat.search(text):
        return pat.sub(lambda _: block, text)
    return text.rstrip() + "\n\n" + block + "\n"


def write_blocks(path: pathlib.Path, blocks: dict[str, str], skeleton: str) -> None:
    text = path.read_text() if path.exists() else skeleton
    for name, body in blocks.items():
        text = replace_block(text, name, body)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


# ---- tables --------------------------------------------------------------------------------


def case_table(rec: dict[str, Any], methods: list[str]) -> str:
    """Every metric for every method of one case, reference rows first."""
    keys = [
        "f_R",
        "s2f_mean_rel",
        "s2f_p95_rel",
        "chamfer_rel",
        "f_H",
        "f_S",
        "f_E",
        "f_F",
        "f_lambda",
        "wall_s",
        "peak_rss_mb",
    ]
    fm_row = rec["rows"].get("foldmatch", {})
    header = ["method"] + [NAMES[k] for k in keys] + ["f_R ÷ FM", "time ÷ FM"]
    rows = []
    for m in list(REF) + methods:
        r = rec["rows"].get(m)
        if r is None:
            continue
        if r.get("status") != "ok":
            why = r.get("reason") or r.get("error") or ""
            rows.append([label(m), f"*{r.get('status')}*: {why[:110]}"] + [""] * (len(keys) + 1))
            continue
        cells = [label(m)] + [fmt(r.get(k), k) for k in keys]
        cells.append(ratio(r.get("f_R"), fm_row.get("f_R")) if m not in REF else "")
        cells.append(ratio(r.get("wall_s"), fm_row.get("wall_s")) if m not in REF else "")
        rows.append(cells)
    return table(header, rows)


def ratio(a: float | None, b: float | None) -> str:
    if a is None or b is None or b == 0:
        return "—"
    return f"{a / b:.2f}×"


def _vals(records: list[dict], method: str, key: str) -> list[float]:
    out = []
    for rec in records:
        r = rec["rows"].get(method)
        if r and r.get("status") == "ok" and r.get(key) is not None:
            v = float(r[key])
            if math.isfinite(v):
                out.append(v)
    return out


def summary_table(records: list[dict], methods: list[str]) -> str:
    """Medians over the cases of a group (peak RSS: the maximum)."""
    keys = [
        "f_R",
        "s2f_mean_rel",
        "s2f_p95_rel",
        "f_H",
        "f_S",
        "f_E",
        "f_F",
        "f_lambda",
        "wall_s",
        "peak_rss_mb",
    ]
    header = ["method", "cases"] + [NAMES[k] for k in keys] + ["f_R ÷ FM", "time ÷ FM"]
    rows = []
    for m in list(REF) + methods:
        n = len(_vals(records, m, "f_lambda"))
        if n == 0:
            why = _skip_reason(records, m)
            rows.append([label(m), "0", f"*not run*: {why[:120]}"] + [""] * (len(keys) + 1))
            continue
        cells = [label(m), str(n)]
        for k in keys:
            v = _vals(records, m, k)
            agg = (max(v) if k == "peak_rss_mb" else float(np.median(v))) if v else None
            cells.append(fmt(agg, k))
        cells.append(_median_ratio(records, m, "f_R") if m not in REF else "")
        cells.append(_median_ratio(records, m, "wall_s") if m not in REF else "")
        rows.append(cells)
    return table(header, rows)


def _skip_reason(records: list[dict], m: str) -> str:
    for rec in records:
        r = rec["rows"].get(m)
        if r:
            return f"{r.get('status')}: {r.get('reason') or r.get('error') or ''}"
    return "not requested"


def _median_ratio(records: list[dict], m: str, key: str) -> str:
    rs = []
    for rec in records:
        a, b = rec["rows"].get(m, {}), rec["rows"].get("foldmatch", {})
        if a.get("status") == b.get("status") == "ok" and a.get(key) and b.get(key):
            rs.append(a[key] / b[key])
    return f"{np.median(rs):.2f}×" if rs else "—"


def wins_table(records: list[dict], methods: list[str]) -> str:
    """In how many cases FoldMatch is better (lower) than each method, per metric."""
    keys = ["f_R", "s2f_mean_rel", "s2f_p95_rel", "f_F", "f_lambda", "wall_s"]
    header = ["FoldMatch better than…"] + [NAMES[k] for k in keys]
    rows = []
    for m in methods:
        if m == "foldmatch":
            continue
        cells = [label(m)]
        for k in keys:
            win = tot = 0
            for rec in records:
                a, b = rec["rows"].get("foldmatch", {}), rec["rows"].get(m, {})
                if (
                    a.get("status") == b.get("status") == "ok"
                    and a.get(k) is not None
                    and b.get(k) is not None
                ):
                    tot += 1
                    win += a[k] < b[k]
            cells.append(f"{win}/{tot}" if tot else "—")
        rows.append(cells)
    return table(header, rows)


def quantile_table(records: list[dict], methods: list[str], keys: Iterable[str]) -> str:
    """Third quartile and maximum of every metric over a sample set, and their ratio to
    FoldMatch's (the paper's Fig. 6 statistic)."""
    keys = list(keys)
    header = ["method"] + [f"{NAMES[k]} Q3" for k in keys] + ["f_λ Q3 ÷ FM", "f_R Q3 ÷ FM", "f_λ max ÷ FM"]
    q3 = {}
    mx = {}
    for m in list(REF) + methods:
        for k in keys:
            v = _vals(records, m, k)
            q3[m, k] = float(np.percentile(v, 75)) if v else None
            mx[m, k] = float(np.max(v)) if v else None
    rows = []
    for m in list(REF) + methods:
        if q3[m, "f_lambda"] is None:
            continue
        cells = [label(m)] + [fmt(q3[m, k], k) for k in keys]
        cells.append(ratio(q3[m, "f_lambda"], q3.get(("foldmatch", "f_lambda"))))
        cells.append(ratio(q3[m, "f_R"], q3.get(("foldmatch", "f_R"))) if "f_R" in keys else "")
        cells.append(ratio(mx[m, "f_lambda"], mx.get(("foldmatch", "f_lambda"))))
        rows.append(cells)
    return table(header, rows)
