"""The exact symmetries of a template mesh, for scoring fits up to them (bench/prealign.py).

A template that maps onto itself by a rotation (a square sheet by quarter turns, a generated
tube about its axis, a generated shirt front to back) gives the same scan whichever of its
symmetric readings a fit takes, with other vertex correspondences: once its scan is moved, no
method can tell which reading the truth used, and f_R (per-vertex RMS to the truth) scores a
right surface as wrong. :func:`symmetries` finds the readings: each proper rotation of the
template's principal frame (the 24 of the cube), refined by rigid ICP onto the template itself,
that lands every vertex within a quarter of the template's point spacing of another, as a
vertex permutation; and the turns about a principal axis by which a template of N segments
around it maps onto itself (a generated or simulated tube: every N-th of a turn, which the fit
cannot tell apart either, docs/method.md "Rigid phase"), each also combined with the former.
:func:`f_r_up_to` is f_R minimised over them.
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.spatial import cKDTree

from bench import cases

#: ICP iterations refining each candidate rotation.
ICP_ITERATIONS = 30
#: A candidate is a symmetry when its mean distance to the template is below this share of the
#: template's median nearest-neighbour spacing.
LANDS = 0.25


def _cube_rotations() -> list[np.ndarray]:
    """The 24 proper rotations that map the coordinate axes onto themselves."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            q = np.zeros((3, 3))
            for row, (col, s) in enumerate(zip(perm, signs)):
                q[row, col] = s
            if np.linalg.det(q) > 0:
                out.append(q)
    return out


def symmetries(vertices: np.ndarray) -> list[np.ndarray]:
    """The template's exact rotational symmetries as vertex permutations ``s`` (vertex ``i``
    maps onto vertex ``s[i]``), the identity first."""
    v = np.asarray(vertices, float)
    centred = v - v.mean(0)
    tree = cKDTree(centred)
    spacing = float(np.median(tree.query(centred, k=2)[0][:, 1]))
    _, axes = np.linalg.eigh(centred.T @ centred)
    found = [np.arange(len(v))]
    for q in _cube_rotations():
        r = axes @ q @ axes.T
        for _ in range(ICP_ITERATIONS):
            _, nearest = tree.query(centred @ r.T)
            r = cases.umeyama(centred, centred[nearest])[1]
        nearest = _maps_onto_itself(centred, tree, spacing, r)
        if nearest is not None and not any(np.array_equal(nearest, s) for s in found):
            found.append(nearest)
    # Turns about an axis beyond the cube's, and each combined with the cube's readings (a
    # straight tube's half turns end over end).
    seen = {f.tobytes() for f in found}
    cube = list(found)
    for axis in axes.T:
        for t in _turns_about(centred, tree, spacing, axis):
            for c in cube:
                s = c[t]
                if s.tobytes() not in seen:
                    seen.add(s.tobytes())
                    found.append(s)
    return found


def _maps_onto_itself(centred: np.ndarray, tree: cKDTree, spacing: float, r: np.ndarray) -> np.ndarray | None:
    """The vertex permutation by which the rotation `r` maps the template onto itself (every
    vertex within :data:`LANDS` of the spacing of another, on average, one to one), or None."""
    d, nearest = tree.query(centred @ r.T)
    if d.mean() > LANDS * spacing or len(np.unique(nearest)) != len(centred):
        return None
    return nearest


def _turns_about(centred: np.ndarray, tree: cKDTree, spacing: float, axis: np.ndarray) -> list[np.ndarray]:
    """The turns about a principal axis that map the template onto itself, beyond the cube's
    quarter turns (a tube of N segments about its axis: every N-th of a turn). The candidate
    step is the least angle between the vertices of the ring farthest from the axis (same height
    and radius as its outermost vertex); it is kept when that turn maps every vertex onto
    another, and then so are its multiples (the step's permutation composed)."""
    height = centred @ axis
    radial = centred - np.outer(height, axis)
    radius = np.linalg.norm(radial, axis=1)
    far = int(np.argmax(radius))
    ring = np.flatnonzero(
        (np.abs(height - height[far]) < LANDS * spacing) & (np.abs(radius - radius[far]) < LANDS * spacing)
    )
    if len(ring) < 3:
        return []
    u = radial[far] / radius[far]
    w = np.cross(axis, u)
    angles = np.sort(np.mod(np.arctan2(radial[ring] @ w, radial[ring] @ u), 2 * np.pi))
    gaps = np.diff(np.r_[angles, angles[0] + 2 * np.pi])
    n = int(round(2 * np.pi / gaps[gaps > 1e-9].min()))
    step = (
        _maps_onto_itself(centred, tree, spacing, cases.rotation_matrix(axis, 360.0 / n)) if n >= 3 else None
    )
    if step is None:
        return []
    # The j-th turn is the step applied j times: its permutation composed j times.
    turns = [step]
    while len(turns) < n - 1:
        turns.append(step[turns[-1]])
    return turns


def f_r_up_to(fitted: np.ndarray, truth: np.ndarray, diagonal: float, perms: list[np.ndarray]) -> float:
    """f_R (RMS distance to the truth ÷ the scan's diagonal) of the reading of the truth that
    lies nearest: the minimum over the symmetries ``perms``."""
    f = np.asarray(fitted, float)
    return min(float(np.sqrt(((f - truth[s]) ** 2).sum(1).mean())) for s in perms) / diagonal
