"""The comparison harness (bench/compare.py) on its CI case.

Runs ``python -m bench.compare --quick`` in a subprocess (a 17 × 17 sheet on 400 noisy points, every
method that imports; peers missing from this environment are recorded as skipped) and checks
the JSON it writes: a row for every method, every metric, the reference rows' defining values
(oracle f_R = 0, identity f_H = 1), and that a peer whose import fails is skipped with its
reason rather than crashing the run. The full comparison is a documented command
(bench/README.md), not part of CI.
"""

from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys

import pytest

REPO = pathlib.Path(__file__).resolve().parent.parent
METHODS = [
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
METRICS = [
    "f_H",
    "f_S",
    "f_E",
    "f_F",
    "f_R",
    "f_lambda",
    "f_lambda_terms",
    "chamfer",
    "scan_to_fit_mean",
    "scan_to_fit_p95",
    "chamfer_rel",
    "s2f_mean_rel",
    "s2f_p95_rel",
]

pytest.importorskip("trimesh")


def run_quick(out: pathlib.Path, *extra: str, env: dict | None = None) -> dict:
    cmd = [sys.executable, "-m", "bench.compare", "--quick", "--out", str(out), *extra]
    proc = subprocess.run(
        cmd,
        check=False,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, **(env or {})},
        cwd=REPO,
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    return json.loads((out / "results-quick.json").read_text())


@pytest.fixture(scope="module")
def quick_out(tmp_path_factory) -> pathlib.Path:
    out = tmp_path_factory.mktemp("bench")
    run_quick(out)
    return out


@pytest.fixture(scope="module")
def quick(quick_out) -> dict:
    return json.loads((quick_out / "results-quick.json").read_text())


def rows(result: dict) -> dict:
    (case,) = result["groups"]["quick"]
    return case["rows"]


def test_every_method_has_a_row(quick):
    r = rows(quick)
    for m in METHODS + ["identity", "oracle"]:
        assert m in r, m
        assert r[m]["status"] in ("ok", "skipped"), (m, r[m])
        if r[m]["status"] == "skipped":
            assert r[m]["reason"], m
    for m in (
        "foldmatch",
        "foldmatch_paper",
        "nrga",
        "nricp_amberg",
        "nricp_sumner",
    ):  # their dependencies are in requirements-dev.txt
        assert r[m]["status"] == "ok", (m, r[m])


def test_every_metric_wall_time_and_memory(quick):
    for m, row in rows(quick).items():
        if row["status"] != "ok":
            continue
        for k in METRICS:
            assert k in row, (m, k)
        assert row["f_R"] is not None, m  # the CI case has ground truth
        if m not in ("identity", "oracle"):
            assert row["wall_s"] > 0, m
            assert row["peak_rss_mb"] >= row["baseline_rss_mb"] > 0, m


def test_reference_rows(quick):
    r = rows(quick)
    assert r["oracle"]["f_R"] == 0.0
    assert r["oracle"]["f_S"] == r["oracle"]["f_E"] == r["oracle"]["f_F"] == 0.0
    assert r["identity"]["f_H"] == 1.0
    assert r["identity"]["f_R"] > 0


def test_fits_improve_on_identity(quick):
    r = rows(quick)
    assert r["foldmatch"]["s2f_mean_rel"] < r["identity"]["s2f_mean_rel"]


def test_report_written(quick_out):
    # in quick mode the Markdown report goes under --out; docs/ is never touched by CI
    text = (quick_out / "results.md").read_text()
    assert "| FoldMatch |" in text and "| oracle (truth) |" in text
    assert "BEGIN GENERATED: summary" in text


def test_missing_peer_is_skipped(tmp_path):
    res = run_quick(tmp_path, "--methods", "foldmatch,cpd_pycpd", env={"FOLDMATCH_BENCH_BLOCK": "pycpd"})
    r = rows(res)
    assert r["foldmatch"]["status"] == "ok"
    assert r["cpd_pycpd"]["status"] == "skipped"
    assert "pycpd" in r["cpd_pycpd"]["reason"]
    assert res["methods"]["cpd_pycpd"]["status"] == "skipped"
    assert (tmp_path / "results.md").read_text().count("skipped") >= 1
