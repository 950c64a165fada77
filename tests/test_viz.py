"""foldmatch_rs.viz: Rerun logging of a fit, checked against a stand-in for the rerun module
and its recording (rerun-sdk, the optional ``viz`` extra, is a 163 MiB wheel and not a test
dependency), and against rerun-sdk itself when it is installed."""

from __future__ import annotations

import types

import foldmatch_rs as fm
import numpy as np
import pytest
from foldmatch_rs import _foldmatch_rs as core
from foldmatch_rs import viz


class Recording:
    """Records what is logged: (timeline value, entity path, archetype, static)."""

    def __init__(self):
        self.time = None
        self.logged = []

    def set_time(self, timeline, *, sequence):
        assert timeline == viz.TIMELINE
        self.time = sequence

    def log(self, path, archetype, static=False):
        self.logged.append((self.time, path, archetype, static))


def archetype(kind):
    def make(*args, **kwargs):
        return types.SimpleNamespace(kind=kind, args=args, **kwargs)

    return make


SDK = types.SimpleNamespace(
    Scalars=archetype("Scalars"), Points3D=archetype("Points3D"), Mesh3D=archetype("Mesh3D")
)


@pytest.fixture(scope="module")
def case():
    return fm.folded_sheet(nx=11, ny=11, scan_points=400)


def test_callback_logs_the_displacements_while_the_fit_runs(case):
    rec = Recording()
    seen = []
    callback = viz.rerun_callback(rec, every=4, sdk=SDK, then=lambda info: seen.append(info))
    fm.fit(case["template_vertices"], case["faces"], case["scan"], iterations=10, callback=callback)
    assert len(seen) == 10
    times = sorted({t for t, *_ in rec.logged})
    assert times == [4, 8, 10]
    by_time = {(t, p): a for t, p, a, _ in rec.logged}
    for t in times:
        info = seen[t - 1]
        assert by_time[(t, "fit/mean_displacement")].args == (info["mean_displacement"],)
        assert by_time[(t, "fit/max_displacement")].args == (info["max_displacement"],)


def test_callback_passes_on_a_stop():
    rec = Recording()
    callback = viz.rerun_callback(rec, sdk=SDK, then=lambda info: False)
    info = {"iteration": 1, "iterations": 5, "mean_displacement": 0.1, "max_displacement": 0.2}
    assert callback(info) is False
    with pytest.raises(ValueError, match="every"):
        viz.rerun_callback(rec, every=0, sdk=SDK)


def test_log_fit_logs_the_scan_the_snapshots_and_the_colored_fit(case):
    result = fm.fit(
        case["template_vertices"], case["faces"], case["scan"], iterations=10, params={"snapshot_every": 5}
    )
    rec = Recording()
    viz.log_fit(result, scan=case["scan"], template=case["template_vertices"], recording=rec, sdk=SDK)
    scan = [(t, a, s) for t, p, a, s in rec.logged if p == "fit/scan"]
    assert len(scan) == 1 and scan[0][2] is True
    np.testing.assert_array_equal(scan[0][1].args[0], case["scan"])
    meshes = [(t, a) for t, p, a, _ in rec.logged if p == "fit/mesh"]
    assert [t for t, _ in meshes] == [0] + [i for i, _ in result.snapshots] + [result.iterations]
    np.testing.assert_array_equal(meshes[0][1].vertex_positions, case["template_vertices"])
    last = meshes[-1][1]
    np.testing.assert_array_equal(last.vertex_positions, result.vertices)
    colors, _ = core.wrinkle_colors(result.wvf_accumulated_magnitude)
    np.testing.assert_array_equal(last.vertex_colors, colors)
    assert len(np.unique(colors, axis=0)) > 10


def test_with_rerun_sdk_installed(case, tmp_path):
    rr = pytest.importorskip("rerun", reason="rerun-sdk is not installed (pip install rerun-sdk)")
    rec = rr.RecordingStream("foldmatch-test")
    rec.save(str(tmp_path / "fit.rrd"))
    result = fm.fit(
        case["template_vertices"],
        case["faces"],
        case["scan"],
        iterations=4,
        callback=viz.rerun_callback(rec),
        params={"snapshot_every": 2},
    )
    viz.log_fit(result, scan=case["scan"], recording=rec)
    rec.flush()
    assert (tmp_path / "fit.rrd").stat().st_size > 1000


def test_missing_rerun_is_named(monkeypatch):
    import builtins

    real_import = builtins.__import__

    def no_rerun(name, *args, **kwargs):
        if name == "rerun":
            raise ImportError("No module named 'rerun'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_rerun)
    with pytest.raises(ImportError, match=r"pip install rerun-sdk"):
        viz.rerun_callback()
