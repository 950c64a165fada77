"""One measurement of ``bench.perf`` in a fresh process (``python -m bench.perf --worker JOB``):
the case generated, the method timed, peak memory (``VmHWM``) and threads sampled, one
``PERF_RESULT`` line printed."""

from __future__ import annotations

import json
import resource
import threading
import time
import warnings
from typing import Any

import numpy as np


def _status_kib(field: str) -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    return 0


class ThreadSampler:
    """Largest OS thread count of this process while running (20 ms sampling)."""

    def __init__(self) -> None:
        self.peak = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self._stop.is_set():
            self.peak = max(self.peak, _status_kib("Threads") - 1)  # minus the sampler
            self._stop.wait(0.02)

    def __enter__(self) -> ThreadSampler:  # noqa: PYI034
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()


def _cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _metrics(case: dict[str, np.ndarray], fitted: np.ndarray) -> dict[str, Any]:
    import foldmatch_rs as fm

    e = fm.evaluate(case["template_vertices"], case["faces"], fitted, case["scan"], case["ground_truth"])
    d = e["target_diagonal"]
    return {
        "f_lambda": e["f_lambda"],
        "f_R": e["f_R"],
        "f_H": e["f_H"],
        "f_S": e["f_S"],
        "f_E": e["f_E"],
        "f_F": e["f_F"],
        "s2f_mean_rel": e["scan_to_fit_mean"] / d,
    }


def _normalized(case: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, Any]:
    x = case["scan"]
    c = x.mean(0)
    s = float(np.linalg.norm(x.max(0) - x.min(0)))
    return (case["template_vertices"] - c) / s, (x - c) / s, (lambda y: y * s + c)


def timed_repeats(job: dict[str, Any], call: Any) -> tuple[list[float], list[Any]]:
    """Runs ``call()`` ``job["repeats"]`` times (1 by default), stopping early once the runs
    have taken ``job["repeat_budget_s"]`` (20 s); returns every run's wall time and result. The
    same rule for FoldMatch and the peers: each is reported by its best wall time."""
    walls, results = [], []
    budget = job.get("repeat_budget_s", 20.0)
    for _ in range(job.get("repeats", 1)):
        t0 = time.perf_counter()
        results.append(call())
        walls.append(time.perf_counter() - t0)
        if sum(walls) > budget:
            break
    return walls, results


def work_foldmatch(job: dict[str, Any], case: dict[str, np.ndarray]) -> dict[str, Any]:
    import foldmatch_rs as fm

    kw = dict(job.get("params", {}))
    cpu0 = _cpu_s()
    with ThreadSampler() as ts:
        walls, results = timed_repeats(
            job,
            lambda: fm.fit(
                case["template_vertices"],
                case["faces"],
                case["scan"],
                preset=job["preset"],
                threads=job.get("threads"),
                params=kw,
            ),
        )
    cpu = _cpu_s() - cpu0
    peak = _status_kib("VmHWM") / 1024
    best = int(np.argmin(walls))
    r = results[best]
    # Under schedule selection the two runs' stage times overlap (they run side by side):
    # each stage is shown as its share of the iterations' wall time, so the rows add up to it.
    raw = dict(r.diagnostics["stage_seconds"])
    setup_s, loop, finish_s = r.diagnostics["wall_seconds"]
    summed = sum(raw.values())
    stages = {s: (v * loop / summed if summed > 0 else 0.0) for s, v in raw.items()}
    stages["setup"] = max(walls[best] - loop, 0.0)
    out = {
        "wall_s": walls[best],
        "walls_s": walls,
        "iterations": r.iterations,
        "per_iteration_s": loop / max(r.iterations, 1),
        "stage_seconds": stages,
        "peak_rss_mb": peak,
        "cpu_s": cpu,
        "cpu_per_wall": cpu / sum(walls),
        "os_threads": ts.peak,
        "target_neighbours": r.diagnostics["target_neighbours"],
        "mean_ring_size": r.diagnostics["mean_ring_size"],
    }
    out["quality"] = _metrics(case, r.vertices)
    # The exact answer's own figures (the oracle), where the tables set methods side
    # by side: f_H stays above 0 for it (the scan's noise and the sheet's boundary), so a fit
    # can score a lower f_λ than the truth.
    # (once a case: on its default run)
    if job["section"] in ("peers", "large") and job["preset"] == "default" and not job.get("variant"):
        out["oracle"] = _metrics(case, case["ground_truth"])
    return out


