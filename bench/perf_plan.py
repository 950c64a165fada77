"""What one run of ``bench.perf`` measures: the cases, the stages and their levers, the
presets and peers, and every job of the plan in run order."""

from __future__ import annotations

import time
from typing import Any

#: Stages of ``diagnostics["stage_seconds"]``, in iteration order.
STAGES = ["knn", "two_way", "nbody", "gradient", "regularize", "rotation", "update"]
STAGE_NAMES = {
    "knn": "k-NN (Γᵏ_X)",
    "two_way": "two-way attraction",
    "nbody": "force + step (Eq. 2–3)",
    "gradient": "gradients (Eq. 4)",
    "regularize": "regularization (Eq. 5)",
    "rotation": "stretch/wrinkle/rotation (Eq. 6–8)",
    "update": "update (+ rigid/coarse)",
    "setup": "setup + final (outside the loop)",
}
#: What would make each stage cheaper (for the "missed targets" analysis).
LEVERS = {
    "knn": "k-NN: the candidate cache (2K candidates, re-used while the re-ranked K-th is "
    "closer than d_c − δ) answers nearly all of the fine phase; the rest are ball queries on a "
    "box-pruned tree over the scan (kiddo's split-plane pruning cost ~20 µs per re-query for "
    "template points off the scan's surface at 1M points). In the rigid and coarse phases a "
    "template point far off the surface (height h ≫ ρ) sees all its candidates at ≈ h, so its "
    "margin d_c − d_K is tiny and it would re-query nearly every iteration; those two phases "
    "re-use the candidates while every neighbour is within (1 + σ) × the true K-th distance "
    '(`knn_slack`, default 0.1; docs/method.md "Approximate neighbours in the rigid and '
    'coarse phases"). '
    "Re-ranking the 2K candidates is memory-bound. Re-queries and first queries are best-first "
    "searches of the box tree writing a sorted list in place (bounded by the old candidates' "
    "ball for re-queries). Closing: what is left is mostly points that moved beyond their "
    "candidates' ball within one iteration (far, fast points), and the re-ranking itself",
    "two_way": "two-way attraction: a scan point's nearest template vertex comes from the "
    "inverted forward k-NN lists when certified (closer than the smallest K-th neighbour "
    "distance: ~100 % once the template lies on the scan), else from a box-tree query "
    "started from a known template point (the tree over the moving template refitted, O(M), "
    "and rebuilt only when its leaves loosen 1.5×); the rigid phase (every 4th vertex, the flat "
    "template still far from the folded scan: ~95 % of the scan uncertified) makes most of "
    "them; where the scan has more than 8 points per rigid-phase vertex (the 1M-point case), "
    "only every s-th scan point pulls in the rigid phase (`rigid_scan_sample`, automatic), "
    "and with at least 8 points per vertex every 2nd in the coarse phase "
    "(`coarse_scan_sample`, automatic). Where the lists are exact (the fine phase) the tree "
    "searches skip nodes whose smallest K-th neighbour distance exceeds the best found (the "
    "same answer). Closing: the coarse "
    "phase's uncertified queries (the template still off the scan), a cheaper exact far query",
    "nbody": "force: f64x4 SIMD over the K neighbors, neighbors' coordinates and κ gathered once per vertex",
    "gradient": "gradients: already closed-form eigenvalues and a direct inverse where B is "
    "well-conditioned; what is left is the ring gathers (memory-bound)",
    "regularize": "regularization (paper preset): the affine-invariant mean needs one "
    "logarithm per ring pair (≈250K per iteration); the default's log-Euclidean mean needs "
    "one per vertex",
    "rotation": "ψ-stretch/rotation: with the regularized gradient, Eq. 8's rotation is R̄ "
    "wherever the ψ-modified eigenvalues stay positive (a determinant/trace bound), so the "
    "iterations skip the Procrustes solve and the ψ-stretch's Jacobi eigen-decomposition; the "
    "wrinkle field is computed once, after the last iteration. Nothing left to close",
    "update": "update: the coarse phase's Kabsch fits of the coarse rings, their sums of "
    "per-point moments taken from an adjacent ring's sum plus and minus the differing members "
    "(`rings::RingDeltas`), and their nearest rotations by Horn's unit quaternion "
    "(`math::rotation_quaternion`); what is left is the moments' reads and one quaternion "
    "solve a vertex",
    "setup": "setup: curvature of the scan, the scan tree and the coarse rings' BFS (shared "
    "by both schedules); the final wrinkle fields and the selection's scan distances and edge "
    "spreads",
}


# ======================================================================================
# The plan: what one run measures
# ======================================================================================


def sheet(side: int, scan: int) -> dict[str, Any]:
    return {"nx": side, "ny": side, "scan_points": scan, "noise": 0.001}


