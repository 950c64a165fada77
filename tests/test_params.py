"""fm.FitParams and the surface of fm.fit: every Rust setting reachable by name from Python and
from the CLI, the generated reference and stub in step with the code, errors that name the
setting, and the conveniences of fm.fit (paths, Open3D objects, progress, repr)."""

from __future__ import annotations

import inspect
import json
import os
import pathlib
import pickle
import subprocess
import sys

import foldmatch_rs as fm
import numpy as np
import pytest
from foldmatch_rs import _foldmatch_rs as core
from foldmatch_rs import params_doc

ROOT = pathlib.Path(__file__).resolve().parents[1]
ENV = {**os.environ, "FOLDMATCH_NO_PROGRESS": "1", "COLUMNS": "200"}


@pytest.fixture(scope="module")
def sheet():
    return fm.folded_sheet(nx=11, ny=11, scan_points=400, noise=0.001)


def cli(*args: str, cwd: pathlib.Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "foldmatch_rs", *args],
        cwd=cwd,
        env=ENV,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def write_ply(path: pathlib.Path, v: np.ndarray, f=None, prop: tuple[str, np.ndarray] | None = None):
    lines = [
        "ply",
        "format ascii 1.0",
        f"element vertex {len(v)}",
        "property double x",
        "property double y",
        "property double z",
    ]
    if prop:
        lines.append(f"property double {prop[0]}")
    if f is not None:
        lines += [f"element face {len(f)}", "property list uchar int vertex_indices"]
    lines.append("end_header")
    for i, p in enumerate(v):
        lines.append(" ".join(repr(float(c)) for c in p) + (f" {float(prop[1][i])!r}" if prop else ""))
    if f is not None:
        lines += ["3 " + " ".join(str(int(i)) for i in t) for t in f]
    path.write_text("\n".join(lines) + "\n")


# ---- the surface is small and in sync ----------------------------------------------------


def test_fit_takes_at_most_16_parameters():
    assert len(inspect.signature(fm.fit).parameters) <= 16


def test_python_names_are_the_rust_serde_keys():
    """FitParams, the Rust struct's serde keys and the reference (read from its JSON schema)
    name the same settings (FitParams in the struct's order); every setting is an attribute with the Rust
    doc comment as its docstring."""
    rust = core.param_names()
    assert list(fm.FitParams()) == rust
    assert sorted(fm.params.SETTINGS) == sorted(rust)
    assert sorted(n for _, _, names in fm.params.GROUPS for n in names) == sorted(rust)
    assert len(rust) >= 40
    for name in rust:
        prop = getattr(fm.FitParams, name)
        assert isinstance(prop, property) and prop.__doc__.strip(), name
        assert getattr(fm.FitParams(), name) == fm.DEFAULT_PARAMS[name]


def test_every_setting_reaches_the_rust_struct(sheet):
    """Each setting set alone to a value other than its default comes back from the Rust
    struct (FitResult.params is read from the fit's own FitParams) with that value, and only
    it changes."""
    base = fm.FitParams(iterations=2, selection="single")
    other = {"int": lambda v: v + 1, "float": lambda v: v / 2 if v else 0.25, "bool": lambda v: not v}
    for name, s in fm.params.SETTINGS.items():
        value = base[name]
        if s["choices"]:
            new = next(c for c, _ in s["choices"] if c != value)
        else:
            new = other[s["type"]](value)
        if name in ("iterations", "snapshot_every", "rigid_fraction", "coarse_fraction"):
            continue  # covered by the fits below
        changed = base.replace(**{name: new})
        assert changed.to_dict() == {**base.to_dict(), name: new} != base.to_dict()
    r = fm.fit(
        sheet["template_vertices"],
        sheet["faces"],
        sheet["scan"],
        params=base.replace(psi=0.125, two_way_pull="mean", velocity_sync=False, k_min=9),
    )
    assert (r.params.psi, r.params.two_way_pull, r.params.velocity_sync, r.params.k_min) == (
        0.125,
        "mean",
        False,
        9,
    )
    assert r.params == base.replace(psi=0.125, two_way_pull="mean", velocity_sync=False, k_min=9)


