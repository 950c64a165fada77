"""One adapter per registration method, with a uniform signature, and the worker process that
times one (method, case) run and measures its peak memory.

Every adapter is ``run(template_vertices, faces, target_points, target_faces=None, trace=False,
**params) -> (fitted_vertices (M, 3), trace)`` where ``trace`` is a list of per-iteration vertex
arrays (or None when not asked for / not available).

Frame: the peers are given the data in FoldMatch's normalized frame (docs/method.md "Frame": centered on the
target's centroid, target bounding-box diagonal = 1), so one set of parameters is meaningful
on every case; the result is mapped back. FoldMatch and NRGa do the same internally.
(trimesh's NRICP additionally re-normalizes by the template, internally.)

Parameters: FoldMatch and NRGa run with the library's defaults (``fm.DEFAULT_PARAMS``: the
paper's constants plus the fidelity options of docs/method.md); "FoldMatch (paper preset)" is
``fm.fit(preset="paper")``, the method as the paper prints it. Every peer's parameters were
chosen by the sweep in ``bench/tune.py`` (held-out generated cases, lowest mean of f_R +
scan→fit p95; see docs/notes/comparison-full-run.md, "How the peers were tuned").

Peak memory: each run is its own Python process (``python -m bench.peers CASE METHOD OUT``);
``resource.getrusage(RUSAGE_SELF).ru_maxrss`` at the end is the peak resident set of the whole
process (interpreter, libraries, data and the method; it sees Rust, BLAS and NumPy-C
allocations, which tracemalloc does not). The same value taken just before the method starts
is reported as the baseline, so ``peak − baseline`` is the method's own working memory (a
lower bound when the method reuses memory the imports touched).
"""

from __future__ import annotations

import importlib
import json
import os
import resource
import sys
import time
import warnings
from typing import Any, Callable

import numpy as np

# ---- parameters (chosen by bench/tune.py; see docs/notes/comparison-full-run.md) ------------

#: CPD (all three implementations are given the same parameters): λ (alpha) the smoothness
#: weight, β the Gaussian kernel's width parameter in the normalized frame (target diagonal 1),
#: w the outlier weight; EM until the σ² change is below `tol` or `maxiter`. (The packages'
#: default α=2, β=2 is near-affine at this scale: sweep score 0.063 against 0.049.) The same β
#: is not the same kernel: probreg's is exp(−d²/(2β)), pycpd's and rustcpd's exp(−d²/(2β²)), so
#: probreg runs at width √0.1 ≈ 0.32 of the diagonal and the other two at 0.1; the best-peer
#: figures take the better of the two models per case (docs/notes/rim-matching.md).
CPD_PARAMS = {"alpha": 512.0, "beta": 0.1, "w": 0.05, "maxiter": 150, "tol": 1e-6}
#: rustcpd extra: rank-300 low-rank kernel (its default; exact kernel when M ≤ 300; the sweep
#: found rank 300 equal to the exact kernel to 4 digits), exact E-step.
RUSTCPD_PARAMS = {**CPD_PARAMS, "low_rank": 300}
#: probreg's BCPD (Hirose 2021): λ, γ, κ; its kernel is an inverse multiquadric of fixed width
#: 1, so the width β is set by scaling the normalized coordinates by 1/β (β < 1 collapsed the
#: template in trials; the sweep's score is erratic in λ: 0.20, 0.14, 0.27, 0.084 for λ = 2, 8,
#: 32, 128). 40 EM iterations (≈2.5 s each at M = 1.7K).
BCPD_PARAMS = {"lmd": 128.0, "gamma": 1.0, "k": 1e20, "beta": 1.0, "w": 0.05, "maxiter": 40, "tol": 1e-6}
#: trimesh nricp_amberg: a decreasing stiffness schedule (ws, wl, wn, max_iter) per step,
#: Amberg et al.'s recipe, from 10 down to 0.01, 20 iterations per step, no normal weighting;
#: correspondences farther than `distance_threshold` (template-normalized units) ignored.
#: (trimesh's own default schedule scored 0.082 against 0.078 in the sweep.)
AMBERG_PARAMS = {
    "steps": [[ws, 0, 0.0, 20] for ws in (10.0, 3.0, 1.0, 0.3, 0.1, 0.03, 0.01)],
    "distance_threshold": 0.3,
}
#: trimesh nricp_sumner: (wc, wi, ws, wl, wn) per step: correspondence weight 1 → 1000,
#: identity 0.001, smoothness 3 (trimesh's default: wc up to 100, ws = 1).
SUMNER_PARAMS = {
    "steps": [[1, 0.001, 3.0, 0, 0], [1, 0.001, 3.0, 0, 0], [10, 0.001, 3.0, 0, 0], [1000, 0.001, 3.0, 0, 0]],
    "distance_threshold": 0.3,
}
FOLDMATCH_PARAMS: dict[str, Any] = {}  # the library defaults (fm.DEFAULT_PARAMS)


