"""Type stubs of the compiled core (checked against the built module by mypy.stubtest)."""

from typing import Any, Callable, Optional, final

import numpy as np
import numpy.typing as npt

__version__: str

_F64 = npt.NDArray[np.float64]
_I64 = npt.NDArray[np.int64]

__all__ = [
    "fit_params",
    "param_names",
    "param_reference",
    "read_mesh",
    "read_weights",
    "read_normals",
    "fit_raw",
    "knn_query",
    "nbody_step",
    "n_rings",
    "gaussian_curvature",
    "prealign_transform",
    "deformation_gradients",
    "regularize_gradients",
    "polar_decomposition",
    "wrinkle_field",
    "solve_rotations",
    "foldmatch_update",
    "folded_sheet",
    "evaluate",
    "assess_raw",
    "_mark_forked",
    "run_cli",
    "cluster_request",
    "RunBook",
    "FileFitter",
    "Tracker",
    "render_preview",
    "wrinkle_colors",
    "write_fitted",
    "__version__",
]

def fit_params(preset: str = "default", overrides: Optional[dict[str, Any]] = None) -> dict[str, Any]: ...
def param_names() -> list[str]: ...
def param_reference() -> list[dict[str, Any]]: ...
def read_mesh(path: str, property: Optional[str] = None) -> tuple[_F64, _I64, Optional[_F64]]: ...
def read_weights(path: str) -> _F64: ...
def read_normals(path: str) -> Optional[_F64]: ...
def fit_raw(
    template_vertices: _F64,
    template_faces: _I64,
    target: _F64,
    target_faces: Optional[_I64],
    params: dict[str, Any],
    callback: Optional[Callable[[dict[str, Any]], Any]] = None,
    threads: Optional[int] = None,
    target_weights: Optional[_F64] = None,
    landmark_vertices: Optional[_I64] = None,
    landmark_positions: Optional[_F64] = None,
    target_normals: Optional[_F64] = None,
) -> dict[str, Any]: ...
def knn_query(
    points: _F64, queries: _F64, k: int, threads: Optional[int] = None
) -> tuple[npt.NDArray[np.uint32], _F64]: ...
def nbody_step(
    positions: _F64,
    velocities: _F64,
    target: _F64,
    neighbours: _I64,
    curvature: _F64,
    params: Optional[dict[str, Any]] = None,
) -> tuple[_F64, _F64]: ...
def n_rings(
    faces: _I64, n_vertices: int, rings: int = 2
) -> tuple[npt.NDArray[np.uint64], npt.NDArray[np.uint32]]: ...
def gaussian_curvature(points: _F64, faces: Optional[_I64] = None) -> _F64: ...
def prealign_transform(template_vertices: _F64, target: _F64, scaled: bool = False) -> dict[str, Any]: ...
def deformation_gradients(
    old: _F64, new: _F64, faces: _I64, rings: int = 2, normal_completion: float = 0.3
) -> tuple[_F64, npt.NDArray[np.bool_]]: ...
def regularize_gradients(
    gradients: _F64, offsets: _I64, members: _I64, mode: str = "affine_invariant"
) -> tuple[_F64, _F64]: ...
def polar_decomposition(matrices: _F64) -> tuple[_F64, _F64]: ...
def wrinkle_field(stretches: _F64, psi: float = 0.05) -> tuple[_F64, _F64]: ...
def solve_rotations(gradients: _F64, modified_stretches: _F64) -> _F64: ...
def foldmatch_update(
    old: _F64, proposed: _F64, faces: _I64, params: Optional[dict[str, Any]] = None
) -> tuple[_F64, _F64]: ...
def folded_sheet(
    nx: int = 41,
    ny: int = 41,
    width: float = 1.0,
    height: float = 1.0,
    fold_amplitude: float = 0.06,
    folds: float = 2.5,
    rotation_degrees: float = 8.0,
    offset: tuple[float, float, float] = ...,
    scan_points: int = 0,
    noise: float = 0.0,
    seed: int = 1,
) -> dict[str, _F64]: ...
def evaluate(
    template_vertices: _F64,
    template_faces: _I64,
    fitted_vertices: _F64,
    target: _F64,
    ground_truth: Optional[_F64] = None,
    tau_s: float = 0.02,
    tau_e: float = 2.0,
    target_weights: Optional[_F64] = None,
) -> dict[str, Any]: ...
def run_cli(argv: list[str]) -> int: ...
def render_preview(
    vertices: _F64,
    faces: _I64,
    scan: Optional[_F64] = None,
    scan_faces: Optional[_I64] = None,
    field: Optional[_F64] = None,
    magnitude: Optional[_F64] = None,
    path: Optional[str] = None,
    panel: int = 320,
    views: Optional[list[str]] = None,
) -> npt.NDArray[np.uint8]: ...
def wrinkle_colors(magnitude: _F64) -> tuple[npt.NDArray[np.uint8], tuple[float, float]]: ...
def write_fitted(path: str, vertices: _F64, faces: _I64, field: _F64, ascii: bool = False) -> None: ...
def _mark_forked() -> None: ...
def cluster_request(argv: list[str]) -> Optional[str]: ...

@final
class RunBook:
    def __new__(cls, request_json: str, verbosity: str = "normal") -> RunBook: ...
    def files_json(self) -> str: ...
    @property
    def params_json(self) -> str: ...
    @property
    def tracking_json(self) -> str: ...
    @property
    def template(self) -> str: ...
    @property
    def report_path(self) -> str: ...
    @property
    def total(self) -> int: ...
    def info(self, message: str) -> None: ...
    def record(self, index: int, entry_json: str) -> None: ...
    def record_failure(self, index: int, message: str) -> None: ...
    def finish(self, interrupted: bool) -> tuple[int, str]: ...

@final
class FileFitter:
    def __new__(cls, template: str, params_json: str, threads: int) -> FileFitter: ...
    def fit(self, file_json: str, ascii: bool = False) -> str: ...
    def track(
        self,
        file_json: str,
        tracking_json: str,
        state_json: Optional[str] = None,
        warm_name: Optional[str] = None,
        ascii: bool = False,
    ) -> tuple[str, str, bool]: ...
    def resume_frame(
        self, file_json: str, state_json: Optional[str] = None, warm_name: Optional[str] = None
    ) -> Optional[tuple[str, str]]: ...

@final
class Tracker:
    def __new__(
        cls,
        template_vertices: _F64,
        template_faces: _I64,
        params: dict[str, Any],
        prediction: float,
        distortion_jump: float,
        distance_jump: float,
        reanchor: bool,
    ) -> Tracker: ...
    @property
    def frames(self) -> int: ...
    def skip(self) -> None: ...
    def accept(self, fitted: _F64) -> None: ...
    def step(
        self,
        target: _F64,
        target_faces: Optional[_I64] = None,
        target_weights: Optional[_F64] = None,
        threads: Optional[int] = None,
    ) -> dict[str, Any]: ...

def assess_raw(
    template_vertices: _F64,
    template_faces: _I64,
    fitted_vertices: _F64,
    scan: _F64,
    thresholds: Optional[dict[str, float]] = None,
) -> dict[str, Any]: ...