def test_cli_takes_every_setting_by_name_with_the_same_defaults(tmp_path, sheet):
    """`foldmatch fit --preset paper --set KEY=VALUE` for every setting: the CLI knows every
    name, and its report's params equal Python's FitParams of the same preset and settings;
    `fit --help` lists a flag for every setting (the CLI writes no snapshots)."""
    write_ply(tmp_path / "t.ply", sheet["template_vertices"], sheet["faces"])
    write_ply(tmp_path / "s.ply", sheet["scan"])
    mine = fm.FitParams("paper", iterations=3, psi=0.1, two_way=1.5, k_min=9)
    sets = [a for k, v in mine.items() for a in ("--set", f"{k}={json.dumps(v)}")]
    out = cli(
        "fit", "t.ply", "s.ply", "-o", "o.ply", "--preset", "paper", *sets, "--report", "r.json", cwd=tmp_path
    )
    assert out.returncode == 0, out.stderr
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["params"] == mine.to_dict()
    assert fm.FitParams.from_dict(report["params"], "paper") == mine

    help_text = cli("fit", "--help", cwd=tmp_path).stdout
    flag_of = {"use_curvature": "--no-curvature", "snapshot_every": None}
    for name in fm.FitParams():
        flag = flag_of.get(name, "--" + name.replace("_", "-"))
        if flag is None:
            continue
        assert flag in help_text or "--no-" + name.replace("_", "-") in help_text, name
    bad = cli("fit", "t.ply", "s.ply", "-o", "o.ply", "--set", "no_such=1", cwd=tmp_path)
    assert bad.returncode != 0 and "no_such" in bad.stderr


def test_reference_and_stub_are_generated_from_the_code():
    """docs/parameters.md and params.pyi are what params_doc writes from the Rust doc
    comments now (run `python -m foldmatch_rs.params_doc` after changing them)."""
    assert (ROOT / params_doc.MARKDOWN).read_text() == params_doc.markdown()
    assert (ROOT / params_doc.STUB).read_text() == params_doc.stub()
    md = params_doc.markdown()
    for title, _, names in fm.params.GROUPS:
        assert f"## {title}" in md
        assert all(f"### `{n}`" in md for n in names)
    assert "| `two_way` | `4.5` | `4.5` | `3.0` | `0.0` | `2.0` |" in md


# ---- FitParams ---------------------------------------------------------------------------


def test_preset_overrides_replace_and_equality():
    p = fm.FitParams("paper", psi=0.1)
    assert (p.psi, p.two_way, p.preset_name) == (0.1, 0.0, "paper")
    assert fm.FitParams.preset("paper") == fm.FitParams("paper") == fm.PAPER_PARAMS
    q = p.replace(iterations=50)
    assert (q.iterations, q.psi, p.iterations) == (50, 0.1, 100)
    assert q.changed() == {"psi": 0.1, "iterations": 50}
    assert repr(q) == "FitParams('paper', iterations=50, psi=0.1)"
    assert eval(repr(q), {"FitParams": fm.FitParams}) == q
    assert pickle.loads(pickle.dumps(q)) == q and hash(q) == hash(p.replace(iterations=50))
    assert dict(q) == q.to_dict() and q["psi"] == 0.1
    text = str(q)
    assert all(f"  {title}:" in text for title, _, _ in fm.params.GROUPS)
    assert "*psi = 0.1" in text and " two_way = 0.0" in text
    with pytest.raises(AttributeError, match="immutable"):
        q.psi = 0.2
    with pytest.raises(AttributeError, match="no setting 'psy'"):
        q.psy  # noqa: B018
    assert fm.FitParams(psi=np.float64(0.2), iterations=np.int64(7)).iterations == 7


@pytest.mark.parametrize(
    "settings, match",
    [
        ({"psi": 3.0}, r"parameter psi = 3: must be finite with \|psi\| < 1"),
        ({"rho": float("nan")}, "parameter rho = nan: must be a finite number"),
        ({"damping": 1.5}, r"parameter damping = 1.5: must be in \[0, 1\]"),
        ({"iterations": 2.5}, "parameter iterations = 2.5: .*cannot be interpreted as an integer"),
        ({"iterations": -1}, "parameter iterations = -1: .*negative"),
        ({"normalize": "false"}, "parameter normalize = 'false': must be true or false"),
        ({"normalize": 1}, "parameter normalize = 1: must be true or false"),
        ({"selection": "best"}, "parameter selection = 'best': unknown variant `best`"),
        ({"psy": 0.1}, "parameter psy = 0.1: unknown parameter; known: method, iterations"),
    ],
)
def test_errors_name_the_setting_and_its_range(settings, match):
    with pytest.raises(fm.InvalidParameterError, match=match):
        fm.FitParams(**settings)


def test_unknown_preset_and_preset_with_params_are_refused(sheet):
    with pytest.raises(fm.InvalidParameterError, match="preset = best: one of default"):
        fm.FitParams("best")
    with pytest.raises(fm.InvalidParameterError, match="carries its preset"):
        fm.fit(
            sheet["template_vertices"], sheet["faces"], sheet["scan"], preset="paper", params=fm.FitParams()
        )


def test_keywords_override_params_and_a_dict_goes_over_the_preset(sheet):
    v, f, x = sheet["template_vertices"], sheet["faces"], sheet["scan"]
    r = fm.fit(v, f, x, preset="paper", params={"psi": 0.2, "iterations": 9}, iterations=4)
    assert r.params == fm.FitParams("paper", psi=0.2, iterations=4) and r.iterations == 4
    s = fm.fit(v, f, x, params=fm.FitParams("paper", psi=0.2, iterations=4))
    np.testing.assert_array_equal(r.vertices, s.vertices)


