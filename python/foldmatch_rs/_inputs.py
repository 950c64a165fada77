"""The inputs of :func:`foldmatch_rs.fit` as the core takes them: ``(n, 3)`` float64 points and
``(t, 3)`` int64 faces from arrays, trimesh and Open3D objects, or mesh files read by the
crate's own readers (the same as the ``foldmatch`` command's)."""

from __future__ import annotations

import os
from typing import Any, Optional

import numpy as np

from . import _foldmatch_rs as _core
from .errors import InvalidInputError


def points(x: Any, name: str) -> np.ndarray:
    """An ``(n, 3)`` C-contiguous, aligned float64 view of ``x`` (no copy when it already is
    one; arrays unpickled from a buffer, as Dask delivers them, may be unaligned)."""
    if hasattr(x, "vertices"):  # trimesh.Trimesh / PointCloud, Open3D TriangleMesh
        x = x.vertices
    elif hasattr(x, "points"):  # Open3D PointCloud
        x = x.points
    a = np.asarray(x)
    if a.ndim != 2 or a.shape[1] != 3:
        raise InvalidInputError(f"{name}: expected shape (n, 3), got {a.shape}")
    if a.shape[0] == 0:
        raise InvalidInputError(f"{name}: expected at least one point, got 0 rows")
    if not np.issubdtype(a.dtype, np.number) or np.issubdtype(a.dtype, np.complexfloating):
        raise InvalidInputError(f"{name}: expected a real numeric array, got dtype {a.dtype}")
    return np.require(a, dtype=np.float64, requirements=["C", "A"])


def faces(f: Any, name: str) -> np.ndarray:
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


def is_path(x: Any) -> bool:
    return isinstance(x, (str, os.PathLike))


def mesh(x: Any, given_faces: Any, name: str) -> tuple[np.ndarray, Optional[np.ndarray]]:
    """``(vertices, faces or None)`` of a mesh or point cloud given as an array (with
    ``given_faces``), a trimesh or Open3D object, or a ``.ply`` / ``.obj`` path."""
    if is_path(x):
        v, f, _ = _core.read_mesh(os.fspath(x))
        if given_faces is None and len(f):
            given_faces = f
    elif given_faces is None:
        if hasattr(x, "faces"):  # trimesh.Trimesh
            given_faces = x.faces
        elif hasattr(x, "triangles"):  # Open3D TriangleMesh
            given_faces = x.triangles
        if given_faces is not None and np.asarray(given_faces).size == 0:
            given_faces = None
        v = x
    else:
        v = x
    return points(v, name), (None if given_faces is None else faces(given_faces, f"{name}_faces"))


def weights(w: Any, n: int, target: Any) -> Optional[np.ndarray]:
    """``target_weights`` as a contiguous ``(n,)`` float64 array (the checks of values are the
    core's: finite, non-negative, not all zero). A path to a ``.npy`` file is read; another
    string names a vertex property of the target's PLY file (``"confidence"``)."""
    if w is None:
        return None
    if isinstance(w, os.PathLike) or (isinstance(w, str) and w.lower().endswith(".npy")):
        w = _core.read_weights(os.fspath(w))
    elif isinstance(w, str):
        if not (is_path(target) and os.fspath(target).lower().endswith(".ply")):
            raise InvalidInputError(
                f"target_weights={w!r}: a property name needs the target as a .ply path "
                "(or pass the weights as an array or a .npy path)"
            )
        _, _, w = _core.read_mesh(os.fspath(target), w)
    try:
        a = np.ascontiguousarray(w, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise InvalidInputError(f"target_weights: not convertible to float64 ({e})") from None
    if a.ndim != 1:
        raise InvalidInputError(f"target_weights: expected shape ({n},), got {a.shape}")
    return a


def normals(value: Any, n: int, target: Any) -> Optional[np.ndarray]:
    """``target_normals`` as a contiguous ``(n, 3)`` float64 array (the checks of values are the
    core's: finite, non-zero). ``True`` takes the target's own: a ``.ply`` path's ``nx ny nz``,
    or an Open3D point cloud's or mesh's normals."""
    if value is None or value is False:
        return None
    if value is True:
        if is_path(target):
            value = _core.read_normals(os.fspath(target))
            where = f"{os.fspath(target)} has no vertex normals (nx ny nz)"
        elif hasattr(target, "has_normals") and target.has_normals():  # Open3D PointCloud
            value = target.normals
        elif hasattr(target, "has_vertex_normals") and target.has_vertex_normals():  # Open3D mesh
            value = target.vertex_normals
        else:
            value = None
            where = "the target carries no normals (a .ply path with nx ny nz, or an Open3D point cloud)"
        if value is None:
            raise InvalidInputError(f"target_normals=True: {where}; pass them as an (N, 3) array")
    a = points(value, "target_normals")
    if len(a) != n:
        raise InvalidInputError(f"target_normals: {len(a)} normals, need one per scan point ({n})")
    return a


def landmarks(value: Any) -> tuple[Optional[np.ndarray], Optional[np.ndarray]]:
    """``landmarks=(indices, positions)`` as a contiguous ``(L,)`` int64 array and an
    ``(L, 3)`` float64 array (the checks of values — range, duplicates, finiteness — are the
    core's)."""
    if value is None:
        return None, None
    if not isinstance(value, (tuple, list)) or len(value) != 2:
        length = f" of length {len(value)}" if isinstance(value, (tuple, list)) else ""
        raise InvalidInputError(
            "landmarks: expected (template_vertex_indices, target_positions), got "
            f"{type(value).__name__}{length}"
        )
    try:
        idx = np.asarray(value[0])
        pos = np.ascontiguousarray(value[1], dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise InvalidInputError(f"landmarks: not convertible to arrays ({e})") from None
    if idx.ndim != 1:
        raise InvalidInputError(f"landmarks: indices must have shape (L,), got {idx.shape}")
    if idx.size and not np.issubdtype(idx.dtype, np.integer):
        raise InvalidInputError(f"landmarks: indices must be integers, got {idx.dtype}")
    if pos.ndim != 2 or pos.shape[1] != 3:
        raise InvalidInputError(f"landmarks: positions must have shape (L, 3), got {pos.shape}")
    return np.ascontiguousarray(idx, dtype=np.int64), pos