def normalize(template: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray, Callable]:
    c = target.mean(0)
    s = float(np.linalg.norm(target.max(0) - target.min(0)))
    return (template - c) / s, (target - c) / s, (lambda y: np.asarray(y) * s + c)


# ---- adapters -------------------------------------------------------------------------------


def run_foldmatch(v, f, x, xf=None, trace=False, method="foldmatch", preset=None, **params):
    import foldmatch_rs as fm

    settings = dict(params, method=method, snapshot_every=1 if trace else 0)
    r = fm.fit(v, f, x, target_faces=xf, preset=preset, params=settings)
    tr = [v] + [s for _, s in r.snapshots] if trace else None
    return r.vertices, tr, {"iterations": r.iterations}


def run_foldmatch_paper(v, f, x, xf=None, trace=False, **params):
    return run_foldmatch(v, f, x, xf, trace, preset="paper", **params)


def run_nrga(v, f, x, xf=None, trace=False, **params):
    # NRGa as published: the paper's constants (constant softening), no fidelity options.
    return run_foldmatch(v, f, x, xf, trace, preset="paper", method="nrga", **params)


def run_pycpd(v, f, x, xf=None, trace=False, alpha=2.0, beta=2.0, w=0.0, maxiter=100, tol=1e-3, **_):
    from pycpd import DeformableRegistration

    yn, xn, back = normalize(v, x)
    tr = [yn.copy()] if trace else None

    def cb(iteration=None, error=None, X=None, Y=None):
        if tr is not None:
            tr.append(np.array(Y))

    reg = DeformableRegistration(
        X=xn, Y=yn, alpha=alpha, beta=beta, w=w, max_iterations=int(maxiter), tolerance=tol
    )
    ty, _ = reg.register(cb)
    return back(ty), ([back(t) for t in tr] if tr else None), {"iterations": int(reg.iteration)}


def run_probreg_cpd(v, f, x, xf=None, trace=False, alpha=2.0, beta=2.0, w=0.0, maxiter=100, tol=1e-3, **_):
    from probreg import cpd

    yn, xn, back = normalize(v, x)
    tr = [yn.copy()] if trace else None
    count = [0]

    def cb(t):
        count[0] += 1
        if tr is not None:
            tr.append(t.transform(yn))

    res = cpd.registration_cpd(
        yn,
        xn,
        tf_type_name="nonrigid",
        w=w,
        maxiter=int(maxiter),
        tol=tol,
        callbacks=[cb],
        beta=beta,
        lmd=alpha,
    )
    out = res.transformation.transform(yn)
    return back(out), ([back(t) for t in tr] if tr else None), {"iterations": count[0]}


def run_rustcpd(
    v, f, x, xf=None, trace=False, alpha=2.0, beta=2.0, w=0.0, maxiter=100, tol=1e-3, low_rank=300, **_
):
    import rustcpd

    yn, xn, back = normalize(v, x)
    tr = [yn.copy()] if trace else None
    count = [0]

    def cb(state):
        count[0] += 1
        if tr is not None:
            tr.append(np.array(state["points"]))

    res = rustcpd.register_deformable(
        xn,
        yn,
        alpha=alpha,
        beta=beta,
        low_rank=(low_rank if low_rank and low_rank < len(yn) else None),
        max_iterations=int(maxiter),
        tolerance=tol,
        outlier_weight=w,
        callback=cb,
    )
    return back(res.points), ([back(t) for t in tr] if tr else None), {"iterations": int(res.iterations)}


