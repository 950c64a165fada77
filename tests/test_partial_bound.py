"""bench/partial_bound.py: the as-rigid-as-possible completion that bounds what the seen half of
a front-only scan determines (docs/notes/partial-scans.md)."""

from __future__ import annotations

import foldmatch_rs as fm
import numpy as np
import pytest

pytest.importorskip("scipy", reason="bench/partial_bound.py needs scipy (requirements-dev.txt)")

from bench import partial, partial_bound  # noqa: E402


def rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    k = axis / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def test_a_stretched_unseen_half_is_completed_by_the_seen_halfs_motion():
    c = fm.folded_sheet(nx=12, ny=12, scan_points=100, noise=0.0, seed=1)
    rest, faces = c["template_vertices"], c["faces"].astype(np.int64)
    rot, shift = rotation(np.array([1.0, 2.0, 0.5]), 0.7), np.array([0.3, -0.1, 0.2])
    moved = rest @ rot.T + shift
    seam = np.median(rest[:, 0])
    fixed = rest[:, 0] < seam  # one half of the sheet seen
    # the moved template is a fixed point (zero energy)
    done = partial_bound.arap_completion(rest, faces, moved.copy(), fixed)
    assert np.abs(done - moved).max() < 1e-9
    # the unseen half stretched by 30 % away from the seam is brought back to the template's
    # lengths, the seen half untouched
    stretched = rest.copy()
    stretched[~fixed, 0] = seam + 1.3 * (rest[~fixed, 0] - seam)
    start = stretched @ rot.T + shift
    assert np.abs(start - moved).max() > 0.1
    done = partial_bound.arap_completion(rest, faces, start, fixed)
    np.testing.assert_array_equal(done[fixed], moved[fixed])
    assert np.abs(done - moved).max() < 1e-4


def test_the_rigid_fit_and_the_seen_vertices():
    c = fm.folded_sheet(nx=8, ny=8, scan_points=100, noise=0.0, seed=2)
    rest = c["template_vertices"]
    moved = rest @ rotation(np.array([0.0, 0.0, 1.0]), 1.1).T + 2.0
    np.testing.assert_allclose(partial_bound.rigid_onto(rest, moved, rest), moved, atol=1e-9)
    # the truth's vertices near a half scan are seen, the others not
    half = moved[moved[:, 0] < np.median(moved[:, 0])]
    seen = partial.seen_vertices(moved, half)
    assert seen[moved[:, 0] < np.median(moved[:, 0])].all()
    assert not seen[moved[:, 0] > np.quantile(moved[:, 0], 0.8)].any()
