"""The tracking benchmark: the DiffCloth wind T-shirt sequences as noisy scans (issue 28).

Each frame of ``../shared/data/diffcloth/tshirt1000_wind_sim/<sequence>`` (``iter0``: frames
0, 10, …, 250; ``iter17``: frames 0, 50, …, 250, another wind) becomes a scan as the harness's
real ``-pts`` cases do (:data:`bench.cases.REAL_POINTS` area-uniform samples, isotropic
Gaussian noise σ = :data:`bench.cases.REAL_NOISE` of the frame's diagonal, a fixed seed per
frame); the template is frame 0's own mesh, and every frame's mesh is its ground truth (all
frames share the template's faces). :func:`foldmatch_rs.track` fits the scans in order.

Printed per frame: f_R (RMS to the truth ÷ the scan's diagonal, in %), the 95th percentile of
the edge-length ratios ``max(ℓ/ℓ⁰, ℓ⁰/ℓ)`` to the template of the fit and of the truth, whether
the frame was flagged, and its time; then the summary against issue 28's targets: frame 0's
f_R ≤ 0.4 %, no frame above 1 %, every frame's edge p95 within 1.15× the truth's, the mean
time per frame ≤ the default's single fit — the alternative that tracking replaces: every frame
fitted on its own from the template by ``fm.fit``'s default, timed in the same run (its f_R is
printed too; frame 0's single fit alone, which starts on its own truth and so refreshes almost
no correspondence, is printed for reference).

``--scans mesh`` (simulated sequences) gives every frame as a scanner's mesh instead of a point
cloud: the same number of area-uniform samples, triangulated in the cloth's flat rest chart
(so the scan ends where its samples end, inside the true rim by up to a spacing, as a
scanner's mesh does), then the same noise. A mesh frame's boundary places the fit's rim
(docs/method.md "Rim matching"), which a point cloud has not.

``--mode chained`` runs what ``foldmatch sequence`` did before tracking: each frame fitted by
``fm.fit`` with the previous fit as its template (no rest shape, no flags).

``--sequence sim-flag`` runs a simulated sequence of bench/sim_sequence.py (a flag in gusty
wind, Newton's cloth solver, 24 frames at 30 Hz; its first frame's mesh the template);
``sim-flag2`` the flag in another wind, ``sim-drape`` a sheet landing and folding on a sphere.

Tune on ``iter0``; ``iter17`` and the simulated sequences are held out.

    python -m bench.tracking                      # iter0, every frame
    python -m bench.tracking --sequence iter17    # the held-out sequence
    python -m bench.tracking --sequence sim-flag  # the simulated held-out sequence
    python -m bench.tracking --every 5            # frames 0, 50, ..., 250 of iter0
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

import numpy as np

from .cases import (
    REAL_NOISE,
    REAL_POINTS,
    SHARED_DATA,
    at_draws,
    bbox_diagonal,
    load_mesh,
    sample_surface,
    surface_draws,
)

WIND = SHARED_DATA / "diffcloth" / "tshirt1000_wind_sim"
#: The simulated sequence with per-frame truth (bench/sim_sequence.py: a flag in gusty wind).
SIM_SEQUENCE = "sim-flag"
#: Every sequence of the benchmark.
SEQUENCES = ["iter0", "iter17", "sim-flag", "sim-flag2", "sim-drape"]

#: Issue 28's tracking targets.
FIRST_FRAME_MAX = 0.4
ANY_FRAME_MAX = 1.0
EDGE_RATIO_MAX = 1.15


def frames_of(
    sequence: str, every: int = 1, limit: int | None = None
) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """(frame number, vertices, faces) of the sequence's frames in order, every ``every``-th."""
    if sequence.startswith("sim-"):
        from . import sim_sequence

        return sim_sequence.frames(sequence)[::every][:limit]
    files = sorted(WIND.joinpath(sequence).glob("*.obj"), key=lambda p: int(p.stem))
    files = files[::every][:limit]
    return [(int(p.stem), *load_mesh(p)) for p in files]


def noisy_scan(vertices: np.ndarray, faces: np.ndarray, seed: int) -> np.ndarray:
    """The harness's real ``-pts`` scan of a mesh: resampled points, isotropic noise."""
    rng = np.random.default_rng(seed)
    pts = sample_surface(vertices, faces, REAL_POINTS, rng)
    return pts + rng.normal(scale=REAL_NOISE * bbox_diagonal(vertices), size=pts.shape)