def plan(quick: bool) -> dict[str, Any]:
    """Cases and jobs of one run. ``quick`` replaces every size by a small one (a smoke test of
    the whole pipeline, not a measurement)."""
    if quick:
        cases = {
            "paper": {
                "label": "quick stand-in for the paper size (32×32 sheet)",
                "spec": sheet(32, 1_300),
            },
            "small": {
                "label": "quick stand-in for the 2K/2.5K case (24×24 sheet)",
                "spec": sheet(24, 700),
            },
            "large": {
                "label": "quick stand-in for the large case (71×71 sheet)",
                "spec": sheet(71, 50_000),
            },
        }
        sweep_m = {"sides": [16, 32, 48, 64], "scan": 10_000, "iterations": 10}
        sweep_n = {"side": 32, "scans": [2_000, 8_000, 32_000], "iterations": 10, "k": 28}
        return {
            "quick": True,
            "cases": cases,
            "sweep_m": sweep_m,
            "sweep_n": sweep_n,
            "repeats": 1,
            "reference_iterations": 1,
            "large_iterations": 10,
            "timeout": 120,
            "peer_caps": {
                "cpd_rustcpd": {"maxiter": 5},
                "cpd_pycpd": {"maxiter": 5},
                "cpd_probreg": {"maxiter": 5},
                "nricp_amberg": {"steps": [[10.0, 0, 0.5, 3]]},
            },
            "large_peer_caps": {
                "cpd_rustcpd": {"maxiter": 1},
                "nricp_amberg": {"steps": [[10.0, 0, 0.5, 1]]},
            },
            "large_peer_timeout": 60,
        }
    cases = {
        "paper": {
            "label": "paper size: 115×115 sheet (13,225 vertices), 14,400 scan points",
            "spec": sheet(115, 14_400),
        },
        "small": {
            "label": "small peer case: 45×45 sheet (2,025 vertices), 2,500 scan points",
            "spec": sheet(45, 2_500),
        },
        "large": {
            "label": "large: 317×317 sheet (100,489 vertices), 1,000,000 scan points",
            "spec": sheet(317, 1_000_000),
        },
    }
    sweep_m = {"sides": [32, 71, 100, 159, 224, 317, 448], "scan": 100_000, "iterations": 20}
    sweep_n = {"side": 100, "scans": [10_000, 100_000, 1_000_000], "iterations": 20, "k": 28}
    return {
        "quick": False,
        "cases": cases,
        "sweep_m": sweep_m,
        "sweep_n": sweep_n,
        "repeats": 3,
        "reference_iterations": 2,
        "large_iterations": 100,
        "timeout": 600,
        "peer_caps": {},
        "large_peer_caps": {
            "cpd_rustcpd": {"maxiter": 1},
            "nricp_amberg": {"steps": [[10.0, 0, 0.5, 1]]},
        },
        "large_peer_timeout": 300,
    }


#: The FoldMatch presets measured beside the peers on the paper-sized and small cases: the
#: default, the fast preset (one schedule: what closes the time targets at an accuracy cost,
#: FAST_PRICE) and the paper's method.
PEER_PRESETS = ("default", "fast", "paper")
#: The fast preset's price, which this script does not measure (docs/method.md "Presets").
FAST_PRICE = (
    "its price is accuracy, which this run does not measure: on the comparison harness "
    "it is farther from the truth than the default (`python -m bench.variants "
    '--variant \'fast={"preset": "fast"}\'` scores it)'
)

#: Peers measured on the paper-sized and small cases (bench/peers.py adapters and tuned
#: parameters), and how many iterations their uncapped run does at most.
PEERS = ["cpd_rustcpd", "cpd_probreg", "cpd_pycpd", "nricp_amberg"]
#: Dense methods: skipped when their M×N (and M×M) arrays would exceed this many bytes.
DENSE = {"cpd_pycpd", "cpd_probreg"}
DENSE_LIMIT_BYTES = 3 * 2**30
#: The large case's second FoldMatch row: the rigid and coarse phases' k-NN slack σ
#: (``knn_slack``) of 0.3 against the default's 0.1 (docs/method.md "Approximate neighbours in
#: the rigid and coarse phases").
LARGE_KNN_SLACK = 0.3

#: Address-space cap of peer processes on the large case (protects the shared machine).
LARGE_PEER_RLIMIT_GB = 12


def peer_full_iterations(method: str) -> int:
    from bench import peers

    params = peers.METHODS[method]["params"]
    if "steps" in params:
        return int(sum(s[3] for s in params["steps"]))
    return int(params.get("maxiter", 100))


