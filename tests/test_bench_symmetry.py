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


def tube(segments: int, radii: list[float]) -> np.ndarray:
    """Rings of `segments` vertices about the z axis, one ring per radius, 0.3 apart."""
    theta = 2 * np.pi * np.arange(segments) / segments
    return np.concatenate(
        [np.c_[r * np.cos(theta), r * np.sin(theta), np.full(segments, 0.3 * k)] for k, r in enumerate(radii)]
    )


def test_a_tube_of_n_segments_has_every_nth_turn():
    # Flared (a skirt): the 12 turns about its axis, of which the cube's rotations find only the
    # quarter turns. Straight (a plain open cylinder): also end over end, 24.
    flared = tube(12, [0.6, 0.7, 0.8, 0.9, 1.0])
    perms = symmetry.symmetries(flared)
    assert len(perms) == 12
    assert len({p.tobytes() for p in perms}) == 12
    for s in perms:
        d = np.linalg.norm(flared[:, None] - flared[None], axis=2)
        assert np.allclose(d, d[np.ix_(s, s)])
    assert len(symmetry.symmetries(tube(12, [1.0] * 5))) == 24
    # A bump on one ring leaves the identity alone.
    bumped = flared.copy()
    bumped[3] *= 2.0
    assert len(symmetry.symmetries(bumped)) == 1