def work_reference(job: dict[str, Any], case: dict[str, np.ndarray]) -> dict[str, Any]:
    """``tests/reference.py`` (loops over vertices, numpy.linalg for the 3×3 algebra) for a few
    iterations of the paper preset's FoldMatch phase, k-NN by scipy's cKDTree; the per-fit
    setup (n-rings, curvature) timed apart."""
    import foldmatch_rs as fm
    from scipy.spatial import cKDTree

    from tests import reference

    p = reference.DEFAULTS
    y, x, _back = _normalized(case)
    faces = case["faces"].astype(np.int64)
    m = len(y)
    k = max(8, min(64, int(0.002 * len(x)), len(x)))
    t0 = time.perf_counter()
    tree = cKDTree(x)
    kappa = fm.gaussian_curvature(x)  # Rust (setup only; the same κ the fit uses)
    rings = reference.n_rings(faces, m, p["rings"])
    setup = time.perf_counter() - t0
    reference.n_rings = lambda *_a, **_k: rings  # foldmatch_update would redo the BFS per call
    v = np.zeros_like(y)
    times = {"knn": 0.0, "nbody": 0.0, "model": 0.0}
    cpu0 = _cpu_s()
    with ThreadSampler() as ts:
        for _ in range(job["iterations"]):
            t = time.perf_counter()
            _, idx = tree.query(y, k)
            times["knn"] += time.perf_counter() - t
            t = time.perf_counter()
            v, proposed = reference.nbody_step(y, v, x, idx, kappa)
            times["nbody"] += time.perf_counter() - t
            t = time.perf_counter()
            new, _ = reference.foldmatch_update(y, proposed, faces)
            times["model"] += time.perf_counter() - t
            v = (new - y) / p["time_step"]
            y = new
    loop = sum(times.values())
    it = job["iterations"]
    per = loop / it
    return {
        "iterations": it,
        "setup_s": setup,
        "per_iteration_s": per,
        "stage_seconds": {s: t / it for s, t in times.items()},
        "wall_s": setup + loop,
        "extrapolated_100_s": setup + 100 * per,
        "peak_rss_mb": _status_kib("VmHWM") / 1024,
        "cpu_per_wall": (_cpu_s() - cpu0) / loop,
        "os_threads": ts.peak,
        "target_neighbours": k,
    }


def run_rustcpd(
    v,
    f,
    x,
    xf=None,
    trace=False,
    alpha=2.0,
    beta=2.0,
    w=0.0,
    maxiter=100,
    tol=1e-3,
    low_rank=300,
    **_,
):
    """bench/peers.py's rustcpd adapter, with the pivoted-Cholesky low-rank kernel above 3,000
    points (its default "eigen" factor forms the dense M×M kernel and decomposes it, O(M³))."""
    import rustcpd

    from bench import peers

    yn, xn, back = peers.normalize(v, x)
    use_low = low_rank if low_rank and low_rank < len(yn) else None
    method = "pivoted_cholesky" if len(yn) > 3000 else "eigen"
    res = rustcpd.register_deformable(
        xn,
        yn,
        alpha=alpha,
        beta=beta,
        low_rank=use_low,
        low_rank_method=method,
        max_iterations=int(maxiter),
        tolerance=tol,
        outlier_weight=w,
    )
    return back(res.points), None, {"iterations": int(res.iterations), "low_rank_method": method}


def work_peer(job: dict[str, Any], case: dict[str, np.ndarray]) -> dict[str, Any]:
    from bench import peers

    method = job["method"]
    spec = peers.METHODS[method]
    if job.get("rlimit_gb"):
        lim = int(job["rlimit_gb"] * 2**30)
        resource.setrlimit(resource.RLIMIT_AS, (lim, lim))
    params = {**spec["params"], **job.get("overrides", {})}
    run = run_rustcpd if method == "cpd_rustcpd" else spec["run"]
    # Repeated like FoldMatch's runs, so that a short peer run's noise does not decide a ratio.
    cpu0 = _cpu_s()
    with warnings.catch_warnings(), ThreadSampler() as ts:
        warnings.simplefilter("ignore")
        walls, results = timed_repeats(
            job, lambda: run(case["template_vertices"], case["faces"], case["scan"], None, False, **params)
        )
    cpu = _cpu_s() - cpu0
    best = int(np.argmin(walls))
    fitted, _, extra = results[best]
    wall = walls[best]
    out = {
        "wall_s": wall,
        "walls_s": walls,
        "peak_rss_mb": _status_kib("VmHWM") / 1024,
        "cpu_per_wall": cpu / sum(walls),
        "os_threads": ts.peak,
        "params": params,
        **extra,
    }
    its = out.get("iterations") or 0
    out["per_iteration_s"] = wall / its if its else None
    fitted = np.asarray(fitted, dtype=np.float64)
    if fitted.shape == case["template_vertices"].shape and np.all(np.isfinite(fitted)):
        out["quality"] = _metrics(case, fitted)
    else:
        out["status"] = "failed"
        out["error"] = f"bad output: shape {fitted.shape}"
    return out


def worker(job: dict[str, Any]) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import foldmatch_rs as fm

        if job["kind"] == "peer":  # the peer's imports count in its baseline, not its peak
            import importlib

            from bench import peers

            for mod in peers.METHODS[job["method"]]["modules"]:
                importlib.import_module(mod)
        if job["kind"] == "reference":
            from scipy.spatial import cKDTree  # noqa: F401

            from tests import reference  # noqa: F401
    case = fm.folded_sheet(**job["case"])
    info: dict[str, Any] = {
        "status": "ok",
        "baseline_rss_mb": _status_kib("VmHWM") / 1024,
        "m": len(case["template_vertices"]),
        "n": len(case["scan"]),
    }
    try:
        fn = {"foldmatch": work_foldmatch, "reference": work_reference, "peer": work_peer}
        info.update(fn[job["kind"]](job, case))
    except MemoryError as e:
        info.update(
            status="failed",
            error=f"MemoryError (address space capped at {job.get('rlimit_gb')} GB): {e}",
        )
    # Recorded, never raised: one failure must not stop the run.
    except Exception as e:  # noqa: BLE001
        info.update(status="failed", error=f"{type(e).__name__}: {str(e)[:300]}")
    print("PERF_RESULT " + json.dumps(info), flush=True)
