"""A small headless mesh renderer on matplotlib (Agg): flat-shaded triangles, optionally colored
by a per-vertex scalar, painter's-algorithm depth sorting (mplot3d's Poly3DCollection)."""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from mpl_toolkits.mplot3d.art3d import Poly3DCollection


def view_vectors(elev: float, azim: float) -> np.ndarray:
    e, a = np.radians(elev), np.radians(azim)
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])


def principal_frame(points: np.ndarray, up: int = 2) -> tuple[np.ndarray, float]:
    """A rotation for a front view, and the elevation to use: the data's ``up`` axis (0/1/2)
    becomes z, the widest horizontal direction x, the viewer looks along y. Flat-lying shapes
    (the vertical extent the smallest) get a high elevation instead."""
    c = points - points.mean(0)
    u = np.zeros(3)
    u[up] = 1.0
    h = c - np.outer(c @ u, u)
    _, _, vt = np.linalg.svd(h, full_matrices=False)
    x = vt[0] - (vt[0] @ u) * u
    x /= np.linalg.norm(x)
    y = np.cross(u, x)
    r = np.stack([x, y, u])
    ext = np.ptp(c @ r.T, axis=0)
    elev = 50.0 if ext[2] < 0.6 * min(ext[0], ext[1]) else 10.0
    return r, elev


def draw_mesh(
    ax,
    vertices: np.ndarray,
    faces: np.ndarray,
    values: np.ndarray | None = None,
    cmap: str = "viridis",
    vmin: float | None = None,
    vmax: float | None = None,
    color: Sequence[float] = (0.75, 0.78, 0.85),
    alpha: float = 1.0,
    elev: float = 20.0,
    azim: float = -60.0,
    edgecolor: str = "none",
) -> None:
    """Flat-shaded mesh on a 3-D axis; ``values`` (per vertex) picks face colors from ``cmap``,
    modulated by a two-sided Lambert term from the view direction."""
    tri = vertices[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-30
    light = view_vectors(elev + 25, azim + 30)
    shade = 0.35 + 0.65 * np.abs(n @ light)
    if values is not None:
        fv = values[faces].mean(1)
        lo = np.nanmin(fv) if vmin is None else vmin
        hi = np.nanmax(fv) if vmax is None else vmax
        t = np.clip((fv - lo) / (hi - lo + 1e-30), 0, 1)
        rgb = plt.get_cmap(cmap)(t)[:, :3]
        rgb = rgb * (0.55 + 0.45 * shade[:, None])
    else:
        rgb = np.asarray(color)[None, :] * shade[:, None]
    coll = Poly3DCollection(
        tri,
        facecolors=np.clip(rgb, 0, 1),
        edgecolors=edgecolor,
        linewidths=0.0,
        alpha=alpha,
        antialiased=False,
    )
    ax.add_collection3d(coll)
    ax.view_init(elev=elev, azim=azim)


def frame_axes(ax, points: np.ndarray, margin: float = 0.02) -> None:
    lo, hi = points.min(0), points.max(0)
    c, r = (lo + hi) / 2, (hi - lo).max() / 2 * (1 + margin)
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)
    ax.set_box_aspect((1, 1, 1), zoom=1.35)
    ax.set_axis_off()


def draw_points(ax, points: np.ndarray, color="k", size: float = 0.3, alpha: float = 0.5) -> None:
    ax.scatter(
        points[:, 0], points[:, 1], points[:, 2], s=size, c=color, alpha=alpha, depthshade=False, linewidths=0
    )
