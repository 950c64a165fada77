"""Runs methods on cases (one subprocess per run), evaluates them with ``fm.evaluate`` and
keeps the results (resumable: a finished run is not repeated unless asked)."""

from __future__ import annotations

import hashlib
import json
import os
import pathlib
import platform
import subprocess
import sys
import time
from collections.abc import Iterable
from typing import Any

import numpy as np

from bench import cases as cases_mod
from bench import peers

HERE = pathlib.Path(__file__).resolve().parent
PY = sys.executable

#: Metrics shown first (ground truth and scan distance: never rank by f_λ alone).
PRIMARY = ["f_R", "s2f_mean_rel", "s2f_p95_rel", "chamfer_rel"]
PAPER = ["f_H", "f_S", "f_E", "f_F", "f_lambda"]
METRICS = PRIMARY + PAPER
COST = ["wall_s", "peak_rss_mb"]
#: Environment variable naming modules to treat as not installed (tests the skip path).
BLOCK_ENV = "FOLDMATCH_BENCH_BLOCK"


def log(msg: str) -> None:
    print(time.strftime("%H:%M:%S"), msg, flush=True)


def evaluate(case_arrays: dict[str, np.ndarray], fitted: np.ndarray) -> dict[str, Any]:
    """Every metric of ``fm.evaluate`` plus the distances relative to the target diagonal."""
    import foldmatch_rs as fm

    e = fm.evaluate(
        case_arrays["template_vertices"],
        case_arrays["faces"],
        fitted,
        case_arrays["target"],
        case_arrays.get("ground_truth"),
    )
    d = e["target_diagonal"]
    e["chamfer_rel"] = e["chamfer"] / d
    e["s2f_mean_rel"] = e["scan_to_fit_mean"] / d
    e["s2f_p95_rel"] = e["scan_to_fit_p95"] / d
    e["f2s_mean_rel"] = e["fit_to_scan_mean"] / d
    return {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in e.items()}


def machine() -> dict[str, Any]:
    """The machine a run was measured on (lscpu fields, memory, load average), shared by
    compare.py and perf.py."""
    info: dict[str, Any] = {
        "platform": platform.platform(),
        "cpus": os.cpu_count(),
        "nproc": os.cpu_count(),
        "python": sys.version.split()[0],
    }
    try:
        out = subprocess.run(["lscpu"], check=False, capture_output=True, text=True, timeout=10).stdout
        for line in out.splitlines():
            k, _, v = line.partition(":")
            if k.strip() in (
                "Model name",
                "CPU(s)",
                "Thread(s) per core",
                "Core(s) per socket",
                "Hypervisor vendor",
                "L2 cache",
                "L3 cache",
                "CPU max MHz",
            ):
                info[k.strip()] = v.strip()
    except (OSError, subprocess.SubprocessError):
        pass
    try:
        with open("/proc/meminfo") as fh:
            info["memory_gib"] = round(int(fh.readline().split()[1]) / 2**20, 1)
    except OSError:
        pass
    info["loadavg_at_start"] = os.getloadavg()
    return info


def code_version() -> str:
    """The commit the checkout is on, whether the tree differs from it, and when the
    extension was built (others rebuild it while the harness runs)."""
    repo = HERE.parent
    try:
        head = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            check=False,
            capture_output=True,
            text=True,
            cwd=repo,
            timeout=10,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            check=False,
            capture_output=True,
            text=True,
            cwd=repo,
            timeout=10,
        ).stdout
    except (OSError, subprocess.SubprocessError):
        head, dirty = "?", ""
    try:
        import foldmatch_rs

        so = next(pathlib.Path(foldmatch_rs.__file__).parent.glob("_foldmatch_rs*"))
        built = time.strftime("%Y-%m-%d %H:%M", time.localtime(so.stat().st_mtime))
    except (StopIteration, OSError, ImportError):
        built = "?"
    return f"commit {head or '?'}{' + uncommitted changes' if dirty.strip() else ''}, extension built {built}"


