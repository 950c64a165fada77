"""Sequence tracking from Python (`foldmatch_rs.track`, docs/method.md "Tracking")."""

from __future__ import annotations

import foldmatch_rs as fm
import numpy as np
import pytest


def rotation(axis, degrees):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    a = np.radians(degrees)
    return np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k


@pytest.fixture(scope="module")
def sequence():
    """A folded sheet (the template) and 8 copies of it, each turned 6° further about an
    oblique axis and moved 6 % of its size further: the last is out of reach of one fit."""
    case = fm.folded_sheet(nx=17, ny=17, fold_amplitude=0.08, rotation_degrees=0.0, offset=(0, 0, 0))
    shape = case["ground_truth"]
    copies = [
        shape @ rotation((0.3, 1.0, 0.2), 6.0 * t).T + np.array([0.06, 0.02, -0.03]) * t for t in range(8)
    ]
    return shape, case["faces"], copies


def rms(a, b):
    return float(np.sqrt(((a - b) ** 2).sum(1).mean()))


def test_yields_one_result_per_frame_with_the_template_topology(sequence):
    shape, faces, copies = sequence
    stream = fm.track(shape, faces, iter(copies), iterations=30)
    results = list(stream)
    assert len(results) == len(copies)
    for t, r in enumerate(results):
        assert isinstance(r, fm.FitResult)
        assert r.vertices.shape == shape.shape
        np.testing.assert_array_equal(r.faces, faces)
        assert r.tracking["frame"] == t
        assert r.tracking["warm_started"] == (t > 0)
        assert r.quality["verdict"] in ("ok", "suspicious")


def test_follows_rigidly_moved_copies_that_a_fit_from_the_template_misses(sequence):
    shape, faces, copies = sequence
    diagonal = float(np.linalg.norm(shape.max(0) - shape.min(0)))
    errors = [
        rms(r.vertices, c) / diagonal for r, c in zip(fm.track(shape, faces, copies, iterations=30), copies)
    ]
    assert max(errors) < 0.01, errors
    cold = fm.fit(shape, faces, copies[-1], preset="tracking", iterations=30)
    assert rms(cold.vertices, copies[-1]) / diagonal > 5 * max(errors)


def test_a_bad_frame_raises_a_typed_error_naming_its_index(sequence):
    shape, faces, copies = sequence
    bad = copies[2].copy()
    bad[5, 1] = np.nan
    stream = fm.track(shape, faces, [copies[0], copies[1], bad, copies[3]], iterations=5)
    assert next(stream).tracking["frame"] == 0
    assert next(stream).tracking["frame"] == 1
    with pytest.raises(fm.InvalidInputError, match=r"^frame 2: target: non-finite coordinate at row 5"):
        next(stream)
    with pytest.raises(fm.InvalidInputError, match=r"^frame 0: target"):
        next(fm.track(shape, faces, [np.zeros((4, 2))]))


def test_settings_are_checked_at_the_call(sequence):
    shape, faces, _ = sequence
    with pytest.raises(fm.InvalidParameterError, match="prediction"):
        fm.track(shape, faces, [], prediction=2.0)
    with pytest.raises(fm.InvalidParameterError, match="iterations"):
        fm.track(shape, faces, [], iterations=-1)


def test_the_core_tracker_takes_a_frame_fitted_elsewhere(sequence):
    # `_core.Tracker.accept`: a frame done elsewhere counts as the last fit (the next frame
    # starts from it); a fit of another vertex count is refused.
    from foldmatch_rs import _core

    shape, faces, copies = sequence
    settings = fm.FitParams("tracking", iterations=30).to_dict()
    tracker = _core.Tracker(shape, faces.astype(np.int64), settings, 0.0, 0.15, 2.0, False)
    tracker.accept(copies[6])
    assert tracker.frames == 1
    with pytest.raises(fm.InvalidInputError):
        tracker.accept(copies[6][:-1])
    raw = tracker.step(copies[7], None, None, None)
    assert raw["tracking"]["warm_started"]
    assert rms(raw["vertices"], copies[7]) < 0.2 * rms(copies[6], copies[7])
