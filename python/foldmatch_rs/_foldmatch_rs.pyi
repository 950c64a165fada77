"""Type stubs of the compiled core (checked against the built module by mypy.stubtest)."""

from typing import Any, Callable, Optional

import numpy as np
import numpy.typing as npt

__version__: str

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]

def default_params_json(preset: str = "default") -> str: ...
def fit_raw(
    template_vertices: F64,
    template_faces: I64,
    target: F64,
    target_faces: Optional[I64],
    params_json: str,
    callback: Optional[Callable[[dict[str, Any]], Any]] = None,
    threads: Optional[int] = None,
    preset: str = "default",
) -> dict[str, Any]: ...
def knn_query(
    points: F64, queries: F64, k: int, threads: Optional[int] = None
) -> tuple[npt.NDArray[np.uint32], F64]: ...
def nbody_step(
    positions: F64,
    velocities: F64,
    target: F64,
    neighbours: I64,
    curvature: F64,
    params_json: str = "{}",
) -> tuple[F64, F64]: ...
def n_rings(
    faces: I64, n_vertices: int, rings: int = 2
) -> tuple[npt.NDArray[np.uint64], npt.NDArray[np.uint32]]: ...
def gaussian_curvature(points: F64, faces: Optional[I64] = None) -> F64: ...
def deformation_gradients(
    old: F64, new: F64, faces: I64, rings: int = 2, normal_completion: float = 0.3
) -> tuple[F64, npt.NDArray[np.bool_]]: ...
def regularize_gradients(
    gradients: F64, offsets: I64, members: I64, mode: str = "affine_invariant"
) -> tuple[F64, F64]: ...
def polar_decomposition(matrices: F64) -> tuple[F64, F64]: ...
def wrinkle_field(stretches: F64, psi: float = 0.05) -> tuple[F64, F64]: ...
def solve_rotations(gradients: F64, modified_stretches: F64) -> F64: ...
def foldmatch_update(
    old: F64, proposed: F64, faces: I64, params_json: str = "{}"
) -> tuple[F64, F64]: ...
def folded_sheet(
    nx: int = 41,
    ny: int = 41,
    width: float = 1.0,
    height: float = 1.0,
    fold_amplitude: float = 0.06,
    folds: float = 2.5,
    rotation_degrees: float = 8.0,
    offset: tuple[float, float, float] = (0.03, -0.02, 0.04),
    scan_points: int = 0,
    noise: float = 0.0,
    seed: int = 1,
) -> dict[str, F64]: ...
def evaluate(
    template_vertices: F64,
    template_faces: I64,
    fitted_vertices: F64,
    target: F64,
    ground_truth: Optional[F64] = None,
    tau_s: float = 0.02,
    tau_e: float = 2.0,
) -> dict[str, Any]: ...
def run_cli(argv: list[str]) -> int: ...
def _mark_forked() -> None: ...
