"""Preview images from Python (``fm.render``, ``FitResult.preview``: the Rust renderer of
``foldmatch fit --preview``) and one PLY layout and color scale of the wrinkle field whether
the CLI or ``FitResult.to_trimesh().export`` writes it."""

from __future__ import annotations

import subprocess
import sys

import foldmatch_rs as fm
import numpy as np
import pytest
from foldmatch_rs import _foldmatch_rs as core

PANEL = 96


@pytest.fixture(scope="module")
def case():
    return fm.folded_sheet(nx=21, ny=21, scan_points=1500)


@pytest.fixture(scope="module")
def fitted(case):
    return fm.fit(case["template_vertices"], case["faces"], case["scan"], iterations=30)


def viridis() -> np.ndarray:
    colors, _ = core.wrinkle_colors(np.linspace(0.0, 1.0, 256))
    return colors.astype(float)


def off_viridis(pixels: np.ndarray) -> np.ndarray:
    """Distance of each pixel from the nearest viridis color shaded by a factor in [0.3, 1]."""
    table = viridis()
    p = pixels.astype(float)[:, None, :]
    s = np.clip((p * table).sum(-1) / (table * table).sum(-1), 0.3, 1.0)[..., None]
    return np.sqrt(((p - s * table) ** 2).sum(-1)).min(1)


def colored(panel: np.ndarray) -> np.ndarray:
    """The pixels of a panel that are neither background nor gray."""
    flat = panel.reshape(-1, 3).astype(int)
    return flat[(flat.max(1) - flat.min(1)) > 24]


def test_render_draws_the_field_and_writes_the_same_png(case, fitted, tmp_path):
    from PIL import Image

    path = tmp_path / "fit.png"
    image = fitted.preview(path, scan=case["scan"], size=PANEL, views=("front", "back"))
    assert image.dtype == np.uint8
    assert image.shape == (3 * PANEL, 2 * PANEL + 96, 3)
    np.testing.assert_array_equal(np.asarray(Image.open(path).convert("RGB")), image)
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 200
    white = (image == 255).all(-1).mean()
    assert 0.2 < white < 0.95
    field_row = image[PANEL : 2 * PANEL, :PANEL]
    mesh = colored(field_row)
    assert len(mesh) > PANEL * PANEL / 20
    assert (off_viridis(mesh) < 12).mean() > 0.95
    distance_row = colored(image[2 * PANEL :, :PANEL])
    assert (off_viridis(distance_row) < 12).mean() < 0.5


def test_the_field_decides_the_mesh_colors(fitted):
    args = (fitted.vertices, fitted.faces)
    with_field = fm.render(*args, field=fitted.wvf_accumulated, size=PANEL, views=("front",))
    magnitudes = fm.render(*args, field=fitted.wvf_accumulated_magnitude, size=PANEL, views=("front",))
    plain = fm.render(*args, size=PANEL, views=("front",))
    # A field given as vectors or as their magnitudes is drawn alike; without one the mesh
    # is gray and there is no color bar.
    np.testing.assert_array_equal(with_field, magnitudes)
    assert with_field.shape == plain.shape == (PANEL, PANEL + 96, 3)
    assert len(colored(with_field[:, :PANEL])) > PANEL * PANEL / 20
    assert len(colored(plain)) == 0
    # A different field paints the mesh differently.
    flipped = fm.render(*args, field=-fitted.wvf_accumulated_magnitude, size=PANEL, views=("front",))
    assert (flipped[:, :PANEL] != with_field[:, :PANEL]).any(-1).mean() > 0.05


def test_render_errors_name_the_input(fitted):
    with pytest.raises(fm.InvalidParameterError, match="views"):
        fm.render(fitted.vertices, fitted.faces, views=("top",))
    with pytest.raises(fm.InvalidParameterError, match="panel"):
        fm.render(fitted.vertices, fitted.faces, size=8)
    with pytest.raises(fm.InvalidInputError, match="field"):
        fm.render(fitted.vertices, fitted.faces, field=np.ones(3))
    with pytest.raises(fm.InvalidInputError, match="faces"):
        fm.render(fitted.vertices, np.array([[0, 1, 10**6]]))


def ply_vertices(path):
    """The header's vertex property lines and the vertex table of a PLY file."""
    trimesh = pytest.importorskip("trimesh")
    header = path.read_bytes().split(b"end_header")[0].decode()
    properties = [
        line.split()[1:] for line in header.splitlines() if line.startswith("property") and "list" not in line
    ]
    raw = trimesh.load(path, process=False).metadata["_ply_raw"]["vertex"]["data"]
    return properties, raw


@pytest.fixture(scope="module")
def cli_fit(case, tmp_path_factory):
    """The CLI's fitted PLY of the case and a FitResult holding its vertices and field."""
    trimesh = pytest.importorskip("trimesh")
    d = tmp_path_factory.mktemp("cli")
    trimesh.Trimesh(case["template_vertices"], case["faces"], process=False).export(d / "template.ply")
    trimesh.PointCloud(case["scan"]).export(d / "scan.ply")
    subprocess.run(
        [
            sys.executable,
            "-m",
            "foldmatch_rs",
            "fit",
            "template.ply",
            "scan.ply",
            "-o",
            "cli.ply",
            "--iterations",
            "10",
            "-q",
        ],
        cwd=d,
        check=True,
    )
    properties, cli = ply_vertices(d / "cli.ply")
    wvf = np.column_stack([cli["wvf_x"], cli["wvf_y"], cli["wvf_z"]])
    magnitude = np.ascontiguousarray(cli["wvf_magnitude"])
    result = fm.FitResult(
        vertices=np.column_stack([cli["x"], cli["y"], cli["z"]]),
        faces=case["faces"],
        wvf=wvf,
        wvf_magnitude=magnitude,
        wvf_accumulated=wvf,
        wvf_accumulated_magnitude=magnitude,
        iterations=10,
        history={},
    )
    return d / "cli.ply", properties, cli, result


def test_save_writes_the_cli_file_byte_for_byte(cli_fit, tmp_path):
    path, _, _, result = cli_fit
    result.save(tmp_path / "py.ply")
    assert (tmp_path / "py.ply").read_bytes() == path.read_bytes()


def test_to_trimesh_export_has_the_cli_properties_and_colors(cli_fit, tmp_path):
    """trimesh's exporter writes float coordinates and an alpha column of its own; everything
    else — the property names and their order, the colors, the field — is the CLI's."""
    _, cli_properties, cli, result = cli_fit
    result.to_trimesh().export(tmp_path / "py.ply")
    py_properties, py = ply_vertices(tmp_path / "py.ply")
    assert [n for _, n in py_properties if n != "alpha"] == [n for _, n in cli_properties]
    assert [n for _, n in cli_properties][-4:] == ["wvf_x", "wvf_y", "wvf_z", "wvf_magnitude"]
    for name in ("red", "green", "blue", "wvf_x", "wvf_y", "wvf_z", "wvf_magnitude"):
        np.testing.assert_array_equal(py[name], cli[name], err_msg=name)
    np.testing.assert_allclose(py["x"], cli["x"], rtol=1e-6)
    # The colors are the shared scale of the magnitudes, and they vary with them.
    colors, (lo, hi) = core.wrinkle_colors(np.ascontiguousarray(cli["wvf_magnitude"]))
    np.testing.assert_array_equal(colors, np.column_stack([cli["red"], cli["green"], cli["blue"]]))
    assert lo < hi and len(np.unique(colors, axis=0)) > 10
