"""The exact symmetries of a template mesh, for scoring fits up to them (bench/prealign.py).

A template that maps onto itself by a rotation (a square sheet by quarter turns, a generated
tube about its axis, a generated shirt front to back) gives the same scan whichever of its
symmetric readings a fit takes, with other vertex correspondences: once its scan is moved, no
method can tell which reading the truth used, and f_R (per-vertex RMS to the truth) scores a
right surface as wrong. :func:`symmetries` finds the readings: each proper rotation of the
template's principal frame (the 24 of the cube), refined by rigid ICP onto the template itself,
that lands every vertex within a quarter of the template's point spacing of another, as a
vertex permutation. :func:`f_r_up_to` is f_R minimised over them.
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
        d, nearest = tree.query(centred @ r.T)
        if d.mean() > LANDS * spacing or len(np.unique(nearest)) != len(v):
            continue
        if not any(np.array_equal(nearest, s) for s in found):
            found.append(nearest)
    return found


def f_r_up_to(fitted: np.ndarray, truth: np.ndarray, diagonal: float, perms: list[np.ndarray]) -> float:
    """f_R (RMS distance to the truth ÷ the scan's diagonal) of the reading of the truth that
    lies nearest: the minimum over the symmetries ``perms``."""
    f = np.asarray(fitted, float)
    return min(float(np.sqrt(((f - truth[s]) ** 2).sum(1).mean())) for s in perms) / diagonal