def scanner_mesh(
    vertices: np.ndarray, faces: np.ndarray, chart: np.ndarray, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """A scanner's mesh of a sheet (``--scans mesh``): the harness's ``-pts`` samples, each also
    placed in ``chart`` (the sheet's flat rest coordinates, (M, 2)) by its barycentric
    coordinates, Delaunay-triangulated there (the hull's slivers, longer than four sample
    spacings, dropped), then the same noise; (points, triangles)."""
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(seed)
    # The same draws as noisy_scan's: its very points.
    draws = surface_draws(vertices, faces, REAL_POINTS, rng)
    points, flat = at_draws(vertices, faces, draws), at_draws(chart, faces, draws)
    triangles = Delaunay(flat).simplices
    longest = np.linalg.norm(flat[triangles] - flat[np.roll(triangles, 1, axis=1)], axis=2).max(axis=1)
    spacing = np.sqrt(np.prod(np.ptp(flat, axis=0)) / REAL_POINTS)
    triangles = triangles[longest < 4 * spacing]
    points = points + rng.normal(scale=REAL_NOISE * bbox_diagonal(vertices), size=points.shape)
    return points, triangles.astype(np.int64)


def edge_index(faces: np.ndarray) -> np.ndarray:
    """The mesh's undirected edges, once each."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    return np.unique(np.sort(e, axis=1), axis=0)


def edge_ratio_p95(vertices: np.ndarray, rest: np.ndarray, edges: np.ndarray) -> float:
    """95th percentile over edges of max(ℓ/ℓ⁰, ℓ⁰/ℓ) against the rest shape."""
    length = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
    rest_length = np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)
    ratio = length / np.maximum(rest_length, 1e-300)
    return float(np.percentile(np.maximum(ratio, 1.0 / np.maximum(ratio, 1e-300)), 95))


def f_r(fitted: np.ndarray, truth: np.ndarray, scan: np.ndarray) -> float:
    """RMS distance to the truth ÷ the scan's bounding-box diagonal."""
    return float(np.sqrt(np.mean(np.sum((fitted - truth) ** 2, axis=1))) / bbox_diagonal(scan))


def run(args: argparse.Namespace) -> dict[str, Any]:
    import foldmatch_rs as fm

    frames = frames_of(args.sequence, args.every, args.limit)
    template, faces = frames[0][1], frames[0][2]
    edges = edge_index(faces)
    scan_faces: list[np.ndarray | None] = [None] * len(frames)
    if args.scans == "mesh":
        if not args.sequence.startswith("sim-"):
            raise SystemExit("--scans mesh: only the simulated sequences have a flat rest chart")
        from . import sim_sequence

        chart = sim_sequence.chart(args.sequence)
        meshes = [scanner_mesh(v, f, chart, seed=1000 + number) for number, v, f in frames]
        scans, scan_faces = [m[0] for m in meshes], [m[1] for m in meshes]
    else:
        scans = [noisy_scan(v, f, seed=1000 + number) for number, v, f in frames]
    settings = dict(kv.split("=", 1) for kv in args.set)
    params = {k: json.loads(v) for k, v in settings.items()}

    # The alternative to tracking: the default's single fit of every frame from the template.
    single_times, single_frs = [], []
    for (_, truth, _), scan, scan_f in zip(frames, scans, scan_faces):
        started = time.perf_counter()
        single = fm.fit(template, faces, scan, target_faces=scan_f, threads=args.threads)
        single_times.append(time.perf_counter() - started)
        single_frs.append(100 * f_r(single.vertices, truth, scan))
    single_seconds = float(np.mean(single_times))

    rows = []
    if args.mode == "track":
        import trimesh

        given = [
            scan if scan_f is None else trimesh.Trimesh(scan, scan_f, process=False)
            for scan, scan_f in zip(scans, scan_faces)
        ]
        stream = fm.track(
            template,
            faces,
            given,
            preset=args.preset,
            iterations=args.iterations,
            params=params or None,
            prediction=args.prediction,
            reanchor=args.reanchor,
            threads=args.threads,
        )
    else:
        stream = chained(fm, template, faces, list(zip(scans, scan_faces)), args, params)
    clock = time.perf_counter()
    for (number, truth, _), scan, result in zip(frames, scans, stream):
        now = time.perf_counter()
        seconds, clock = now - clock, now
        tracking = result.tracking
        rows.append(
            {
                "frame": number,
                "f_R_pct": 100 * f_r(result.vertices, truth, scan),
                "edge_p95": edge_ratio_p95(result.vertices, template, edges),
                "truth_edge_p95": edge_ratio_p95(truth, template, edges),
                "flagged": bool(tracking.get("flagged", False)),
                "reanchored": bool(tracking.get("reanchored", False)),
                "verdict": result.quality.get("verdict"),
                "seconds": seconds,
            }
        )
        r = rows[-1]
        print(
            f"  frame {number:>3}  f_R {r['f_R_pct']:6.3f} %  edge p95 {r['edge_p95']:.3f} "
            f"(truth {r['truth_edge_p95']:.3f}, ×{r['edge_p95'] / r['truth_edge_p95']:.3f})  "
            f"{r['verdict']:10s}{' re-anchored' if r['reanchored'] else ''}  {seconds:5.2f} s",
            flush=True,
        )
    per_frame = float(np.mean([r["seconds"] for r in rows]))
    summary = {
        "sequence": args.sequence,
        "scans": args.scans,
        "frames": [r["frame"] for r in rows],
        "mode": args.mode,
        "first_f_R_pct": rows[0]["f_R_pct"],
        "max_f_R_pct": max(r["f_R_pct"] for r in rows),
        "mean_f_R_pct": float(np.mean([r["f_R_pct"] for r in rows])),
        "max_edge_over_truth": max(r["edge_p95"] / r["truth_edge_p95"] for r in rows),
        "flagged": sum(r["flagged"] for r in rows),
        "seconds_per_frame": per_frame,
        "default_single_fit_seconds": single_seconds,
        "default_single_fit_frame0_seconds": single_times[0],
        "default_single_fit_max_f_R_pct": max(single_frs),
        "default_single_fit_mean_f_R_pct": float(np.mean(single_frs)),
    }
    checks = [
        (
            f"frame 0's f_R ≤ {FIRST_FRAME_MAX} %",
            summary["first_f_R_pct"],
            summary["first_f_R_pct"] <= FIRST_FRAME_MAX,
        ),
        (
            f"no frame's f_R > {ANY_FRAME_MAX} %",
            summary["max_f_R_pct"],
            summary["max_f_R_pct"] <= ANY_FRAME_MAX,
        ),
        (
            f"edge p95 ≤ {EDGE_RATIO_MAX}× the truth's",
            summary["max_edge_over_truth"],
            summary["max_edge_over_truth"] <= EDGE_RATIO_MAX,
        ),
        (
            "time per frame ≤ the default's single fit",
            per_frame / single_seconds,
            per_frame <= single_seconds,
        ),
    ]
    print(
        f"{args.sequence} ({len(rows)} frames, {args.mode}): mean f_R {summary['mean_f_R_pct']:.3f} %, "
        f"{summary['flagged']} flagged; {per_frame:.3f} s per frame\n"
        f"the default's single fit of every frame from the template: {single_seconds:.3f} s per frame "
        f"(frame 0, which starts on its own truth: {single_times[0]:.3f} s), max f_R "
        f"{summary['default_single_fit_max_f_R_pct']:.3f} %, "
        f"mean {summary['default_single_fit_mean_f_R_pct']:.3f} %"
    )
    for label, value, met in checks:
        print(f"  {'met ' if met else 'MISS'} {label}: {value:.3f}")
    summary["met"] = {label: met for label, _, met in checks}
    return summary


def chained(
    fm: Any,
    template: np.ndarray,
    faces: np.ndarray,
    scans: list[tuple[np.ndarray, np.ndarray | None]],
    args: argparse.Namespace,
    params: dict[str, Any],
) -> Any:
    """Each frame (points, faces or None) fitted with the previous fit as its template (no
    rest shape)."""
    previous = template
    for scan, scan_faces in scans:
        result = fm.fit(
            previous,
            faces,
            scan,
            target_faces=scan_faces,
            preset=args.preset,
            iterations=args.iterations,
            params=params or None,
            threads=args.threads,
        )
        previous = result.vertices
        yield result


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sequence", default="iter0", choices=SEQUENCES)
    ap.add_argument("--every", type=int, default=1, help="every k-th frame of the sequence (default 1)")
    ap.add_argument("--limit", type=int, default=None, help="at most this many frames")
    ap.add_argument(
        "--scans",
        default="points",
        choices=["points", "mesh"],
        help="the frames as noisy point clouds (default) or as a scanner's meshes (simulated sequences)",
    )
    ap.add_argument("--mode", default="track", choices=["track", "chained"])
    ap.add_argument("--preset", default="tracking")
    ap.add_argument("--iterations", type=int, default=None)
    ap.add_argument(
        "--prediction", type=float, default=0.0, help="λ of the start's prediction (default 0, as fm.track)"
    )
    ap.add_argument("--reanchor", action="store_true", help="re-anchor flagged frames")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=JSON", help="a fit setting")
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--json", help="write the summary here")
    args = ap.parse_args(argv)
    summary = run(args)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(summary, f, indent=1)


if __name__ == "__main__":
    main()