def run_probreg_bcpd(
    v, f, x, xf=None, trace=False, lmd=2.0, gamma=1.0, k=1e20, beta=1.0, w=0.0, maxiter=50, tol=1e-3, **_
):
    from probreg import bcpd

    yn, xn, back = normalize(v, x)
    yb, xb = yn / beta, xn / beta  # kernel width β via coordinate scaling (see BCPD_PARAMS)
    tr = [yn.copy()] if trace else None
    count = [0]

    def cb(t):
        count[0] += 1
        if tr is not None:
            tr.append(t.transform(yb) * beta)

    t = bcpd.registration_bcpd(
        yb, xb, w=w, maxiter=int(maxiter), tol=tol, callbacks=[cb], lmd=lmd, k=k, gamma=gamma
    )
    out = t.transform(yb) * beta
    return back(out), ([back(t) for t in tr] if tr else None), {"iterations": count[0]}


def _trimesh_target(x, xf):
    import trimesh

    if xf is not None:
        return trimesh.Trimesh(x, xf, process=False), True
    return trimesh.PointCloud(x), False


def _without_isolated(v, f):
    """Vertices referenced by a face, the faces renumbered to them, and a function putting a
    fit of those back on all vertices: each unreferenced vertex moves with its nearest
    referenced template vertex. trimesh's Amberg system is singular with unreferenced
    vertices (the real skirts have 80–84, duplicates of seam vertices)."""
    used = np.zeros(len(v), bool)
    used[np.asarray(f).ravel()] = True
    if used.all():
        return v, f, lambda y: y
    keep = np.flatnonzero(used)
    new_index = np.full(len(v), -1)
    new_index[keep] = np.arange(len(keep))
    lonely = np.flatnonzero(~used)
    d2 = ((v[lonely, None, :] - v[None, keep, :]) ** 2).sum(-1)
    partner = d2.argmin(1)

    def expand(y):
        out = v.astype(np.float64).copy()
        out[keep] = y
        out[lonely] = v[lonely] + (y[partner] - v[keep[partner]])
        return out

    return v[keep], new_index[f], expand


def run_amberg(v, f, x, xf=None, trace=False, steps=None, distance_threshold=0.1, **_):
    import trimesh
    from trimesh.registration import nricp_amberg

    yn, xn, back = normalize(v, x)
    yk, fk, expand = _without_isolated(yn, np.asarray(f))
    src = trimesh.Trimesh(yk, fk, process=False)
    tgt, use_faces = _trimesh_target(xn, xf)
    # trimesh 5.2 needs use_faces=False for point-cloud targets (and rtree for mesh targets)
    rec = nricp_amberg(
        src, tgt, steps=steps, distance_threshold=distance_threshold, use_faces=use_faces, return_records=True
    )
    return (
        back(expand(rec[-1])),
        ([back(expand(r)) for r in rec] if trace else None),
        {"iterations": len(rec) - 1},
    )


def run_sumner(v, f, x, xf=None, trace=False, steps=None, distance_threshold=0.1, **_):
    import trimesh
    from trimesh.registration import nricp_sumner

    yn, xn, back = normalize(v, x)
    src = trimesh.Trimesh(yn, f, process=False)
    tgt, use_faces = _trimesh_target(xn, xf)
    rec = nricp_sumner(
        src, tgt, steps=steps, distance_threshold=distance_threshold, use_faces=use_faces, return_records=True
    )
    return back(rec[-1]), ([back(r) for r in rec] if trace else None), {"iterations": len(rec) - 1}


# ---- the registry ---------------------------------------------------------------------------