def method_status(methods: Iterable[str]) -> dict[str, str | None]:
    """Import check of every method in a subprocess: method → None or why it cannot run;
    ``_rtree`` → why mesh targets cannot be used by trimesh's NRICP."""
    methods = list(methods)
    blocked = {m for m in os.environ.get(BLOCK_ENV, "").split(",") if m}
    out = subprocess.run(
        [PY, "-m", "bench.peers", "--missing", *methods],
        check=False,
        capture_output=True,
        text=True,
        timeout=600,
        cwd=HERE.parent,
    )
    try:
        status = json.loads(out.stdout.strip().splitlines()[-1])
    except (IndexError, json.JSONDecodeError):
        status = {m: f"import check failed: {out.stderr[-300:]}" for m in methods}
        status["_rtree"] = None
    for m in methods:
        for mod in peers.METHODS[m]["modules"]:
            if mod in blocked:
                status[m] = f"cannot import {mod}: blocked by {BLOCK_ENV} (simulated missing peer)"
    if "rtree" in blocked:
        status["_rtree"] = f"cannot import rtree: blocked by {BLOCK_ENV}"
    return status


def case_digest(case: cases_mod.Case) -> str:
    h = hashlib.sha1()
    for a in (case.template_vertices, case.faces, case.target, case.target_faces, case.ground_truth):
        if a is not None:
            h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:12]


def extension_stamp() -> str:
    try:
        import foldmatch_rs

        so = next(pathlib.Path(foldmatch_rs.__file__).parent.glob("_foldmatch_rs*"))
        st = so.stat()
        return f"{st.st_size}-{int(st.st_mtime)}"
    except (StopIteration, OSError, ImportError):
        return "?"


def _key(params: dict[str, Any], trace: bool) -> str:
    return hashlib.sha1(json.dumps([params, trace], sort_keys=True, default=str).encode()).hexdigest()[:10]


class Runner:
    """Runs (case, method) pairs into ``out/runs/<case>/<method>[-tag].{npz,json}``."""

    def __init__(
        self,
        out: pathlib.Path,
        timeout: float = 1800,
        force: bool = False,
        status: dict[str, str | None] | None = None,
    ):
        self.out = out
        self.timeout = timeout
        self.force = force
        self.status = status or {}
        self._saved: set[pathlib.Path] = set()

    def case_path(self, case: cases_mod.Case) -> pathlib.Path:
        p = self.out / "cases" / f"{case.name}.npz"
        if p not in self._saved:
            case.save(p)
            self._saved.add(p)
        return p

    def run(
        self,
        case: cases_mod.Case,
        method: str,
        trace: bool = False,
        overrides: dict[str, Any] | None = None,
        tag: str = "",
    ) -> dict[str, Any]:
        """One run: a result row with status ok / failed / timeout / skipped, the metrics,
        wall time and memory."""
        spec = peers.METHODS[method]
        overrides = overrides or {}
        params = {**spec["params"], **overrides}
        row: dict[str, Any] = {"method": method, "label": spec["label"]}
        reason = self.status.get(method)
        if reason is None and method.startswith("nricp") and case.target_faces is not None:
            reason = self.status.get("_rtree")
        if reason is None:
            reason = peers.size_skip_reason(method, len(case.template_vertices), len(case.target), case.group)
        if reason is not None:
            row.update(status="skipped", reason=reason)
            return row
        d = self.out / "runs" / case.name
        d.mkdir(parents=True, exist_ok=True)
        stem = d / f"{method}{('-' + tag) if tag else ''}"
        npz, meta = pathlib.Path(str(stem) + ".npz"), pathlib.Path(str(stem) + ".npz.json")
        stamp = [case_digest(case)]
        if "foldmatch_rs" in spec["modules"]:
            stamp.append(extension_stamp())  # a rebuilt extension invalidates FoldMatch runs
        key = _key({**params, "_stamp": stamp}, trace)
        cp = self.case_path(case)
        cached = None
        if not self.force and meta.exists():
            try:
                cached = json.loads(meta.read_text())
            except json.JSONDecodeError:
                cached = None
            if cached is not None and (
                cached.get("key") != key or cached.get("status") not in ("ok", "failed", "timeout")
            ):
                cached = None
        if cached is None:
            for p in (npz, meta):
                p.unlink(missing_ok=True)
            cmd = [PY, "-m", "bench.peers", str(cp), method, str(npz)]
            if trace:
                cmd.append("--trace")
            if overrides:
                cmd += ["--params", json.dumps(overrides)]
            env = {**os.environ, "PYTHONWARNINGS": "ignore"}
            t0 = time.perf_counter()
            try:
                proc = subprocess.run(
                    cmd,
                    check=False,
                    capture_output=True,
                    text=True,
                    timeout=self.timeout,
                    env=env,
                    cwd=HERE.parent,
                )
                if meta.exists():
                    cached = json.loads(meta.read_text())
                else:
                    cached = {
                        "status": "failed",
                        "error": f"worker exited {proc.returncode}: {proc.stderr[-500:]}",
                    }
            except subprocess.TimeoutExpired:
                cached = {"status": "timeout", "error": f"no result within {self.timeout:.0f} s (killed)"}
            cached["process_s"] = round(time.perf_counter() - t0, 2)
            cached["key"] = key
            meta.write_text(json.dumps(cached))
        row.update(
            {
                k: cached.get(k)
                for k in (
                    "status",
                    "error",
                    "wall_s",
                    "peak_rss_mb",
                    "baseline_rss_mb",
                    "iterations",
                    "process_s",
                )
            }
        )
        row["params"] = params
        if cached.get("status") == "ok":
            with np.load(npz) as z:
                row["_fitted"] = z["fitted"]
                if "trace" in z.files:
                    row["_trace"] = z["trace"]
        return row