def dense_skip(method: str, m: int, n: int) -> str | None:
    if method not in DENSE:
        return None
    need = 8 * (3 * m * n + m * m)  # P and the M×N×3 differences, the M×M kernel (f64)
    if need > DENSE_LIMIT_BYTES:
        return (
            f"dense CPD: its M×N×3 differences, M×N posterior and M×M kernel need "
            f"≈{need / 2**30:.1f} GiB (M·N = {m * n:.2g}), beyond the {DENSE_LIMIT_BYTES >> 30} "
            f"GiB allowed here; plus an O(M³) solve per iteration"
        )
    return None


def jobs_for(p: dict[str, Any]) -> list[dict[str, Any]]:
    """Every job of the plan, in run order."""
    jobs: list[dict[str, Any]] = []
    cases = p["cases"]
    t = p["timeout"]

    def fm_job(section, case, preset, threads=None, repeats=None, **extra):
        spec = cases[case]["spec"] if isinstance(case, str) else case
        name = case if isinstance(case, str) else f"{spec['nx']}x{spec['ny']}/{spec['scan_points']}"
        return dict(
            section=section,
            kind="foldmatch",
            case_name=name,
            case=spec,
            preset=preset,
            threads=threads,
            repeats=repeats or p["repeats"],
            **{"timeout": t, **extra},
        )

    # (a) the paper-sized case and the small peer case.
    for cname in ("paper", "small"):
        spec = cases[cname]["spec"]
        m, n = spec["nx"] * spec["ny"], spec["scan_points"]
        for preset in PEER_PRESETS:
            jobs.append(fm_job("peers", cname, preset))
        jobs.append(
            {
                "section": "peers",
                "kind": "reference",
                "case_name": cname,
                "case": spec,
                "iterations": p["reference_iterations"],
                "timeout": t,
            }
        )
        for method in PEERS:
            job = {
                "section": "peers",
                "kind": "peer",
                "case_name": cname,
                "case": spec,
                "method": method,
                "overrides": p["peer_caps"].get(method, {}),
                "timeout": t,
                "repeats": p["repeats"],
            }
            reason = dense_skip(method, m, n)
            if reason:
                job.update(skip=reason)
            jobs.append(job)
    # (d) threads, on the paper-sized case.
    for preset in ("default", "paper"):
        for threads in (1, 2):
            jobs.append(fm_job("threads", "paper", preset, threads=threads))
    # (c) sweeps.
    sm = p["sweep_m"]
    for side in sm["sides"]:
        jobs.append(
            fm_job(
                "sweep_m",
                sheet(side, sm["scan"]),
                "default",
                repeats=1,
                params={"iterations": sm["iterations"]},
            )
        )
    sn = p["sweep_n"]
    for scan in sn["scans"]:
        jobs.append(
            fm_job(
                "sweep_n",
                sheet(sn["side"], scan),
                "default",
                repeats=1,
                params={"iterations": sn["iterations"], "k_min": sn["k"], "k_max": sn["k"]},
            )
        )
    # (b) the large case last (longest), with capped peers.
    spec = cases["large"]["spec"]
    m, n = spec["nx"] * spec["ny"], spec["scan_points"]
    # The default, then the same with a larger k-NN slack in the rigid and coarse phases (an
    # option: docs/method.md "Approximate neighbours in the rigid and coarse phases").
    slack = {"knn_slack": LARGE_KNN_SLACK}
    for extra, variant in (({}, None), (slack, f"knn_slack {LARGE_KNN_SLACK}")):
        jobs.append(
            fm_job(
                "large",
                "large",
                "default",
                repeats=1,
                params={"iterations": p["large_iterations"], **extra},
                variant=variant,
                timeout=2 * t,
            )
        )
    for method in PEERS:
        job = {
            "section": "large",
            "kind": "peer",
            "case_name": "large",
            "case": spec,
            "method": method,
            "overrides": p["large_peer_caps"].get(method, {}),
            "timeout": p["large_peer_timeout"],
            "rlimit_gb": LARGE_PEER_RLIMIT_GB,
            "capped": True,
        }
        reason = dense_skip(method, m, n)
        if reason:
            job.update(skip=reason)
        jobs.append(job)
    return jobs


def log(msg: str) -> None:
    print(time.strftime("%H:%M:%S"), msg, flush=True)


def run_name(r: dict[str, Any]) -> str:
    """A FoldMatch run's preset, and its variant when it has one."""
    return r["preset"] + (f", {r['variant']}" if r.get("variant") else "")


def describe(rec: dict[str, Any]) -> str:
    what = rec["kind"] if rec["kind"] != "peer" else rec["method"]
    if rec["kind"] == "foldmatch":
        what += f" {run_name(rec)}" + (f" t={rec['threads']}" if rec.get("threads") else "")
    c = rec["case"]
    return f"[{rec['section']}] {what} on {c['nx']}×{c['ny']}/{c['scan_points']}"