#: name → label, adapter, parameters, modules it needs (pip names), size limit and notes.
METHODS: dict[str, dict[str, Any]] = {
    "foldmatch": {
        "label": "FoldMatch",
        "run": run_foldmatch,
        "params": FOLDMATCH_PARAMS,
        "modules": ["foldmatch_rs"],
        "pip": [],
        "family": "ours",
        "note": "library defaults (fm.DEFAULT_PARAMS, recorded in the header): the "
        "paper's constants (G=1.67, ε=0.1, η=0.1, Δt=0.006, ψ=0.05, 2-ring, ξ=100) "
        "plus the additions of docs/method.md (ρ = 0.1 %, K ≤ 32)",
    },
    "foldmatch_paper": {
        "label": "FoldMatch (paper preset)",
        "run": run_foldmatch_paper,
        "params": FOLDMATCH_PARAMS,
        "modules": ["foldmatch_rs"],
        "pip": [],
        "family": "ours",
        "note": "fm.fit(preset='paper'): the method as the paper prints it "
        "(one-way attraction, no rigid/coarse phases), with only the "
        "converging readings of docs/method.md",
    },
    "nrga": {
        "label": "NRGa",
        "run": run_nrga,
        "params": FOLDMATCH_PARAMS,
        "modules": ["foldmatch_rs"],
        "pip": [],
        "family": "ours",
        "note": "fm.fit(preset='paper', method='nrga'): the same N-body model, per-vertex "
        "rigid fits of k-nearest template neighborhoods, no mesh model",
    },
    "cpd_pycpd": {
        "label": "CPD (pycpd)",
        "run": run_pycpd,
        "params": CPD_PARAMS,
        "modules": ["pycpd"],
        "pip": ["pycpd"],
        "family": "cpd",
        "max_mn": 1.2e7,
        "max_m": 3000,
        "note": "dense kernel (M×M solve) and dense M×N×3 E-step; ~5 s per "
        "iteration at M=4.4K here, so M ≤ 3,000 only (rustcpd covers CPD "
        "beyond)",
    },
    "cpd_probreg": {
        "label": "CPD (probreg)",
        "run": run_probreg_cpd,
        "params": CPD_PARAMS,
        "modules": ["probreg"],
        "pip": ["probreg"],
        "family": "cpd",
        "max_mn": 1.2e7,
        "max_m": 3000,
        "note": "dense kernel (M×M solve), M ≤ 3,000 only; needs libusb-1.0 for open3d",
    },
    "cpd_rustcpd": {
        "label": "CPD (rustcpd)",
        "run": run_rustcpd,
        "params": RUSTCPD_PARAMS,
        "modules": ["rustcpd"],
        "pip": ["rustcpd"],
        "family": "cpd",
        "note": "rank-300 low-rank kernel, exact E-step, Rust, parallel",
    },
    "bcpd_probreg": {
        "label": "BCPD (probreg)",
        "run": run_probreg_bcpd,
        "params": BCPD_PARAMS,
        "modules": ["probreg"],
        "pip": ["probreg"],
        "family": "cpd",
        "max_mn": 4.5e6,
        "max_m": 2100,
        "groups": ("quick", "small", "sim"),
        "note": "dense (3M×3N) Kronecker products, ~2.5 s per iteration at "
        "M=1.7K: the small generated and simulated cases only",
    },
    "nricp_amberg": {
        "label": "NRICP (Amberg)",
        "run": run_amberg,
        "params": AMBERG_PARAMS,
        "modules": ["trimesh", "scipy"],
        "pip": ["trimesh", "scipy"],
        "family": "nricp",
        "note": "trimesh.registration.nricp_amberg; rtree for mesh targets",
    },
    "nricp_sumner": {
        "label": "NRICP (Sumner)",
        "run": run_sumner,
        "params": SUMNER_PARAMS,
        "modules": ["trimesh", "scipy"],
        "pip": ["trimesh", "scipy"],
        "family": "nricp",
        "note": "trimesh.registration.nricp_sumner (deformation-transfer energy)",
    },
}
ALL_METHODS = list(METHODS)


def size_skip_reason(method: str, m: int, n: int, group: str = "") -> str | None:
    """Why ``method`` is not run at template size ``m`` and target size ``n`` (in case group
    ``group``), or None."""
    spec = METHODS[method]
    if "groups" in spec and group and group not in spec["groups"]:
        return f"run on the {'/'.join(spec['groups'])} cases only ({spec['note']})"
    if "max_m" in spec and m > spec["max_m"]:
        return (
            f"too large for a dense method: M={m} > {spec['max_m']} ({spec['note']}; ~M³ flops per iteration)"
        )
    if "max_mn" in spec and m * n > spec["max_mn"]:
        return f"too large for a dense method: M·N={m * n:.2g} > {spec['max_mn']:.2g} ({spec['note']})"
    return None