def reference_rows(case: cases_mod.Case, arrays: dict[str, np.ndarray]) -> dict[str, Any]:
    rows = {
        "identity": {
            "method": "identity",
            "label": "identity (template as is)",
            "status": "ok",
            **evaluate(arrays, case.template_vertices),
        }
    }
    if case.ground_truth is not None:
        rows["oracle"] = {
            "method": "oracle",
            "label": "oracle (ground truth)",
            "status": "ok",
            **evaluate(arrays, case.ground_truth),
        }
    else:
        rows["oracle"] = {
            "method": "oracle",
            "label": "oracle (ground truth)",
            "status": "skipped",
            "reason": "no ground truth for this case",
        }
    return rows


def case_arrays(case: cases_mod.Case) -> dict[str, np.ndarray]:
    a = {"template_vertices": case.template_vertices, "faces": case.faces, "target": case.target}
    if case.ground_truth is not None:
        a["ground_truth"] = case.ground_truth
    return a


def run_case(
    runner: Runner, case: cases_mod.Case, methods: list[str], keep_fits: bool = False, verbose: bool = True
) -> dict[str, Any]:
    """Every method (+ identity and oracle) on one case: the JSON record of the case."""
    arrays = case_arrays(case)
    rec: dict[str, Any] = {
        "name": case.name,
        "group": case.group,
        "template_vertices": len(case.template_vertices),
        "template_faces": len(case.faces),
        "target_points": len(case.target),
        "target_is_mesh": case.target_faces is not None,
        "ground_truth": case.ground_truth is not None,
        "meta": case.meta,
        "rows": reference_rows(case, arrays),
    }
    fits = {}
    for m in methods:
        row = runner.run(case, m)
        fitted = row.pop("_fitted", None)
        row.pop("_trace", None)
        if fitted is not None:
            row.update(evaluate(arrays, fitted))
            if keep_fits:
                fits[m] = fitted
        rec["rows"][m] = row
        if verbose:
            if row["status"] == "ok":
                log(
                    f"  {case.name:28s} {m:14s} f_R={_fmt(row.get('f_R'))} "
                    f"s2f_p95={_fmt(row['s2f_p95_rel'])} f_lambda={_fmt(row['f_lambda'])} "
                    f"{row['wall_s']:.2f}s {row['peak_rss_mb']:.0f}MB"
                )
            else:
                log(f"  {case.name:28s} {m:14s} {row['status']}: {row.get('reason') or row.get('error')}")
    if keep_fits:
        rec["_fits"] = fits
    return rec


def _fmt(v: Any) -> str:
    return "—" if v is None else f"{v:.4f}"
