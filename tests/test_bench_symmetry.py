"""bench/symmetry.py: the exact symmetries of a template, by which bench/prealign.py scores
fits of moved scans up to the readings no scan can tell apart."""

from __future__ import annotations

import numpy as np

from bench import symmetry


def grid(n: int) -> np.ndarray:
    u = np.linspace(-0.5, 0.5, n)
    x, y = np.meshgrid(u, u, indexing="ij")
    return np.c_[x.ravel(), y.ravel(), np.zeros(n * n)]


def test_a_square_sheet_has_eight_readings_and_a_rectangle_four():
    square = grid(9)
    perms = symmetry.symmetries(square)
    assert len(perms) == 8
    assert np.array_equal(perms[0], np.arange(len(square)))
    for s in perms:
        # A permutation that maps the sheet onto itself: distances between vertices kept.
        assert sorted(s) == list(range(len(square)))
        d = np.linalg.norm(square[:, None] - square[None], axis=2)
        assert np.allclose(d, d[np.ix_(s, s)])
    rectangle = square * [2.0, 1.0, 1.0]
    assert len(symmetry.symmetries(rectangle)) == 4


def test_a_bump_off_centre_leaves_the_identity_alone():
    sheet = grid(9)
    sheet[10, 2] = 0.2
    assert len(symmetry.symmetries(sheet)) == 1


def test_f_r_up_to_the_symmetries_forgives_a_symmetric_reading_only():
    square = grid(9)
    perms = symmetry.symmetries(square)
    truth = square + [0.0, 0.0, 0.01] * np.sin(3 * square[:, :1])
    turned = truth[perms[3]]  # the same surface, another reading
    plain = symmetry.f_r_up_to(turned, truth, 1.0, perms[:1])
    assert plain > 0.1
    assert symmetry.f_r_up_to(turned, truth, 1.0, perms) < 1e-12
    shifted = truth + [0.0, 0.0, 0.05]
    assert np.isclose(symmetry.f_r_up_to(shifted, truth, 2.0, perms), 0.025)
