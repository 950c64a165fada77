"""bench/standing.py's scoring and rendering (the "standing" block of docs/results.md), on
crafted rows whose verdicts are known by hand; the fits themselves are the documented command's,
not CI's."""

from __future__ import annotations

import math
import pathlib

from bench import standing, variants

REPO = pathlib.Path(__file__).resolve().parent.parent


def row(
    case: str, group: str, variant: str, f_r: float, f_l: float, f_f: float = 0.0, s2f: float = 0.01
) -> dict:
    return {
        "case": case,
        "group": group,
        "variant": variant,
        "seconds": 0.1,
        "f_R": f_r,
        "f_lambda": f_l,
        "f_H": 0.2,
        "f_E": 0.0,
        "f_F": f_f,
        "s2f_mean_rel": s2f,
    }


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
    assert "articulated motion still under way" in standing.accuracy_reason("wind-250-mesh", lost_f_r)
    assert standing.accuracy_reason("sheet-paper-holes", lost_f_r).startswith("holes")
    assert standing.accuracy_reason("sheet-sample-21", won_f_r) == standing.F_LAMBDA_ONLY
    assert standing.accuracy_reason("sheet-sample-21", lost_f_r) == "not investigated"
    # A reason about f_R (articulated motion) does not explain a loss of f_λ alone; one about
    # f_H (a curled frame's stranded flap) does.
    assert standing.accuracy_reason("wind-iter0-120-pts", won_f_r) == standing.F_LAMBDA_ONLY
    assert "articulated motion" in standing.accuracy_reason("wind-iter0-120-pts", lost_f_r)
    assert standing.accuracy_reason("wind-iter0-190-pts", won_f_r).startswith("curled frames")
    # Each criterion has its own reasons: the same name gives another text for flips, and a
    # reason about f_R alone explains no flips.
    assert "folded over" in standing.reason("sheet-sample-07", "flips")
    assert "schedule selection" in standing.reason("sheet-sample-07", "f_R")
    assert standing.reason("skirt-penetrate-mesh", "flips") is None


def test_closeness_reason_says_when_the_peer_is_closer_than_the_truth():
    # The exact answer farther from the scan than the best peer: the ratios, both to the truth.
    text = standing.closeness_reason("sheet-sample-08", 0.0084, 0.0072, 0.0080)
    assert text == standing.S2F_BELOW_TRUTH.format(peer="0.90", ours="1.05")
    # The truth closer (a mesh target: its own vertices, distance 0): the named reason.
    assert "tangential sliding" in standing.closeness_reason("tshirt-flattened-mesh", 0.0059, 0.0055, 0.0)
    assert standing.closeness_reason("sheet-sample-08", 0.0084, 0.0072, None) == "not investigated"


def test_render_scores_both_configurations_and_lists_the_default_s_losses():
    rows = [
        row("sheet-a", "sheets", "default", 0.01, 0.04),  # wins both
        row("wind-250-mesh", "real", "default", 0.0303, 0.071),  # loses both (1.68×, 1.27×)
        row("odd-case", "real", "default", 0.02, 0.084),  # loses f_λ only (1.2×)
        row("sheet-a", "sheets", "paper preset", 0.05, 0.2),
        row("wind-250-mesh", "real", "paper preset", 0.05, 0.2),
        row("odd-case", "real", "paper preset", 0.05, 0.2),
        row("not-scored", "real", "default", 1.0, 1.0),  # no peer figures: left out
    ]
    md = standing.render(rows, BEST, "peers.json", "stamp")
    lines = md.splitlines()
    assert lines[0] == "stamp"
    crit = {
        tuple(c.strip() for c in ln.strip("|").split("|")[:2]): ln
        for ln in lines
        if ln.startswith("| default |") or ln.startswith("| paper preset |")
    }
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


def test_render_scores_the_exact_answer_and_lists_flips_and_scan_distance_losses():
    rows = [
        row("sheet-a", "sheets", "default", 0.01, 0.04, s2f=0.012),  # scan→fit lost
        row("wind-250-mesh", "real", "default", 0.0303, 0.071, s2f=0.006),  # both tables
        row("sheet-a", "sheets", variants.EXACT, 0.0, 0.055, s2f=0.011),  # truth farther
        row("wind-250-mesh", "real", variants.EXACT, 0.0, 0.02, s2f=0.0),  # mesh target
    ]
    md = standing.render(rows, BEST, "peers.json", "stamp")
    lines = md.splitlines()
    exact = [ln for ln in lines if ln.startswith(f"| {variants.EXACT} |")]
    # Its criteria, no ratios (its f_R is 0); it is not a configuration whose losses are listed.
    assert len(exact) == 4 and not any("÷" in ln for ln in exact)
    assert exact[1].rstrip(" |").endswith("1 of 2")  # lowest f_λ: not sheet-a's 0.055
    assert "exact answer: f_λ" in md and "loses on f_R or f_λ: 1 of 2" in md
    assert "loses on flips or scan→fit: 2 of 2**" in md
    assert "on 1 of them the best peer's scan→fit distance is below the exact answer's own" in md
    second = md[md.index("loses on flips or scan→fit") : md.index("<details>")].splitlines()
    sheet = next(ln for ln in second if ln.startswith("| sheet-a |"))
    wind = next(ln for ln in second if ln.startswith("| wind-250-mesh |"))
    assert standing.S2F_BELOW_TRUTH.format(peer="0.91", ours="1.09") in sheet
    assert "scan→fit: large articulated motion" in wind
    # Largest scan→fit loss first (sheet-a 1.3× before wind-250-mesh 1.2×).
    rows[0] = row("sheet-a", "sheets", "default", 0.01, 0.04, s2f=0.013)
    md = standing.render(rows, BEST, "p", "s")
    order = [
        ln.split("|")[1].strip()
        for ln in md[md.index("loses on flips") :].splitlines()
        if ln.startswith("| sheet-a |") or ln.startswith("| wind-250-mesh |")
    ]
    assert order[:2] == ["sheet-a", "wind-250-mesh"]
