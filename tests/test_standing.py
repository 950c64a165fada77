"""bench/standing.py's scoring and rendering (the "standing" block of docs/results.md), on
crafted rows whose verdicts are known by hand; the fits themselves are the documented command's,
not CI's."""

from __future__ import annotations

import math
import pathlib
import sys

REPO = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "bench"))

import standing  # noqa: E402
import variants  # noqa: E402


def row(case: str, group: str, variant: str, f_r: float, f_l: float, f_f: float = 0.0,
        s2f: float = 0.01) -> dict:
    return {"case": case, "group": group, "variant": variant, "seconds": 0.1, "f_R": f_r,
            "f_lambda": f_l, "f_H": 0.2, "f_E": 0.0, "f_F": f_f, "s2f_mean_rel": s2f}


BEST = {
    "sheet-a": {"f_R": 0.02, "f_lambda": 0.05, "s2f_mean_rel": 0.01, "truth_f_F": 0.0},
    "wind-250-mesh": {"f_R": 0.018, "f_lambda": 0.056, "s2f_mean_rel": 0.005, "truth_f_F": 0.02},
    "odd-case": {"f_R": 0.03, "f_lambda": 0.07, "s2f_mean_rel": 0.01, "truth_f_F": math.nan},
}


def test_verdict_counts_ties_as_won_and_skips_flips_without_truth():
    b = BEST["sheet-a"]
    v = variants.verdict(row("sheet-a", "sheets", "d", 0.02, 0.06, f_f=0.01, s2f=0.011), b)
    assert v == {"f_R": True, "f_lambda": False, "flips": True, "s2f": False}
    v = variants.verdict(row("sheet-a", "sheets", "d", 0.021, 0.05, f_f=0.0101), b)
    assert v == {"f_R": False, "f_lambda": True, "flips": False, "s2f": True}
    assert variants.verdict(row("odd-case", "real", "d", 0.01, 0.01), BEST["odd-case"])["flips"] is None


def test_reason_by_name_then_by_what_was_lost():
    won_f_r = {"f_R": True, "f_lambda": False}
    lost_f_r = {"f_R": False, "f_lambda": False}
    assert "articulated motion still under way" in standing.reason("wind-250-mesh", lost_f_r)
    assert standing.reason("sheet-paper-holes", lost_f_r).startswith("holes")
    assert standing.reason("sheet-sample-21", won_f_r) == standing.F_LAMBDA_ONLY
    assert standing.reason("sheet-sample-21", lost_f_r) == "not investigated"
    # A reason about f_R (articulated motion) does not explain a loss of f_λ alone; one about
    # f_H (a curled frame's stranded flap) does.
    assert standing.reason("wind-iter0-120-pts", won_f_r) == standing.F_LAMBDA_ONLY
    assert "articulated motion" in standing.reason("wind-iter0-120-pts", lost_f_r)
    assert standing.reason("wind-iter0-190-pts", won_f_r).startswith("curled frames")


def test_render_scores_both_configurations_and_lists_the_default_s_losses():
    rows = [
        row("sheet-a", "sheets", "default", 0.01, 0.04),            # wins both
        row("wind-250-mesh", "real", "default", 0.0303, 0.071),     # loses both (1.68×, 1.27×)
        row("odd-case", "real", "default", 0.02, 0.084),            # loses f_λ only (1.2×)
        row("sheet-a", "sheets", "paper preset", 0.05, 0.2),
        row("wind-250-mesh", "real", "paper preset", 0.05, 0.2),
        row("odd-case", "real", "paper preset", 0.05, 0.2),
        row("not-scored", "real", "default", 1.0, 1.0),             # no peer figures: left out
    ]
    md = standing.render(rows, BEST, "peers.json", "stamp")
    lines = md.splitlines()
    assert lines[0] == "stamp"
    crit = {tuple(c.strip() for c in ln.strip("|").split("|")[:2]): ln for ln in lines
            if ln.startswith("| default |") or ln.startswith("| paper preset |")}
    # real: 2 cases, sheets: 1; "all" is the last cell.
    assert crit[("default", "lowest f_R")].rstrip(" |").endswith("2 of 3")
    assert crit[("default", "lowest f_λ")].rstrip(" |").endswith("1 of 3")
    assert crit[("paper preset", "lowest f_R")].rstrip(" |").endswith("0 of 3")
    # flips: odd-case has no truth f_F, so 2 cases count.
    assert crit[("default", "flips ≤ truth + 1 pt")].rstrip(" |").endswith("2 of 2")
    geo = crit[("default", "f_R ÷ best peer (geo. mean)")].rstrip(" |").split("|")[-1].strip()
    expected = (0.01 / 0.02 * 0.0303 / 0.018 * 0.02 / 0.03) ** (1 / 3)
    assert float(geo) == round(expected, 3)
    assert "loses on f_R or f_λ: 2 of 3" in md
    lost = [ln for ln in lines if ln.startswith("| wind-250-mesh |") or ln.startswith("| odd-case |")]
    # The lost table comes first, largest loss first; the folded table repeats every case.
    assert lost[0].startswith("| wind-250-mesh |") and "1.68×" in lost[0]
    assert lost[1].startswith("| odd-case |") and standing.F_LAMBDA_ONLY in lost[1]
    assert "not-scored" not in md
    assert md.count("| sheet-a |") == 1  # won: only in the folded table