# ---- fm.fit as a user expects it ---------------------------------------------------------


def test_paths_are_read_by_the_crates_readers(tmp_path, sheet):
    """fm.fit("template.ply", None, "scan.ply") equals the fit of the arrays; a PLY vertex
    property or a .npy file gives the scan weights."""
    v, f, x = sheet["template_vertices"], sheet["faces"], sheet["scan"]
    w = np.where(x[:, 0] > 0, 1.0, 0.0)
    write_ply(tmp_path / "t.ply", v, f)
    write_ply(tmp_path / "s.ply", x, prop=("confidence", w))
    np.save(tmp_path / "w.npy", w)
    arrays = fm.fit(v, f, x, iterations=5, target_weights=w)
    files = fm.fit(
        str(tmp_path / "t.ply"), None, tmp_path / "s.ply", iterations=5, target_weights="confidence"
    )
    np.testing.assert_array_equal(arrays.vertices, files.vertices)
    npy = fm.fit(tmp_path / "t.ply", None, x, iterations=5, target_weights=tmp_path / "w.npy")
    np.testing.assert_array_equal(arrays.vertices, npy.vertices)
    with pytest.raises(fm.MeshFileError, match="missing.ply"):
        fm.fit(tmp_path / "missing.ply", None, x)
    with pytest.raises(fm.InvalidInputError, match="needs the target as a .ply path"):
        fm.fit(v, f, x, target_weights="confidence")


class Vector3dVector:
    """Open3D's vector type as NumPy sees it: only the buffer protocol (np.asarray)."""

    def __init__(self, a):
        self._a = np.asarray(a)

    def __array__(self, dtype=None, copy=None):
        return self._a if dtype is None else self._a.astype(dtype)


class TriangleMesh:  # open3d.geometry.TriangleMesh: .vertices and .triangles
    def __init__(self, v, f):
        self.vertices, self.triangles = Vector3dVector(v), Vector3dVector(f)


class PointCloud:  # open3d.geometry.PointCloud: .points
    def __init__(self, x):
        self.points = Vector3dVector(x)


def test_open3d_meshes_and_point_clouds_are_taken_like_trimesh_ones(sheet):
    v, f, x = sheet["template_vertices"], sheet["faces"], sheet["scan"]
    a = fm.fit(v, f, x, iterations=5)
    b = fm.fit(TriangleMesh(v, f), None, PointCloud(x), iterations=5)
    np.testing.assert_array_equal(a.vertices, b.vertices)
    np.testing.assert_array_equal(b.faces, f)


def test_progress_bar_on_stderr_with_a_callback(sheet, capsys, monkeypatch):
    """progress=True draws a bar on stderr ending at the last iteration and still calls the
    user's callback (whose False stops the fit); off by default when stderr is no terminal."""
    monkeypatch.setitem(sys.modules, "tqdm", None)  # the built-in line, whatever is installed
    seen = []
    r = fm.fit(
        sheet["template_vertices"],
        sheet["faces"],
        sheet["scan"],
        iterations=6,
        progress=True,
        callback=lambda info: seen.append(info["iteration"]) or len(seen) < 4,
    )
    err = capsys.readouterr().err
    assert seen == [1, 2, 3, 4] and r.iterations == 4
    assert "fit 4/6 [" in err and err.endswith("\n")
    fm.fit(sheet["template_vertices"], sheet["faces"], sheet["scan"], iterations=3)
    assert capsys.readouterr().err == ""


def test_fit_result_repr_is_one_short_line(sheet):
    r = fm.fit(sheet["template_vertices"], sheet["faces"], sheet["scan"], iterations=4)
    text = repr(r)
    assert "\n" not in text and len(text) < 200
    assert text.startswith("FitResult(vertices=(121, 3), faces=(200, 3), iterations=4, ")
    assert f"schedule={r.diagnostics['schedule']!r}" in text
    assert text.endswith("params=FitParams('default', iterations=4))")


def test_cluster_runs_take_params_like_fit(tmp_path):
    """distributed.fit_batch's request carries a FitParams' preset and settings (keywords
    over them), as fm.fit takes them."""
    pytest.importorskip("distributed")
    from foldmatch_rs import distributed

    def request(**params):
        return distributed._request(
            "batch",
            tmp_path / "t.ply",
            tmp_path,
            tmp_path / "out",
            resume=False,
            preset="default",
            recursive=False,
            glob=None,
            format="ply",
            ascii=False,
            gt_dir=None,
            params=params,
        )

    r = request(params=fm.FitParams("paper", psi=0.1), iterations=7)
    assert r["preset"] == "paper"
    assert r["params"] == {**fm.FitParams("paper", psi=0.1).to_dict(), "iterations": 7}
    assert request(params={"psi": 0.2}, psi=0.3)["params"] == {"psi": 0.3}
