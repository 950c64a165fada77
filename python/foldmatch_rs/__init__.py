"""FoldMatch: fit a garment template mesh onto a 3D scan.

Implements *FoldMatch: accurate and high fidelity garment fitting onto 3D scans*: scan points
attract template points as an N-body system (the NRG motion model, paper §2), and the template
deforms through regularized per-vertex deformation gradients with a wrinkle-vector field
(paper §3). The Rust core does the work; this module converts inputs, names the parameters and
wraps the results.

Inputs are any ``(n, 3)`` array-like (or ``trimesh.Trimesh`` / ``trimesh.PointCloud``).
C-contiguous float64 arrays are used without a copy; other dtypes or layouts are converted once.
Outputs are NumPy arrays that own memory allocated by Rust. The GIL is released while the core
computes.

Many scans or 4D sequences on a Dask cluster: :mod:`foldmatch_rs.distributed` (the ``dask``
extra; ``import foldmatch_rs`` does not import Dask).

Examples
--------
>>> import foldmatch_rs as fm
>>> case = fm.folded_sheet(nx=21, ny=21)
>>> result = fm.fit(case["template_vertices"], case["faces"], case["scan"], iterations=20)
>>> result.vertices.shape
(441, 3)
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from typing import Any, Callable, Optional

import numpy as np

from . import _foldmatch_rs as _core
from .errors import (
    FitCancelled,
    FoldMatchError,
    InternalError,
    InvalidInputError,
    InvalidParameterError,
    MeshFileError,
    MeshFormatError,
    NumericalError,
    OutOfMemoryError,
    RunSetupError,
)

__version__: str = _core.__version__

if hasattr(os, "register_at_fork"):
    # rayon's thread pool does not survive fork(): a forked child (multiprocessing, Dask)
    # computes in a fresh pool of its own.
    os.register_at_fork(after_in_child=_core._mark_forked)

#: The default fit parameters: the paper's constants with the converging readings of SPEC §2,
#: plus the fidelity options that won on the comparison harness (docs/method.md).
DEFAULT_PARAMS: dict[str, Any] = json.loads(_core.default_params_json("default"))
#: The paper's method as printed (one-way attraction, no rigid/coarse phases), with only the
#: converging readings of SPEC §2: ``fit(..., preset="paper")``.
PAPER_PARAMS: dict[str, Any] = json.loads(_core.default_params_json("paper"))


def _points(x: Any, name: str) -> np.ndarray:
    """An ``(n, 3)`` C-contiguous, aligned float64 view of ``x`` (no copy when it already is
    one; arrays unpickled from a buffer, as Dask delivers them, may be unaligned)."""
    if hasattr(x, "vertices"):  # trimesh.Trimesh / PointCloud
        x = x.vertices
    a = np.asarray(x)
    if a.ndim != 2 or a.shape[1] != 3:
        raise InvalidInputError(f"{name}: expected shape (n, 3), got {a.shape}")
    if a.shape[0] == 0:
        raise InvalidInputError(f"{name}: expected at least one point, got 0 rows")
    if not np.issubdtype(a.dtype, np.number) or np.issubdtype(a.dtype, np.complexfloating):
        raise InvalidInputError(f"{name}: expected a real numeric array, got dtype {a.dtype}")
    return np.require(a, dtype=np.float64, requirements=["C", "A"])


def _faces(f: Any, name: str) -> np.ndarray:
    """An ``(t, 3)`` int64 array of face indices (range-checked by the core)."""
    a = np.asarray(f)
    if a.size == 0:
        return np.zeros((0, 3), dtype=np.int64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise InvalidInputError(f"{name}: expected shape (t, 3) of triangles, got {a.shape}")
    if not np.issubdtype(a.dtype, np.integer):
        if not np.all(np.isfinite(a)) or not np.all(np.equal(np.mod(a, 1), 0)):
            raise InvalidInputError(f"{name}: face indices must be integers")
    return np.require(a, dtype=np.int64, requirements=["C", "A"])


def _split_mesh(mesh: Any, faces: Any, name: str) -> tuple[np.ndarray, Optional[np.ndarray]]:
    if faces is None and hasattr(mesh, "faces"):
        faces = mesh.faces
    v = _points(mesh, name)
    return v, (None if faces is None else _faces(faces, f"{name}_faces"))


def _weights(w: Any, n: int) -> Optional[np.ndarray]:
    """``target_weights`` as a contiguous ``(n,)`` float64 array (the checks of values are the
    core's: finite, non-negative, not all zero)."""
    if w is None:
        return None
    try:
        a = np.ascontiguousarray(w, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise InvalidInputError(f"target_weights: not convertible to float64 ({e})") from None
    if a.ndim != 1:
        raise InvalidInputError(f"target_weights: expected shape ({n},), got {a.shape}")
    return a


def _whole(name: str, value: Any) -> int:
    """An int argument as the core takes it (0 ≤ n < 2⁶⁴): anything else raises
    :class:`InvalidParameterError` naming the argument (not ``OverflowError``)."""
    try:
        n = int(value)
    except (TypeError, ValueError):
        raise InvalidParameterError(
            f"parameter {name} = {value!r}: must be a whole number"
        ) from None
    if not 0 <= n < 2**64:
        raise InvalidParameterError(f"parameter {name} = {n}: must be a whole number in 0..2^64")
    return n


def _params_json(params: dict[str, Any]) -> str:
    # JSON has no NaN or infinity: they go as text ("nan", "inf"), which the core rejects
    # naming the parameter alone.
    given = {
        k: (repr(v) if isinstance(v, float) and not math.isfinite(v) else v)
        for k, v in params.items()
        if v is not None
    }
    return json.dumps(given)


@dataclass
class FitResult:
    """The outcome of :func:`fit`, in the caller's frame and units.

    Attributes
    ----------
    vertices : (M, 3) float
        The fitted template vertices (same order and faces as the template).
    faces : (T, 3) int
        The template faces, unchanged.
    wvf : (M, 3) float
        Per-step wrinkle-vector field of the last iteration (Eq. 7); tends to a constant as
        the fit converges.
    wvf_magnitude : (M,) float
    wvf_accumulated : (M, 3) float
        Wrinkle-vector field of the total motion from the input template to the fit: the one
        that shows the folds (paper Fig. 1), for coloring meshes.
    wvf_accumulated_magnitude : (M,) float
    iterations : int
        Iterations run.
    history : dict of (iterations,) arrays
        ``mean_displacement``, ``max_displacement`` (normalized units: target bounding-box
        diagonals) and ``degenerate_gradients`` per iteration.
    snapshots : list of (int, (M, 3) array)
        Vertex positions every ``snapshot_every`` iterations, when requested.
    params : dict
        Every parameter used.
    diagnostics : dict
        Facts about the run: K, ring size, removed faces, (ω₀Δt)², curvature source, frame.
    """

    vertices: np.ndarray
    faces: np.ndarray
    wvf: np.ndarray
    wvf_magnitude: np.ndarray
    wvf_accumulated: np.ndarray
    wvf_accumulated_magnitude: np.ndarray
    iterations: int
    history: dict[str, np.ndarray]
    snapshots: list[tuple[int, np.ndarray]] = field(default_factory=list)
    params: dict[str, Any] = field(default_factory=dict)
    diagnostics: dict[str, Any] = field(default_factory=dict)

    def to_trimesh(self, accumulated: bool = True) -> Any:
        """The fitted mesh as a ``trimesh.Trimesh`` with the wrinkle-field magnitude as vertex
        colors (viridis) and the field in ``vertex_attributes``."""
        import trimesh  # optional dependency

        mag = self.wvf_accumulated_magnitude if accumulated else self.wvf_magnitude
        mesh = trimesh.Trimesh(self.vertices, self.faces, process=False)
        lo, hi = float(np.min(mag)), float(np.max(mag))
        t = (mag - lo) / (hi - lo) if hi > lo else np.zeros_like(mag)
        mesh.visual.vertex_colors = trimesh.visual.interpolate(t, color_map="viridis")
        mesh.vertex_attributes["wvf"] = self.wvf_accumulated if accumulated else self.wvf
        mesh.vertex_attributes["wvf_magnitude"] = mag
        return mesh


def fit(
    template: Any,
    template_faces: Any = None,
    target: Any = None,
    *,
    target_faces: Any = None,
    target_weights: Any = None,
    preset: str = "default",
    method: Optional[str] = None,
    iterations: Optional[int] = None,
    rings: Optional[int] = None,
    rho: Optional[float] = None,
    k_min: Optional[int] = None,
    k_max: Optional[int] = None,
    gravity: Optional[float] = None,
    softening: Optional[float] = None,
    damping: Optional[float] = None,
    time_step: Optional[float] = None,
    template_mass: Optional[float] = None,
    target_mass: Optional[float] = None,
    alpha_floor: Optional[float] = None,
    numerator: Optional[str] = None,
    summation: Optional[str] = None,
    damping_mode: Optional[str] = None,
    psi: Optional[float] = None,
    normal_completion: Optional[float] = None,
    regularization: Optional[str] = None,
    rotation_source: Optional[str] = None,
    velocity_sync: Optional[bool] = None,
    normalize: Optional[bool] = None,
    tolerance: Optional[float] = None,
    use_curvature: Optional[bool] = None,
    prealign: Optional[str] = None,
    snapshot_every: Optional[int] = None,
    two_way: Optional[float] = None,
    two_way_trust: Optional[float] = None,
    two_way_rim: Optional[float] = None,
    two_way_pull: Optional[str] = None,
    rigid_fraction: Optional[float] = None,
    coarse_fraction: Optional[float] = None,
    coarse_rings: Optional[int] = None,
    coarse_levels: Optional[int] = None,
    rigid_sample: Optional[int] = None,
    rigid_scan_sample: Optional[int] = None,
    coarse_scan_sample: Optional[int] = None,
    coarse_sample: Optional[int] = None,
    knn_cache: Optional[bool] = None,
    knn_slack: Optional[float] = None,
    matrix_series: Optional[bool] = None,
    rest_rigidity: Optional[float] = None,
    anneal: Optional[float] = None,
    anneal_fraction: Optional[float] = None,
    selection: Optional[str] = None,
    selection_margin: Optional[float] = None,
    selection_at: Optional[float] = None,
    callback: Optional[Callable[[dict[str, Any]], Optional[bool]]] = None,
    threads: Optional[int] = None,
) -> FitResult:
    """Fit a template mesh onto a target scan (FoldMatch, paper §2–3).

    Parameters
    ----------
    template : (M, 3) float or trimesh.Trimesh
        Template vertices (or a mesh, whose faces are then used).
    template_faces : (T, 3) int, optional
        Template triangles (required unless ``template`` is a mesh).
    target : (N, 3) float or trimesh.Trimesh / trimesh.PointCloud
        The scan.
    target_faces : (F, 3) int, optional
        Scan triangles, when the scan is a mesh (only used for its Gaussian curvature).
    target_weights : (N,) float, optional
        A non-negative weight per scan point (a segmenter's mask or confidence, a scanner's
        quality): each point's pull is scaled by its weight; 0 removes the point (a 0/1 mask
        fits exactly as the masked scan). Wrong length, negative, NaN or all-zero weights raise
        :class:`InvalidParameterError`.
    preset : {"default", "accurate", "fast", "paper", "tracking"}
        Where unset parameters come from: ``"default"`` (:data:`DEFAULT_PARAMS`, the most
        accurate configuration for its cost), ``"accurate"`` (the default with 150 iterations
        instead of 100, every phase lengthened in proportion: closer to the truth and to the
        scan on the harness, about 1.3× the time), ``"fast"`` (one schedule instead of the
        default's two: ``selection="single"``, ``two_way=3``, ``coarse_fraction=0.3``,
        constant softening; about 0.6× the time, with f_R about 15 % higher on the harness
        and 4–22 % held out), ``"paper"`` (:data:`PAPER_PARAMS`, the method as the paper
        describes it) or ``"tracking"`` (the default without softening
        annealing, for a fit warm-started close to its scan, e.g. the previous frame of a
        sequence).
    method : {"foldmatch", "nrga"}
        FoldMatch (default) or the NRGa point-based baseline.
    iterations : int
        ξ, the number of iterations (100).
    rings : int
        n of the n-ring template neighborhoods (2).
    rho, k_min, k_max : float, int, int
        Target neighborhood size ``K = clamp(floor(rho * N), k_min, k_max)`` (0.001, 8, 32;
        the ``"paper"`` preset keeps the paper's rho = 0.002 and SPEC's k_max = 64).
    gravity, softening, damping, time_step, template_mass, target_mass : float
        N-body constants G, ε, η, Δt, m(Y), m(X) (1.67, 0.1, 0.1, 0.006, 1, 1), in the
        normalized frame.
    alpha_floor : float
        Positive floor of the curvature term α of Eq. 2 (0.1).
    numerator : {"centered", "literal"}
        Eq. 2 numerator ``α(Y−X)`` (default) or the printed ``Yα − X``.
    summation : {"mean", "sum"}
        Mean of the K neighbour forces (default) or their plain sum.
    damping_mode : {"fraction", "force"}
        η as the fraction of velocity removed per step (default) or as the ``−ηv`` force.
    psi : float
        ψ, the wrinkle stretch coefficient (0.05).
    normal_completion : float
        γ, weight of the normal pair that completes Eq. 4 on flat rings (0.3).
    regularization : {"affine_invariant", "log_euclidean", "none"}
        Mean used by Eq. 5.
    rotation_source : {"regularized", "raw"}
        Gradient entering Eq. 8.
    velocity_sync : bool
        Velocities follow the applied motion after each update (True).
    normalize : bool
        Work in the normalized frame: centered on the scan, unit bounding-box diagonal (True).
    tolerance : float
        Stop when an iteration's mean displacement (normalized units) is below this (0: off).
    use_curvature : bool
        Use the curvature term of Eq. 2 (True).
    prealign : {"rigid", "similarity", "none", "centroid"}
        How the template is placed on the scan first (docs/method.md, "Global pre-alignment").
        ``"rigid"`` (default) turns and moves it onto a scan in any orientation and position;
        a template already placed is left as given. ``"similarity"`` also scales it (a scan in
        millimetres against a template in metres, or of another size). A nearly symmetric
        garment (a T-shirt's front and back) may be placed turned 180°: landmarks settle it.
        ``"centroid"`` moves the template's centroid onto the scan's; with ``"none"`` a
        template more than one scan diagonal away raises :class:`InvalidInputError`.
    snapshot_every : int
        Keep the vertex positions every this many iterations (0: none).
    two_way : float
        Weight of the two-way attraction: every scan point also pulls its nearest template
        vertex (4.5; the tracking preset 2.0; 0 is the paper's one-way attraction; FoldMatch
        only).
    two_way_trust : float
        Trust radius of the two-way attraction, a multiple c of the fit's current misfit: a scan
        point pulls its nearest vertex only within ``c * max(median vertex-to-scan distance,
        mean edge length)`` of it, so what the garment cannot explain (skin, hair, another
        garment) does not drag it (4, and ¾ of it on a scan much larger than the template;
        0: every point pulls; docs/method.md "Scans of dressed people").
    two_way_rim : float
        Rim rule, in mean edge lengths: on a scan much larger than the template (a dressed
        body), scan points beyond the template's boundary by more than this pull nothing — the
        skin below a hem or out of a sleeve (1; 0: off).
    two_way_pull : {"coverage", "mean"}
        How the two-way pulls on one vertex combine: ``"coverage"`` (default) sums them and
        scales by M / N, so every scan point pulls with the same weight and a vertex at the
        edge of a scan region no other vertex covers is pulled in proportion to that region;
        ``"mean"`` averages them (the rule before 2026-12-01; the tracking preset).
    rigid_fraction : float
        Rigid phase: this fraction of the iterations comes first and moves the whole template
        rigidly under the N-body forces (0.3; FoldMatch only).
    coarse_fraction, coarse_rings : float, int
        Coarse phase: the next fraction of the iterations moves every vertex by the rigid fit
        of its ``coarse_rings``-ring neighborhood, i.e. piecewise rigidly (0.5, 0). 0 (the
        default): automatic, scaled with the template's resolution, ``clamp(round(8 *
        sqrt(M / 1700)), 8, 12)`` for M template vertices, so that the rigid pieces keep their
        share of the surface on finer meshes; the radius used is in
        ``diagnostics["coarse_rings"]``.
    coarse_levels : int
        Split the coarse phase into this many levels, level ``l`` with radius
        ``max(1, r // 2**l)``, r the coarse radius (1: one radius throughout).
    rigid_sample : int
        Rigid phase on a sample: only every ``rigid_sample``-th template vertex feels the
        N-body and two-way forces, and their one Kabsch fit moves the whole template (1: every
        vertex; 1..=64).
    rigid_scan_sample : int
        Rigid phase on a scan sample: it sees only every ``rigid_scan_sample``-th scan point,
        with ``ceil(K / s)`` neighbours per vertex and the sampled points' two-way pulls (0, the
        default: automatic, a stride only where the scan has more than 8 points per vertex of
        the rigid phase's sample, e.g. 4 for 1M points under 100K vertices; 1: the whole scan;
        0..=64).
    coarse_scan_sample : int
        The same for the coarse phase: every ``coarse_scan_sample``-th scan point, ``ceil(K / s)``
        neighbours (0, the default: automatic, 2 where the scan has at least 8 points per
        vertex of the coarse phase, e.g. 1M points under 100K vertices, else 1; 1: the whole
        scan; 0..=64).
    coarse_sample : int
        Coarse phase on a sample: only every ``coarse_sample``-th vertex feels the forces, and
        every vertex moves by the Kabsch fit of its coarse ring's sampled members (1: every
        vertex; 1..=64; more needs coarse rings of radius ≥ 3 at every level).
    knn_cache : bool
        Re-use earlier k-NN candidates, and the two-way attraction's nearest-vertex queries,
        where that is provably exact (True; with ``knn_slack=0`` the same results as False;
        ``diagnostics["knn_queries"]`` and ``["two_way_queries"]`` count the fresh k-d tree
        queries).
    knn_slack : float
        σ in [0, 1] of the rigid and coarse phases' approximate target neighborhoods: there a
        vertex's cached k-NN candidates are re-used while every neighbour returned is within
        ``(1 + σ)`` × the true K-th nearest distance, which spares the fresh k-d tree queries
        of vertices still far off the scan; the FoldMatch iterations stay exact (0.1, measured
        to leave the harness's accuracy unchanged; 0: exact throughout, as is
        ``knn_cache=False``; docs/performance.md, "Thirteenth round").
    matrix_series : bool
        Evaluate Eq. 5's logarithms/exponentials of near-identity matrices by truncated series
        (True; agrees with the eigen-decomposition path to round-off).
    rest_rigidity : float
        As-rigid-as-possible blending of the FoldMatch iterations, β₀ in [0, 1]: in the j-th of
        the J iterations after the rigid and coarse phases each vertex goes to ``(1 - β)`` × its
        Eq. 8 update ``+ β`` × where the Kabsch fit of its template ring (the rest shape) onto
        the proposed ring puts it, with ``β = β₀ (1 - j / J)``, so the template's edge lengths
        are remembered where the scan does not pin them (0.65; the paper and tracking presets
        0, the paper's update alone; FoldMatch only).
    anneal, anneal_fraction : float, float
        Softening annealing: ε starts at ``anneal × ε`` and decreases linearly to ε over the
        first ``anneal_fraction`` of the iterations (3, 0.6; 1: constant, the paper's reading).
    selection : {"scan_distance", "scan_distance_wide", "single"}
        ``"scan_distance"`` (default) also fits with the *sharp* schedule (two-way 1, coarse
        30 %, constant softening) and returns the fit closer to the scan (mean scan→fit
        distance), a near-tie (``selection_margin``) going to the fit whose edge lengths spread
        least from the template's (twice the work, the runs advancing side by side in
        lockstep, so the callback still sees ξ iterations and a stop applies to all);
        ``"scan_distance_wide"`` adds the *gentle* schedule (⅔ of the two-way weight, softening
        annealed over 80 % of the iterations); ``diagnostics["schedule"]`` says which won
        (``"given"``, ``"sharp"`` or ``"gentle"``)
        and ``diagnostics["candidate_scan_distances"]`` and
        ``diagnostics["candidate_edge_spreads"]`` give every candidate's distance and spread.
        ``"single"`` runs the given schedule only (the paper and tracking presets).
    selection_margin : float
        Schedule selection's near-tie margin, ≥ 0: candidates within ``(1 + margin) ×`` the
        closest one's scan distance are tied and the one whose edge lengths spread least from
        the template's (standard deviation of the log length ratios, 0 for any similarity)
        wins (0.06; 0: the closest fit alone). The given schedule's strong two-way pull
        minimizes the very distance compared, so it wins it narrowly even where its fit slid
        along the scan (docs/method.md "Eighth round").
    selection_at : float
        When schedule selection compares its candidates, as a fraction in (0, 1] of the
        iterations: there the same rule picks one and only it runs on, sparing the others'
        remaining iterations; a case whose choice there is the end's gets the same fit, bit for
        bit (1: at the end; docs/method.md "Twelfth round").
    callback : callable, optional
        Called after every iteration with a dict (``iteration``, ``iterations``,
        ``mean_displacement``, ``max_displacement``); returning ``False`` stops the fit, which
        returns what it has. An exception raised by the callback propagates.
    threads : int, optional
        Number of worker threads (default: all cores; at most 4 per hardware thread). Results
        are bit-identical for any count.

    Returns
    -------
    FitResult

    Raises
    ------
    InvalidInputError
        Empty or wrongly shaped arrays, NaN/Inf, face indices out of range, a far-away template.
    InvalidParameterError
        A parameter out of range (``iterations`` 1..=10⁶, finite reals at most 10⁶, see
        docs/cli.md "Limits"), an unknown option value, or an int that does not fit.
    NumericalError
        The fit diverged.
    KeyboardInterrupt
        Ctrl-C: the fit stops at its next iteration (with or without a callback).
    """
    if target is None:
        raise InvalidInputError("target: missing (pass the scan as the third argument)")
    tv, tf = _split_mesh(template, template_faces, "template_vertices")
    if tf is None:
        raise InvalidInputError("template_faces: missing (pass faces or a trimesh.Trimesh)")
    x, xf = _split_mesh(target, target_faces, "target")
    params = dict(
        method=method, iterations=iterations, rings=rings, rho=rho, k_min=k_min, k_max=k_max,
        gravity=gravity, softening=softening, damping=damping, time_step=time_step,
        template_mass=template_mass, target_mass=target_mass, alpha_floor=alpha_floor,
        numerator=numerator, summation=summation, damping_mode=damping_mode, psi=psi,
        normal_completion=normal_completion, regularization=regularization,
        rotation_source=rotation_source, velocity_sync=velocity_sync, normalize=normalize,
        tolerance=tolerance, use_curvature=use_curvature, prealign=prealign,
        snapshot_every=snapshot_every, two_way=two_way, two_way_trust=two_way_trust, two_way_rim=two_way_rim,
        two_way_pull=two_way_pull,
        rigid_fraction=rigid_fraction,
        coarse_fraction=coarse_fraction, coarse_rings=coarse_rings,
        coarse_levels=coarse_levels, rigid_sample=rigid_sample,
        rigid_scan_sample=rigid_scan_sample, coarse_scan_sample=coarse_scan_sample,
        coarse_sample=coarse_sample,
        rest_rigidity=rest_rigidity, anneal=anneal, anneal_fraction=anneal_fraction,
        selection=selection, selection_margin=selection_margin, selection_at=selection_at,
        knn_cache=knn_cache, knn_slack=knn_slack, matrix_series=matrix_series,
    )
    weights = _weights(target_weights, len(x))
    raw = _core.fit_raw(tv, tf, x, xf, _params_json(params), callback, threads, preset, weights)
    return FitResult(
        vertices=raw["vertices"],
        faces=tf,
        wvf=raw["wvf"],
        wvf_magnitude=raw["wvf_magnitude"],
        wvf_accumulated=raw["wvf_accumulated"],
        wvf_accumulated_magnitude=raw["wvf_accumulated_magnitude"],
        iterations=raw["iterations"],
        history={
            "mean_displacement": raw["mean_displacement"],
            "max_displacement": raw["max_displacement"],
            "degenerate_gradients": raw["degenerate_gradients"],
        },
        snapshots=raw["snapshots"],
        params=json.loads(raw["params_json"]),
        diagnostics=json.loads(raw["diagnostics_json"]),
    )


# ---- the stages, for researchers who recombine them -------------------------------------


def knn(points: Any, queries: Any, k: int, threads: Optional[int] = None) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` nearest ``points`` of every query (k-d tree).

    Returns
    -------
    indices : (Q, k) uint32
        Nearest first.
    squared_distances : (Q, k) float
    """
    return _core.knn_query(_points(points, "points"), _points(queries, "queries"), int(k), threads)


def nbody_step(
    positions: Any, velocities: Any, target: Any, neighbours: Any, curvature: Any, **params: Any
) -> tuple[np.ndarray, np.ndarray]:
    """One N-body step (Eq. 2–3) for template points with K scan ``neighbours`` each.

    Parameters
    ----------
    positions, velocities : (M, 3) float
    target : (N, 3) float
    neighbours : (M, K) int
        Indices into ``target``.
    curvature : (N,) float
        Gaussian curvature κ of every scan point.
    **params
        Any N-body parameter of :func:`fit` (gravity, softening, ...).

    Returns
    -------
    velocities : (M, 3) float
        ``v^{t+Δt}``.
    proposed : (M, 3) float
        ``Y^t + v^{t+Δt} Δt``.
    """
    nb = np.ascontiguousarray(np.asarray(neighbours), dtype=np.int64)
    kappa = np.ascontiguousarray(np.asarray(curvature), dtype=np.float64)
    return _core.nbody_step(
        _points(positions, "positions"), _points(velocities, "velocities"),
        _points(target, "target"), nb, kappa, _params_json(params),
    )


def n_rings(faces: Any, n_vertices: int, rings: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """n-ring neighborhoods Γᵏ_Y as CSR arrays ``(offsets (M+1,), members)``; row k lists
    vertex k first, then the vertices within graph distance ``rings``."""
    return _core.n_rings(
        _faces(faces, "faces"), _whole("n_vertices", n_vertices), _whole("rings", rings)
    )


def gaussian_curvature(points: Any, faces: Any = None) -> np.ndarray:
    """Gaussian curvature κ per point: angle deficit over mixed area for a mesh, a local
    quadric fit for a point cloud. Returns ``(N,)`` float."""
    return _core.gaussian_curvature(
        _points(points, "points"), None if faces is None else _faces(faces, "faces")
    )


def prealign(template_vertices: Any, target: Any, motion: str = "rigid") -> dict[str, Any]:
    """Global pre-alignment of a template onto a scan given in any orientation and position
    (``motion="similarity"``: and scale or units), as ``fit(prealign=...)`` does first
    (docs/method.md, "Global pre-alignment"). Returns ``rotation`` (3, 3), ``scale`` and
    ``translation`` (3,) of ``p ↦ scale · rotation · p + translation`` (template → scan), the
    robust two-sided distances ``identity_score`` (the placement as given) and ``score`` (after),
    and ``searched`` (False: the placement as given was already good and was kept)."""
    if motion not in ("rigid", "similarity"):
        raise InvalidParameterError(
            f"parameter motion = {motion!r}: must be \"rigid\" or \"similarity\""
        )
    return _core.prealign_transform(
        _points(template_vertices, "template_vertices"), _points(target, "target"),
        motion == "similarity",
    )


def deformation_gradients(
    old: Any, new: Any, faces: Any, rings: int = 2, normal_completion: float = 0.3
) -> tuple[np.ndarray, np.ndarray]:
    """Deformation gradients H_k (Eq. 4, with the normal completion) of the motion
    ``old → new``. Returns ``(gradients (M, 3, 3), degenerate (M,) bool)``."""
    return _core.deformation_gradients(
        _points(old, "old"), _points(new, "new"), _faces(faces, "faces"), _whole("rings", rings),
        float(normal_completion),
    )


def regularize(
    gradients: Any, offsets: Any, members: Any, mode: str = "affine_invariant"
) -> tuple[np.ndarray, np.ndarray]:
    """Regularization of the gradients over neighborhoods (Eq. 5 on the stretch part, chordal
    mean of the rotations). Returns ``(rotations (M, 3, 3), stretches (M, 3, 3))``."""
    return _core.regularize_gradients(
        np.ascontiguousarray(gradients, dtype=np.float64),
        np.ascontiguousarray(offsets, dtype=np.int64),
        np.ascontiguousarray(members, dtype=np.int64),
        mode,
    )


def polar_decomposition(matrices: Any) -> tuple[np.ndarray, np.ndarray]:
    """Polar decomposition ``H = R U`` (R a proper rotation, U symmetric positive) of every
    ``(3, 3)`` matrix. Returns ``(rotations, stretches)``."""
    return _core.polar_decomposition(np.ascontiguousarray(matrices, dtype=np.float64))


def wrinkle_field(stretches: Any, psi: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """ψ-modified stretch tensors Û and wrinkle vectors ``λ̂1 e1`` (Eq. 6–7).
    Returns ``(modified_stretches (M, 3, 3), wvf (M, 3))``."""
    return _core.wrinkle_field(np.ascontiguousarray(stretches, dtype=np.float64), float(psi))


def solve_rotations(gradients: Any, modified_stretches: Any) -> np.ndarray:
    """Eq. 8: ``argmin_R ||H − R Û||_F`` over rotations, for every vertex. Returns (M, 3, 3)."""
    return _core.solve_rotations(
        np.ascontiguousarray(gradients, dtype=np.float64),
        np.ascontiguousarray(modified_stretches, dtype=np.float64),
    )


def foldmatch_update(old: Any, proposed: Any, faces: Any, **params: Any) -> tuple[np.ndarray, np.ndarray]:
    """One FoldMatch deformation update (Eq. 4–8 and ``Y ← R* Y + t*``) of the motion from
    ``old`` to the N-body ``proposed`` positions. Returns ``(new positions, per-step wvf)``."""
    return _core.foldmatch_update(
        _points(old, "old"), _points(proposed, "proposed"), _faces(faces, "faces"),
        _params_json(params),
    )


def evaluate(
    template: Any,
    template_faces: Any,
    fitted: Any,
    target: Any,
    ground_truth: Any = None,
    *,
    tau_s: float = 0.02,
    tau_e: float = 2.0,
) -> dict[str, Any]:
    """The paper's evaluation metrics (§4, SPEC §3) of a fit.

    Parameters
    ----------
    template : (M, 3) float or trimesh.Trimesh
        The template before fitting (Y).
    template_faces : (T, 3) int
    fitted : (M, 3) float or FitResult
        The fitted vertices (Ŷ).
    target : (N, 3) float
        The scan (X).
    ground_truth : (M, 3) float, optional
        True positions of the template vertices, when known.
    tau_s, tau_e : float
        Area-ratio thresholds of f_S (collapse) and f_E (expansion).

    Returns
    -------
    dict
        ``f_H`` (Hausdorff ratio after/before), ``f_S``, ``f_E``, ``f_F`` (fractions of
        collapsed, expanded, flipped faces), ``f_R`` (ground-truth RMSE / target diagonal, or
        None), ``f_lambda`` (mean of the available terms, named in ``f_lambda_terms``),
        ``chamfer``, ``scan_to_fit_mean``, ``scan_to_fit_p95``, ``fit_to_scan_mean``,
        ``hausdorff_before``, ``hausdorff_after``, ``rmse``, ``target_diagonal`` and face counts.
    """
    return _core.evaluate(
        _points(template, "template_vertices"),
        _faces(template_faces, "template_faces"),
        _points(fitted, "fitted_vertices"),
        _points(target, "target"),
        None if ground_truth is None else _points(ground_truth, "ground_truth"),
        float(tau_s),
        float(tau_e),
    )


def folded_sheet(**spec: Any) -> dict[str, np.ndarray]:
    """A generated case with ground truth: a flat sheet template (``template_vertices``,
    ``faces``), the same sheet folded, rotated and offset (``ground_truth``, same vertex
    order), and a ``scan`` of it (the folded vertices, or ``scan_points`` surface samples with
    ``noise``). Keyword arguments: nx, ny, width, height, fold_amplitude, folds,
    rotation_degrees, offset, scan_points, noise, seed. Sizes are bounded (nx, ny ≤ 10,000,
    nx·ny ≤ 10⁷, scan_points ≤ 10⁷): larger ones raise :class:`InvalidParameterError`."""
    for name in ("nx", "ny", "scan_points", "seed"):
        if name in spec:
            spec[name] = _whole(name, spec[name])
    return _core.folded_sheet(**spec)


__all__ = [
    "DEFAULT_PARAMS",
    "PAPER_PARAMS",
    "FitResult",
    "fit",
    "knn",
    "nbody_step",
    "n_rings",
    "gaussian_curvature",
    "prealign",
    "deformation_gradients",
    "regularize",
    "polar_decomposition",
    "wrinkle_field",
    "solve_rotations",
    "foldmatch_update",
    "folded_sheet",
    "evaluate",
    "FoldMatchError",
    "InvalidInputError",
    "InvalidParameterError",
    "MeshFileError",
    "RunSetupError",
    "MeshFormatError",
    "NumericalError",
    "FitCancelled",
    "OutOfMemoryError",
    "InternalError",
]
