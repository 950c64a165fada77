"""Do no harm (docs/method.md "Do no harm"): a template that already sits on its scan stays
there — started exactly at the truth, the default returns it, where the iteration alone slides
along the scan's noise."""

from __future__ import annotations

import foldmatch_rs as fm
import numpy as np
import pytest


@pytest.fixture(scope="module")
def noisy():
    """A folded sheet (31 × 31) and its surface resampled at 3000 points with noise 0.2 % of
    the diagonal per axis, as the real-garment point clouds of the harness."""
    c = fm.folded_sheet(nx=31, ny=31, scan_points=3000, rotation_degrees=3.0, offset=(0, 0, 0.05))
    rng = np.random.default_rng(5)
    scan = np.asarray(c["scan"])
    diag = float(np.linalg.norm(scan.max(0) - scan.min(0)))
    return c, scan + rng.normal(scale=0.002 * diag, size=scan.shape), diag


def f_r(a, b, diag):
    return float(np.sqrt(((np.asarray(a) - b) ** 2).sum(1).mean())) / diag


def test_the_truth_is_a_fixed_point(noisy):
    c, scan, diag = noisy
    truth = np.asarray(c["ground_truth"])
    r = fm.fit(truth, c["faces"], scan, iterations=60)
    assert r.diagnostics["kept_start"]
    np.testing.assert_allclose(r.vertices, truth, atol=1e-12 * diag)
    # The iteration alone moves off the truth along the noise: what the rule guards against.
    moved = fm.fit(truth, c["faces"], scan, iterations=60, params=dict(keep_margin=0.0))
    assert not moved.diagnostics["kept_start"]
    assert f_r(moved.vertices, truth, diag) > 0.001


def test_a_template_off_the_scan_is_fitted(noisy):
    c, scan, diag = noisy
    truth = np.asarray(c["ground_truth"])
    r = fm.fit(c["template_vertices"], c["faces"], scan, iterations=60)
    assert not r.diagnostics["kept_start"]
    assert f_r(r.vertices, truth, diag) < 0.5 * f_r(c["template_vertices"], truth, diag)


def test_keep_margin_is_validated_and_off_in_the_paper_preset(noisy):
    c, scan, _ = noisy
    with pytest.raises(fm.InvalidParameterError, match="keep_margin"):
        fm.fit(c["ground_truth"], c["faces"], scan, iterations=2, params=dict(keep_margin=-0.1))
    r = fm.fit(c["ground_truth"], c["faces"], scan, iterations=20, preset="paper")
    assert r.params["keep_margin"] == 0.0 and not r.diagnostics["kept_start"]
