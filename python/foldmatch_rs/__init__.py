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

import os
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, Callable, Optional, Union

import numpy as np

from . import _foldmatch_rs as _core
from . import _inputs, _progress
from ._inputs import faces as _faces
from ._inputs import points as _points
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
from .params import FitParams

__version__: str = _core.__version__

if hasattr(os, "register_at_fork"):
    # rayon's thread pool does not survive fork(): a forked child (multiprocessing, Dask)
    # computes in a fresh pool of its own.
    os.register_at_fork(after_in_child=_core._mark_forked)

#: The settings of the ``"default"`` preset, by name (``FitParams("default").to_dict()``).
DEFAULT_PARAMS: dict[str, Any] = FitParams("default").to_dict()
#: The settings of the ``"paper"`` preset, the paper's method as printed.
PAPER_PARAMS: dict[str, Any] = FitParams("paper").to_dict()


def _whole(name: str, value: Any) -> int:
    """An int argument as the core takes it (0 ≤ n < 2⁶⁴): anything else raises
    :class:`InvalidParameterError` naming the argument (not ``OverflowError``)."""
    try:
        n = int(value)
    except (TypeError, ValueError):
        raise InvalidParameterError(f"parameter {name} = {value!r}: must be a whole number") from None
    if not 0 <= n < 2**64:
        raise InvalidParameterError(f"parameter {name} = {n}: must be a whole number in 0..2^64")
    return n


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
    params : FitParams
        Every setting used.
    diagnostics : dict
        Facts about the run: K, ring size, removed faces, (ω₀Δt)², curvature source, frame;
        ``prealign`` (what the global pre-alignment found) and ``coherent`` (the coherent
        candidate, when it ran: ``kept``, both fits' ``fit_to_scan`` and ``scan_to_fit``,
        docs/method.md "Coherent candidate").
    quality : dict
        Does the fit look right: ``verdict`` (``"ok"`` or ``"suspicious"``), ``reasons`` and
        the figures behind them, none of which needs ground truth (see :func:`assess`; the
        fit's own ``fit_to_scan`` leaves out the vertices it carried without support, and
        ``carried_share``, their share of the vertices, is counted in ``unsupported_share`` but
        left out of the verdict's test of it).
    correspondences : (M,) uint32
        Per template vertex, the index of the scan point it ends nearest to.
    residuals : (M,) float
        Per template vertex, the distance to that scan point (the scan's units).
    support : (M,) bool
        Per template vertex, whether it has scan support: its nearest scan point lies within
        the support radius and is claimed back by the vertex or a template neighbour, and the
        fit did not carry it as unseen (a one-sided scan's back, docs/guide.md).
    garment_points : (P,) uint32
        On a scan that holds more than the garment (a dressed body), the fit's own
        segmentation: the indices, into the scan as given and increasing, of the points it took
        for the garment and was last fitted to (docs/dressed.md). Empty when the fit ran on the
        whole scan (a garment-only scan).
    tracking : dict
        :func:`track` only, the frame's figures: ``frame``, ``fit_to_scan``, ``scan_to_fit``,
        ``edge_distortion`` (against the template), ``motion``, ``warm_started``,
        ``reanchored``, ``flagged`` and ``reasons`` (empty for :func:`fit`).
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
    params: FitParams = field(default_factory=FitParams)
    diagnostics: dict[str, Any] = field(default_factory=dict)
    quality: dict[str, Any] = field(default_factory=dict)
    correspondences: np.ndarray = field(default_factory=lambda: np.zeros(0, np.uint32))
    residuals: np.ndarray = field(default_factory=lambda: np.zeros(0))
    support: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    garment_points: np.ndarray = field(default_factory=lambda: np.zeros(0, np.uint32))
    tracking: dict[str, Any] = field(default_factory=dict)

    def save(self, path: str | os.PathLike[str], accumulated: bool = True, ascii: bool = False) -> None:
        """Writes the fitted mesh as ``foldmatch fit`` does, with the same Rust writer (byte for
        byte the same file for the same vertices and field): ``.ply`` with vertex colors (the
        wrinkle-field magnitude, viridis over its 2nd–98th percentiles) and the properties
        ``wvf_x``, ``wvf_y``, ``wvf_z``, ``wvf_magnitude``; ``.obj`` with the colors only.
        Written atomically."""
        _core.write_fitted(
            os.fspath(path),
            _points(self.vertices, "vertices"),
            _faces(self.faces, "faces"),
            _points(self.wvf_accumulated if accumulated else self.wvf, "field"),
            ascii,
        )

    def __repr__(self) -> str:
        """A line: the sizes, iterations, the schedule that won and the last step."""
        steps = self.history.get("mean_displacement", ())
        last = f", last_step={float(steps[-1]):.2e}" if len(steps) else ""
        schedule = self.diagnostics.get("schedule")
        chosen = f", schedule={schedule!r}" if schedule else ""
        return (
            f"FitResult(vertices={self.vertices.shape}, faces={self.faces.shape}, "
            f"iterations={self.iterations}{chosen}{last}, params={self.params!r})"
        )

    def to_trimesh(self, accumulated: bool = True) -> Any:
        """The fitted mesh as a ``trimesh.Trimesh`` with the colors and vertex attributes of
        :meth:`save` (the CLI's layout): vertex colors from the wrinkle-field magnitude with
        the CLI's scale (the same Rust code) and the attributes ``wvf_x``, ``wvf_y``, ``wvf_z``,
        ``wvf_magnitude``, which ``export("fitted.ply")`` writes as PLY properties of those
        names in that order. trimesh's PLY exporter itself writes ``float`` coordinates and an
        ``alpha`` column; :meth:`save` writes the CLI's file exactly."""
        import trimesh  # optional dependency

        wvf = self.wvf_accumulated if accumulated else self.wvf
        mag = self.wvf_accumulated_magnitude if accumulated else self.wvf_magnitude
        mesh = trimesh.Trimesh(self.vertices, self.faces, process=False)
        colors, _ = _core.wrinkle_colors(np.ascontiguousarray(mag, dtype=np.float64))
        mesh.visual.vertex_colors = np.column_stack([colors, np.full(len(colors), 255, np.uint8)])
        for axis, name in enumerate(("wvf_x", "wvf_y", "wvf_z")):
            mesh.vertex_attributes[name] = np.ascontiguousarray(wvf[:, axis])
        mesh.vertex_attributes["wvf_magnitude"] = mag
        return mesh

    def preview(
        self,
        path: Optional[str | os.PathLike[str]] = None,
        scan: Any = None,
        *,
        size: int = 320,
        views: tuple[str, ...] = ("front", "three-quarter", "back"),
    ) -> np.ndarray:
        """A picture of the fit, as ``foldmatch fit --preview`` draws it: see :func:`render`.

        The mesh is colored by ``wvf_accumulated``; give the ``scan`` (points or a trimesh
        object) to add the scan row and the distance-to-scan row. Returns the
        ``(H, W, 3)`` uint8 image and writes it as a PNG when ``path`` is given."""
        return render(
            self.vertices,
            self.faces,
            scan=scan,
            field=self.wvf_accumulated,
            path=path,
            size=size,
            views=views,
        )


def render(
    vertices: Any,
    faces: Any,
    scan: Any = None,
    field: Any = None,
    path: Optional[str | os.PathLike[str]] = None,
    *,
    scan_faces: Any = None,
    size: int = 320,
    views: tuple[str, ...] = ("front", "three-quarter", "back"),
) -> np.ndarray:
    """Draws a mesh without a display, as ``foldmatch fit --preview`` does (same Rust code).

    One column per view (``"front"``, ``"three-quarter"``, ``"side"``, ``"back"``: turns about
    +y, the camera on +z) and one row per layer: the scan (gray points, or its mesh), the mesh
    colored by the wrinkle-field magnitude (viridis over its 2nd–98th percentiles, the colors
    of the fitted PLY), and the mesh colored by each vertex's distance to the nearest scan
    point (yellow to dark red over [0, 98th percentile]), with a color bar per colored row.
    Without a scan only the mesh row is drawn; without a field the mesh is gray.

    Parameters
    ----------
    vertices : (M, 3) float
    faces : (T, 3) int
    scan : (N, 3) float or trimesh object, optional
    field : (M, 3) float or (M,) float, optional
        A wrinkle-vector field (its magnitude is drawn) or per-vertex magnitudes.
    path : str or path-like, optional
        Also write the image there as a PNG (atomically).
    scan_faces : (S, 3) int, optional
        The scan's triangles (taken from a trimesh mesh given as ``scan``).
    size : int
        Edge of one square panel in pixels (16 to 4096).
    views : tuple of str
        One to four views.

    Returns
    -------
    (H, W, 3) uint8
        ``W = len(views)·size + 96`` (the color-bar column), ``H = rows·size``.
    """
    vertices = _points(vertices, "vertices")
    faces_array = _faces(faces, "faces")
    scan_points = None
    if scan is not None:
        scan_points, scan_faces = _inputs.mesh(scan, scan_faces, "scan")
    elif scan_faces is not None:
        raise InvalidInputError("scan_faces: given without a scan")
    magnitude = None
    if field is not None:
        field = np.ascontiguousarray(field, dtype=np.float64)
        if field.ndim == 1:
            magnitude, field = field, None
    if isinstance(views, str):
        views = (views,)
    return _core.render_preview(
        vertices,
        faces_array,
        scan=scan_points,
        scan_faces=scan_faces,
        field=field,
        magnitude=magnitude,
        path=None if path is None else os.fspath(path),
        panel=_whole("size", size),
        views=list(views),
    )


def fit(
    template: Any,
    template_faces: Any = None,
    target: Any = None,
    *,
    target_faces: Any = None,
    target_weights: Any = None,
    target_normals: Any = None,
    landmarks: Any = None,
    preset: Optional[str] = None,
    iterations: Optional[int] = None,
    rings: Optional[int] = None,
    psi: Optional[float] = None,
    prealign: Optional[str] = None,
    params: Union[FitParams, dict[str, Any], None] = None,
    callback: Optional[Callable[[dict[str, Any]], Optional[bool]]] = None,
    progress: Optional[bool] = None,
    threads: Optional[int] = None,
) -> FitResult:
    """Fit a template mesh onto a target scan (FoldMatch, paper §2–3).

    Parameters
    ----------
    template : (M, 3) float, a mesh object, or a path
        Template vertices; or a ``trimesh.Trimesh`` / Open3D ``TriangleMesh`` or a ``.ply`` /
        ``.obj`` file (read by the same readers as the ``foldmatch`` command), whose faces are
        then used.
    template_faces : (T, 3) int, optional
        Template triangles (required unless ``template`` is a mesh or a mesh file).
    target : (N, 3) float, a mesh or point cloud object, or a path
        The scan: points, a ``trimesh`` or Open3D mesh or point cloud, or a ``.ply`` / ``.obj``
        file.
    target_faces : (F, 3) int, optional
        Scan triangles, when the scan is a mesh (only used for its Gaussian curvature).
    target_weights : (N,) float, str or path, optional
        A non-negative weight per scan point (a segmenter's mask or confidence, a scanner's
        quality): each point's pull is scaled by its weight; 0 removes the point (a 0/1 mask
        fits exactly as the masked scan). A ``.npy`` path is read; another string names a
        vertex property of the target's PLY file (``"confidence"``). Wrong length, negative,
        NaN or all-zero weights raise :class:`InvalidParameterError`.
    target_normals : (N, 3) float or True, optional
        The scan's own normals, as a scanner writes them (their length and sign do not matter);
        ``True`` takes the target's: a ``.ply`` path's ``nx ny nz``, an Open3D point cloud's
        ``normals``. They are the planes of the final isometric refinement's fit → scan term,
        in place of the plane of each point's 12 nearest scan points (docs/guide.md "Scan
        normals"; the ``"tracking"`` preset uses the fit's own normals and ignores them). A
        wrong count, a non-finite or zero normal raise :class:`InvalidInputError` /
        :class:`InvalidParameterError`.
    landmarks : tuple of (L,) int and (L, 3) float, optional
        ``(template_vertex_indices, target_positions)``: template vertices whose positions on
        the scan are known (clicked, detected, marked). They decide the pre-alignment (three or
        more: the rigid fit of those vertices onto their targets moves the template first, in
        place of ``prealign``; one or two: they choose among the search's placements the one
        that puts them nearest, e.g. which side of a T-shirt is the front) and pull their
        vertices toward the targets while the fit deforms (its
        first, rigid part follows the scan alone), as hard as the setting ``landmark_weight``
        says (``params={"landmark_weight": 3}``;
        default 1; docs/guide.md "Landmarks"). An index out of range or repeated, or a
        non-finite position, raises :class:`InvalidInputError` naming the landmark.
    preset : {"default", "accurate", "fast", "paper", "tracking"}, optional
        Where the settings not given come from (default ``"default"``): ``"default"``, the most
        accurate configuration for its cost; ``"accurate"``, the default with 150 iterations
        instead of 80 (closer to the truth and to the scan, about 1.5× the time); ``"fast"``,
        one schedule instead of the default's two and no isometric refinement (about 0.7× the
        time, less accurate);
        ``"paper"``, the method as the paper describes it; ``"tracking"``, for a fit
        warm-started close to its scan (the previous frame of a sequence). Not with a
        :class:`FitParams` ``params``, which carries its own preset.
    iterations : int, optional
        ξ, the number of iterations (80, then 30 steps of isometric refinement; ``"accurate"``
        150; ``"fast"`` and ``"paper"`` 100).
    rings : int, optional
        n of the n-ring template neighborhoods (2).
    psi : float, optional
        ψ, the wrinkle stretch coefficient (0.05).
    prealign : {"none", "centroid", "rigid", "similarity"}, optional
        How the template is placed on the scan first (docs/method.md, "Global pre-alignment").
        ``"rigid"`` (the default; the ``"paper"`` and ``"tracking"`` presets: ``"none"``)
        turns and moves it onto a scan in any orientation and position (a template already
        placed is left as given) and raises :class:`InvalidInputError` for a template 20
        times larger or smaller than the scan; ``"similarity"`` also scales it (a scan in
        millimetres against a template in metres); ``"none"`` fits as given and raises
        :class:`InvalidInputError` for a template more than one scan diagonal away;
        ``"centroid"`` moves the template's centroid onto the scan's.
        A nearly symmetric garment (a T-shirt's front and back) may be placed turned 180°:
        landmarks settle it.
    params : FitParams or dict, optional
        Every other setting (docs/parameters.md), e.g. ``{"method": "nrga"}`` for the NRGa
        baseline or ``{"two_way": 2.0}``: a :class:`FitParams`, or a dict of settings by name
        over ``preset``. The keywords above override it.
    callback : callable, optional
        Called after every iteration with a dict (``iteration``, ``iterations``,
        ``mean_displacement``, ``max_displacement``); returning ``False`` stops the fit, which
        returns what it has. An exception raised by the callback propagates.
    progress : bool, optional
        Show a progress bar on stderr (tqdm's when installed). Default: only when stderr is a
        terminal. Works together with ``callback``.
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
        A setting unknown, of the wrong type or out of its range (the message names it and
        its range), or ``preset`` given with a :class:`FitParams`.
    MeshFileError, MeshFormatError
        A mesh file that cannot be read, or is malformed.
    NumericalError
        The fit diverged.
    KeyboardInterrupt
        Ctrl-C: the fit stops at its next iteration (with or without a callback).
    """
    if target is None:
        raise InvalidInputError("target: missing (pass the scan as the third argument)")
    settings = _settings(preset, params, iterations=iterations, rings=rings, psi=psi, prealign=prealign)
    tv, tf = _inputs.mesh(template, template_faces, "template_vertices")
    if tf is None:
        raise InvalidInputError("template_faces: missing (pass faces, a mesh object or a mesh file)")
    x, xf = _inputs.mesh(target, target_faces, "target")
    weights = _inputs.weights(target_weights, len(x), target)
    normals = _inputs.normals(target_normals, len(x), target)
    lm_vertices, lm_positions = _inputs.landmarks(landmarks)
    values = settings.to_dict()
    scan = (weights, lm_vertices, lm_positions, normals)
    if _progress.wanted(progress):
        with _progress.Bar(settings.iterations, callback) as bar:
            raw = _core.fit_raw(tv, tf, x, xf, values, bar, threads, *scan)
    else:
        raw = _core.fit_raw(tv, tf, x, xf, values, callback, threads, *scan)
    return _result(raw, tf, settings)


def _result(raw: dict[str, Any], tf: np.ndarray, settings: FitParams) -> FitResult:
    """A :class:`FitResult` from the core's dict."""
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
        params=FitParams.from_dict(raw["params"], settings.preset_name),
        diagnostics=raw["diagnostics"],
        quality=raw["quality"],
        correspondences=raw["correspondences"],
        residuals=raw["residuals"],
        support=raw["support"],
        garment_points=raw.get("garment_points", np.zeros(0, np.uint32)),
        tracking=raw.get("tracking", {}),
    )


def track(
    template: Any,
    template_faces: Any = None,
    frames: Iterable[Any] = (),
    *,
    preset: Optional[str] = None,
    iterations: Optional[int] = None,
    params: Union[FitParams, dict[str, Any], None] = None,
    prediction: float = 0.0,
    distortion_jump: float = 0.15,
    distance_jump: float = 2.0,
    reanchor: bool = False,
    threads: Optional[int] = None,
) -> Iterator[FitResult]:
    """Track a 4D sequence: fit ``frames`` in order, yielding each frame's :class:`FitResult`.

    Each frame starts from the previous frame's fit (moved on by ``prediction`` times its last
    motion) but stays anchored to ``template``: the rest-shape rigidity and the quality
    verdict refer to the template's shape, not to the previous fit, so errors do not pile up
    from frame to frame (docs/method.md "Tracking"). A frame whose edge distortion or scan
    distances jump against the first frame's is flagged: its ``quality["verdict"]`` is
    ``"suspicious"`` with the reasons, and ``result.tracking["flagged"]`` is true; with
    ``reanchor=True`` it is first fitted again from the template placed rigidly on its fit, and
    the better fit kept. ``foldmatch sequence`` runs the same tracker.

    Parameters
    ----------
    template : (M, 3) float, a mesh object, or a path
        The template; ideally the first frame's own mesh or a fit of it.
    template_faces : (T, 3) int, optional
        Template triangles (required unless ``template`` is a mesh or a mesh file).
    frames : iterable
        The frames in order: ``(N, 3)`` point arrays, mesh or point cloud objects, or
        ``.ply`` / ``.obj`` paths; read one at a time (a generator works).
    preset : str, optional
        The preset of every frame's fit (default ``"tracking"``, see :func:`fit`).
    iterations : int, optional
        ξ per frame (the preset's, 60); a frame whose start lies more than two mean template
        edges from its scan gets proportionally more, at most three times as many.
    params : FitParams or dict, optional
        Other fit settings, as for :func:`fit`.
    prediction : float
        λ in [0, 1] of the constant-velocity start: previous fit + λ × its last motion.
    distortion_jump : float
        Flag a frame whose edge distortion exceeds the first frame's by more than this.
    distance_jump : float
        Flag a frame whose fit→scan or scan→fit distance exceeds this multiple of the first
        frame's.
    reanchor : bool
        Fit a flagged frame again from the template placed rigidly on its fit.
    threads : int, optional
        Worker threads, as for :func:`fit`.

    Yields
    ------
    FitResult
        One per frame, with the template's faces and the frame's figures in ``tracking``.

    Raises
    ------
    InvalidInputError, InvalidParameterError
        A bad template or setting (at the call), or a bad frame (when it is reached; the
        message starts with ``frame <index>:``, and the sequence stops there).
    MeshFileError, MeshFormatError
        A frame file that cannot be read (naming the frame index).
    """
    settings = _settings(
        preset or ("tracking" if not isinstance(params, FitParams) else None), params, iterations=iterations
    )
    tv, tf = _inputs.mesh(template, template_faces, "template_vertices")
    if tf is None:
        raise InvalidInputError("template_faces: missing (pass faces, a mesh object or a mesh file)")
    tracker = _core.Tracker(
        tv,
        tf,
        settings.to_dict(),
        float(prediction),
        float(distortion_jump),
        float(distance_jump),
        bool(reanchor),
    )
    return _frames(tracker, tf, settings, iter(frames), threads)


def _frames(
    tracker: Any, tf: np.ndarray, settings: FitParams, frames: Iterator[Any], threads: Optional[int]
) -> Iterator[FitResult]:
    """The frames of :func:`track`, fitted one by one."""
    for index, frame in enumerate(frames):
        try:
            x, xf = _inputs.mesh(frame, None, "target")
            raw = tracker.step(x, xf, None, threads)
        except FoldMatchError as e:
            raise type(e)(f"frame {index}: {e}") from e
        yield _result(raw, tf, settings)


def _settings(preset: Optional[str], params: Any, **given: Any) -> FitParams:
    """The fit's settings: ``params`` (a :class:`FitParams`, or a dict over ``preset``) with
    the keywords that were given over it."""
    given = {k: v for k, v in given.items() if v is not None}
    if isinstance(params, FitParams):
        if preset is not None:
            raise InvalidParameterError(
                f"parameter preset = {preset!r}: not with params=FitParams(...), which carries "
                f"its preset ({params.preset_name!r}); use FitParams({preset!r}, ...)"
            )
        return params.replace(**given) if given else params
    if params is not None and not isinstance(params, Mapping):
        raise InvalidParameterError(
            f"parameter params = {type(params).__name__}: must be a FitParams or a dict"
        )
    return FitParams(preset or "default", **{**dict(params or {}), **given})


# ---- the stages, for researchers who recombine them -------------------------------------


def _stage_settings(given: dict[str, Any]) -> dict[str, Any]:
    """A stage's settings by name (over the default's), as the core reads them."""
    return FitParams(**given).to_dict()


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
        _points(positions, "positions"),
        _points(velocities, "velocities"),
        _points(target, "target"),
        nb,
        kappa,
        _stage_settings(params),
    )


def n_rings(faces: Any, n_vertices: int, rings: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """n-ring neighborhoods Γᵏ_Y as CSR arrays ``(offsets (M+1,), members)``; row k lists
    vertex k first, then the vertices within graph distance ``rings``."""
    return _core.n_rings(_faces(faces, "faces"), _whole("n_vertices", n_vertices), _whole("rings", rings))


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
    ``searched`` (False: the template lay on a scan larger than the garment, a dressed body,
    and was kept without a search; a template that lies on a garment's scan is searched from
    its own reading and its half turns only, and turned back by a half turn where that halves
    its score, else kept as given) and ``readings``
    (the orientations that fit the scan alike; above 1, a symmetric template's reading was
    chosen by least turn, and landmarks settle it; 0 when nothing was searched). ``fit`` goes
    further when two such readings are other shapes of the template (a garment back to front,
    not a symmetric image): it fits from both and keeps the closer
    (``diagnostics["prealign"]["fitted_readings"] == 2``; ``reading_gap``, how much farther
    the other fit ended, below 0.04: the scan did not tell them apart)."""
    if motion not in ("rigid", "similarity"):
        raise InvalidParameterError(f'parameter motion = {motion!r}: must be "rigid" or "similarity"')
    return _core.prealign_transform(
        _points(template_vertices, "template_vertices"),
        _points(target, "target"),
        motion == "similarity",
    )


def deformation_gradients(
    old: Any, new: Any, faces: Any, rings: int = 2, normal_completion: float = 0.3
) -> tuple[np.ndarray, np.ndarray]:
    """Deformation gradients H_k (Eq. 4, with the normal completion) of the motion
    ``old → new``. Returns ``(gradients (M, 3, 3), degenerate (M,) bool)``."""
    return _core.deformation_gradients(
        _points(old, "old"),
        _points(new, "new"),
        _faces(faces, "faces"),
        _whole("rings", rings),
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
        _points(old, "old"),
        _points(proposed, "proposed"),
        _faces(faces, "faces"),
        _stage_settings(params),
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
    target_weights: Any = None,
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
    target_weights : (N,) float, optional
        As in :func:`fit`: the scan points of weight 0 are left out (a dressed-body scan's
        garment mask: the fit is measured against the garment's points, and ``f_R`` and
        ``target_diagonal`` are relative to their diagonal), the others count alike. The same
        checks as :func:`fit`'s.

    Returns
    -------
    dict
        ``f_H`` (Hausdorff ratio after/before), ``f_S``, ``f_E``, ``f_F`` (fractions of
        collapsed, expanded, flipped faces), ``f_R`` (ground-truth RMSE / target diagonal, or
        None), ``f_lambda`` (mean of the available terms, named in ``f_lambda_terms``),
        ``chamfer``, ``scan_to_fit_mean``, ``scan_to_fit_p95``, ``fit_to_scan_mean``,
        ``hausdorff_before``, ``hausdorff_after``, ``rmse``, ``target_diagonal`` and face counts.
    """
    x = _points(target, "target")
    return _core.evaluate(
        _points(template, "template_vertices"),
        _faces(template_faces, "template_faces"),
        _points(fitted, "fitted_vertices"),
        x,
        None if ground_truth is None else _points(ground_truth, "ground_truth"),
        float(tau_s),
        float(tau_e),
        _inputs.weights(target_weights, len(x), target),
    )


def assess(
    template: Any,
    template_faces: Any,
    fitted: Any,
    scan: Any,
    *,
    thresholds: Optional[dict[str, float]] = None,
    target_weights: Any = None,
) -> dict[str, Any]:
    """Does a fit look right? The quality verdict from figures that need no ground truth
    (docs/method.md "Quality verdict"); :func:`fit` puts the same into ``FitResult.quality``.

    Parameters
    ----------
    template : (M, 3) float or trimesh.Trimesh
        The template before fitting.
    template_faces : (T, 3) int
    fitted : (M, 3) float or FitResult
        The fitted vertices.
    scan : (N, 3) float
        The scan the template was fitted to.
    thresholds : dict, optional
        Replaces the verdict's thresholds (every key of ``quality`` below from ``fit_to_scan``
        to ``pose_turn``); ``float("inf")`` turns a test off.
    target_weights : (N,) float, optional
        As in :func:`fit`; the scan points of weight 0 are left out of every figure (a
        dressed-body scan's garment mask: the body's points lie far from any garment fit and
        would make the scan → fit distance and the asymmetry flag a right fit), the others
        count alike. The same checks as :func:`fit`'s.

    Returns
    -------
    dict
        ``quality``: ``verdict`` (``"ok"`` or ``"suspicious"``), ``reasons`` (one sentence per
        figure past its threshold), ``fit_to_scan`` and ``scan_to_fit`` (mean distances over
        the scan's bounding-box diagonal; scan→fit to the fitted surface), ``asymmetry``,
        ``unsupported_share``, ``carried_share`` (0 here: :func:`assess` knows of no carried
        vertices), ``flipped_share``, ``collapsed_share``, ``edge_distortion``
        (95th percentile of the edge-length ratio, scale divided out), ``pose_gap`` (the
        template in the fit's rigid pose against its best rigid placement on the scan: the
        ratio of their distances to the scan, ≥ 1), ``pose_turn`` (degrees from the fit's rigid
        pose to the placement the pre-alignment would start a fit from, when the gap is 1.02 or
        more; else 0), ``support_radius``,
        ``scan_diagonal``. ``correspondences`` (M,) uint32: each vertex's nearest scan point;
        ``residuals`` (M,) float: the distance to it; ``support`` (M,) bool: whether the
        vertex has scan support.
    """
    if thresholds is not None:
        # Missing keys keep their defaults; +inf turns a threshold off.
        thresholds = {k: float(v) for k, v in thresholds.items()}
    x = _points(scan, "scan")
    kept = _kept_points(_inputs.weights(target_weights, len(x), scan), len(x))
    raw = _core.assess_raw(
        _points(template, "template_vertices"),
        _faces(template_faces, "template_faces"),
        _points(fitted, "fitted_vertices"),
        x if kept is None else np.ascontiguousarray(x[kept]),
        thresholds,
    )
    correspondences = raw["correspondences"]
    if kept is not None:  # indices of the whole scan
        correspondences = kept[correspondences].astype(np.uint32)
    return {
        "quality": raw["quality"],
        "correspondences": correspondences,
        "residuals": raw["residuals"],
        "support": raw["support"],
    }


def _kept_points(weights: Optional[np.ndarray], n: int) -> Optional[np.ndarray]:
    """The indices of the scan points with a positive weight (None: no weights), after the
    checks :func:`fit` makes: one weight per point, finite, non-negative, not all zero."""
    if weights is None:
        return None
    if len(weights) != n:
        raise InvalidParameterError(
            f"parameter target_weights = {len(weights)} weights: need one weight per scan point ({n})"
        )
    bad = np.flatnonzero(~np.isfinite(weights) | (weights < 0))
    if len(bad):
        j = int(bad[0])
        raise InvalidParameterError(
            f"parameter target_weights[{j}] = {weights[j]}: weights must be finite and >= 0"
        )
    if not (weights > 0).any():
        raise InvalidParameterError(
            "parameter target_weights = all zero: at least one scan point needs a positive weight"
        )
    return np.flatnonzero(weights > 0)


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
    "FitParams",
    "FitResult",
    "fit",
    "track",
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
    "render",
    "assess",
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