def missing_reason(method: str, mesh_target: bool = False) -> str | None:
    """Why ``method`` cannot run in this environment (a failed import), or None. Imports in
    this process; the harness calls it in a subprocess so heavy imports stay out of its own
    memory."""
    need = list(METHODS[method]["modules"])
    if method.startswith("nricp") and mesh_target:
        need.append("rtree")
    for mod in need:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                importlib.import_module(mod)
        except Exception as e:  # noqa: BLE001  (ImportError, OSError from a missing library, ...)
            return f"cannot import {mod}: {type(e).__name__}: {str(e).splitlines()[0][:200]}"
    return None


def versions() -> dict[str, str]:
    """Versions of every package the harness can use (missing ones as 'not installed')."""
    from importlib import metadata

    out = {"python": sys.version.split()[0]}
    for dist in (
        "foldmatch-rs",
        "numpy",
        "scipy",
        "trimesh",
        "pycpd",
        "probreg",
        "open3d",
        "rustcpd",
        "rtree",
        "matplotlib",
        "psutil",
    ):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = "not installed"
    return out


# ---- the worker -----------------------------------------------------------------------------


def _maxrss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # KiB on Linux


def worker(case_path: str, method: str, out_path: str, trace: bool, overrides: dict) -> int:
    """Run one method on one case; write ``out_path`` (.npz with ``fitted`` and ``trace``) and
    ``out_path`` + ``.json`` (timings, memory, status)."""
    spec = METHODS[method]
    info: dict[str, Any] = {"method": method, "status": "ok"}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for mod in spec["modules"]:
                importlib.import_module(mod)
        with np.load(case_path) as z:
            v, f, x = z["template_vertices"], z["faces"], z["target"]
            xf = z["target_faces"] if "target_faces" in z.files else None
        if method.startswith("nricp") and xf is not None:
            importlib.import_module("rtree")
        params = {**spec["params"], **overrides}
        info["params"] = params
        info["baseline_rss_mb"] = round(_maxrss_mb(), 1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t0 = time.perf_counter()
            fitted, tr, extra = spec["run"](v, f, x, xf, trace, **params)
            info["wall_s"] = round(time.perf_counter() - t0, 4)
        info["peak_rss_mb"] = round(_maxrss_mb(), 1)
        info.update(extra)
        fitted = np.asarray(fitted, dtype=np.float64)
        if fitted.shape != v.shape or not np.all(np.isfinite(fitted)):
            info["status"] = "failed"
            info["error"] = f"bad output: shape {fitted.shape}, finite={np.isfinite(fitted).all()}"
        arrays = {"fitted": fitted}
        if tr is not None:
            arrays["trace"] = np.asarray(tr, dtype=np.float32)
        np.savez(out_path, **arrays)
    except Exception as e:  # noqa: BLE001  (recorded: one failure must not stop the harness)
        info["status"] = "failed"
        info["error"] = f"{type(e).__name__}: {str(e)[:500]}"
    with open(out_path + ".json", "w") as fh:
        json.dump(info, fh)
    return 0


if __name__ == "__main__":
    if len(sys.argv) >= 2 and sys.argv[1] == "--missing":
        status = {m: missing_reason(m) for m in sys.argv[2:]}
        try:
            importlib.import_module("rtree")
            status["_rtree"] = None
        except Exception as e:  # noqa: BLE001
            status["_rtree"] = f"cannot import rtree: {type(e).__name__}: {e}"
        print(json.dumps(status))
        sys.exit(0)
    if len(sys.argv) < 4:
        print(
            "usage: peers.py CASE.npz METHOD OUT.npz [--trace] [--params JSON]\n"
            "       peers.py --missing METHOD...",
            file=sys.stderr,
        )
        sys.exit(2)
    args = sys.argv[1:]
    tr = "--trace" in args
    ov = json.loads(args[args.index("--params") + 1]) if "--params" in args else {}
    os.environ.setdefault("PYTHONWARNINGS", "ignore")
    sys.exit(worker(args[0], args[1], args[2], tr, ov))
