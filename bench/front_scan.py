"""A front-only scan: what one camera rig standing on one side of the garment sees.

Six pinhole cameras (3 azimuths, −40°, 0°, +40° about the front direction, at 2 heights) at two
bounding-box diagonals from the true surface's centre render it with exact visibility
(``dressed_scans.render_view``); the hits are fused on a voxel grid, thinned to at most the
whole scan's point count and given N(0, (0.002·diag)²) noise, as the real point-cloud cases
are (bench/cases.py). The front is the horizontal axis along which the true surface is
thinnest (a garment's depth), the up axis the case's ``meta["up"]`` (y for every real source);
``side`` = −1 scans the back instead. Used by bench/partial.py and bench/verdict.py.
"""

from __future__ import annotations

import numpy as np

from bench import cases as cases_mod
from bench.dressed_scans import render_view

AZIMUTHS_DEG = (-40.0, 0.0, 40.0)
HEIGHTS = (-0.25, 0.25)  # in bounding-box diagonals, about the centre
DISTANCE = 2.0  # in bounding-box diagonals
PIXELS = 400  # across one diagonal at the look-at distance
VOXEL = 1 / 200  # of the diagonal
NOISE = 0.002  # of the diagonal


def front_axis(truth: np.ndarray, up: int) -> int:
    """The horizontal axis along which ``truth`` is thinnest."""
    extent = truth.max(0) - truth.min(0)
    horizontal = [k for k in range(3) if k != up]
    return min(horizontal, key=lambda k: extent[k])


def front_scan(
    truth: np.ndarray, faces: np.ndarray, up: int, seed: int, most: int, side: int = 1
) -> np.ndarray:
    """The points one rig on the ``side`` of the front sees of ``(truth, faces)``."""
    rng = np.random.default_rng(seed)
    diag = cases_mod.bbox_diagonal(truth)
    centre = (truth.min(0) + truth.max(0)) / 2
    front = front_axis(truth, up)
    lateral = next(k for k in range(3) if k not in (up, front))
    hits = []
    for az in np.radians(AZIMUTHS_DEG):
        for h in HEIGHTS:
            eye = centre.copy()
            eye[front] += side * DISTANCE * diag * np.cos(az)
            eye[lateral] += DISTANCE * diag * np.sin(az)
            eye[up] += h * diag
            p, _, _ = render_view(truth, faces, eye, centre.copy(), up, diag / PIXELS)
            hits.append(p)
    p = np.concatenate(hits)
    p = p[rng.permutation(len(p))]
    vox = np.floor((p - p.min(0)) / (VOXEL * diag)).astype(np.int64)
    _, keep = np.unique(vox, axis=0, return_index=True)
    p = p[np.sort(keep)]
    if len(p) > most:
        p = p[np.sort(rng.choice(len(p), most, replace=False))]
    return np.ascontiguousarray(p + rng.normal(scale=NOISE * diag, size=p.shape))
