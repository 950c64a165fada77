"""The physically simulated cases of the harness (issue 28; docs/simulated.md): group ``sim``.

Each scene of bench/sim_cloth.py gives one rest mesh and its simulated final state (vertex
*i* of the rest mesh is particle *i*: the per-vertex ground truth). Two cases per scene:

* ``sim-{scene}-mesh``: the target is the simulated mesh itself (vertices + faces, as the real
  ``-mesh`` cases of bench/cases.py);
* ``sim-{scene}-scan``: what a camera rig sees of it (:func:`scan_target`): 24 pinhole
  cameras around the scene (bench/dressed_scans.py's scanner: exact visibility, so the cloth's
  underside, what the colliders hide and what lies on the ground are missing), the cloth's
  points only (a segmented scan), thinned to at most :data:`SCAN_POINTS` points, Gaussian
  noise σ = 0.2 % of the bounding-box diagonal, two holes of radius 6 % of the diagonal, and
  1 % outliers spread uniformly over the bounding box grown by 10 %.

The template is the rest mesh placed as bench/cases.py places the real templates: the
least-squares similarity onto the truth (Umeyama 1991), the same placed template for every
method, so the comparison measures the non-rigid fit only.

The states are read from ``bench/data/sim/`` (bench/sim_cloth.py's stored states; running the simulator
needs ``pip install -r bench/requirements-sim.txt``). :func:`tiny_case` is the CI case, read
from the stored ``bench/data/sim-sphere-tiny.npz`` (no simulator needed).
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import pathlib
import sys
from collections.abc import Iterator
from typing import Any

import numpy as np

from bench import cases as cases_mod
from bench import sim_cloth

HERE = pathlib.Path(__file__).resolve().parent
#: The stored tiny simulated state for CI (python -m bench.sim --store-tiny).
TINY = HERE / "data" / "sim-sphere-tiny.npz"

#: Scan settings, relative to the truth's bounding-box diagonal (noise, holes, outliers) or in
#: metres (the scanner's rig: every scene is about a metre across).
SCAN_NOISE = 0.002
SCAN_HOLES = 2
SCAN_HOLE_RADIUS = 0.06
SCAN_OUTLIERS = 0.01
SCANNER = {
    "rings": 3,
    "azimuths": 8,
    "radius": 2.0,
    "heights": (-0.2, 0.4, 1.0),  # above the ground: the scenes stand on it
    "pixel": 0.003,
    "voxel": 0.005,
    "noise": 0.0,  # added below, relative to the diagonal
    "holes": 0,  # made below, relative to the diagonal
    "hole_radius": 0.0,
}
#: At most this many scan points: the generated cases' counts (bench/cases.py SCAN_POINTS).
SCAN_POINTS = {"small": 2000, "paper": 14400}
PAPER_SCENES = ("dress",)


def scan_target(
    truth: np.ndarray,
    faces: np.ndarray,
    occluders: list[tuple[np.ndarray, np.ndarray]],
    most: int,
    seed: int,
) -> tuple[np.ndarray, dict[str, Any]]:
    """The scan of the cloth ``(truth, faces)`` seen among ``occluders`` (see the module's
    docstring); returns the points and a description."""
    from bench import dressed_scans

    rng = np.random.default_rng(seed)
    meshes = [(truth, faces, 1)] + [(v, f, 0) for v, f in occluders]
    s = dressed_scans.scan(meshes, units=1.0, seed=seed, up=2, settings=SCANNER)
    pts = s.points[s.labels == 1]
    seen = len(pts)
    if len(pts) > most:
        pts = pts[np.sort(rng.choice(len(pts), most, replace=False))]
    diag = cases_mod.bbox_diagonal(truth)
    pts = pts + rng.normal(scale=SCAN_NOISE * diag, size=pts.shape)
    keep = np.ones(len(pts), bool)
    for c in pts[rng.choice(len(pts), SCAN_HOLES, replace=False)]:
        keep &= np.linalg.norm(pts - c, axis=1) > SCAN_HOLE_RADIUS * diag
    pts = pts[keep]
    lo, hi = truth.min(0), truth.max(0)
    pad = 0.1 * (hi - lo)
    n_out = int(round(SCAN_OUTLIERS * len(pts)))
    outliers = rng.uniform(lo - pad, hi + pad, size=(n_out, 3))
    pts = np.concatenate([pts, outliers])
    info = {
        "variant": "camera scan: 24 cameras, cloth points only, noise 0.2 %, 2 holes, 1 % outliers",
        "visible_points": int(seen),
        "removed_by_holes": int((~keep).sum()),
        "outliers": n_out,
        "noise_sigma_rel": SCAN_NOISE,
        "points": int(len(pts)),
    }
    return np.ascontiguousarray(pts[rng.permutation(len(pts))]), info


#: Scans already made (the camera rig is the slow part of building the cases), keyed by the
#: truth, the occluders and every scan setting.
SCANS = sim_cloth.OUT / "scans"


def cached_scan(
    truth: np.ndarray,
    faces: np.ndarray,
    occluders: list[tuple[np.ndarray, np.ndarray]],
    most: int,
    seed: int,
) -> tuple[np.ndarray, dict[str, Any]]:
    """:func:`scan_target`, read from :data:`SCANS` when the same scan was made before."""
    h = hashlib.sha1()
    for a in (truth, faces, *[x for v_f in occluders for x in v_f]):
        h.update(np.ascontiguousarray(a).tobytes())
    settings = [SCANNER, SCAN_NOISE, SCAN_HOLES, SCAN_HOLE_RADIUS, SCAN_OUTLIERS, most, seed]
    h.update(json.dumps(settings, sort_keys=True, default=str).encode())
    path = SCANS / f"{h.hexdigest()[:16]}.npz"
    if path.is_file():
        with np.load(path) as z:
            return z["points"], json.loads(str(z["info"]))
    pts, info = scan_target(truth, faces, occluders, most, seed)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, points=pts, info=json.dumps(info))
    tmp.replace(path)
    return pts, info


def placed_template(rest: np.ndarray, truth: np.ndarray) -> tuple[np.ndarray, dict[str, float]]:
    """The rest mesh moved by the least-squares similarity onto the truth (bench/cases.py)."""
    s, r, t = cases_mod.umeyama(rest, truth)
    angle = float(np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1))))
    return rest @ (s * r).T + t, {"scale": round(s, 4), "rotation_deg": round(angle, 1)}


def cases_of(
    name: str,
    sim: sim_cloth.SimResult,
    occluders: list[tuple[np.ndarray, np.ndarray]],
    most: int,
    seed: int,
    group: str = "sim",
    kinds: tuple[str, ...] = ("mesh", "scan"),
    cache: bool = True,
) -> Iterator[cases_mod.Case]:
    """The cases of one simulated state (see the module's docstring); ``cache``: read and keep
    the scan in :data:`SCANS`."""
    truth = np.asarray(sim.final, float)
    faces = np.asarray(sim.faces, np.int64)
    placed, pre = placed_template(np.asarray(sim.rest, float), truth)
    meta = {
        "source": f"simulated (bench/sim_cloth.py, scene {name})",
        "up": 2,
        "prealign": pre,
        "simulator": sim.info.get("simulator"),
        "edge_ratio_p01_p50_p99": sim.info.get("edge_ratio_p01_p50_p99"),
    }
    if "mesh" in kinds:
        yield cases_mod.Case(
            f"sim-{name}-mesh", group, placed, faces, truth, faces, truth, {**meta, "variant": "mesh target"}
        )
    if "scan" in kinds:
        make = cached_scan if cache else scan_target
        pts, info = make(truth, faces, occluders, most, seed)
        yield cases_mod.Case(f"sim-{name}-scan", group, placed, faces, pts, None, truth, {**meta, **info})


def sim_cases(
    scenes: tuple[str, ...] | None = None, simulate: bool | None = None
) -> Iterator[cases_mod.Case]:
    """The cases of every scene (``scenes``: a subset; all of :data:`sim_cloth.SCENES` keep
    their order, so each keeps its scan seed), from the cache of bench/sim_cloth.py. With
    ``simulate`` (default: when Newton is installed) a scene whose state is missing or was made
    with other settings is simulated; without, the cached state is read whatever its settings
    and a missing one is skipped with a message."""
    if simulate is None:
        simulate = importlib.util.find_spec("newton") is not None
    order = list(sim_cloth.SCENES)
    for name in scenes or tuple(order):
        i = order.index(name)
        scene = sim_cloth.SCENES[name]
        sim = sim_cloth.simulate_cached(scene) if simulate else cached_state(scene)
        if sim is None:
            continue
        size = "paper" if name in PAPER_SCENES else "small"
        yield from cases_of(name, sim, sim_cloth.collider_meshes(scene), SCAN_POINTS[size], seed=2800 + i)


def cached_state(scene: sim_cloth.Scene) -> sim_cloth.SimResult | None:
    """The stored state of a scene whatever its key (no Newton needed), or None."""
    sim = sim_cloth.load_state(scene)
    if sim is None:
        print(
            f"group sim: {scene.name}: no simulated state in {sim_cloth.STATES} (python -m bench.sim_cloth)",
            file=sys.stderr,
        )
    return sim


def load_tiny(path: pathlib.Path = TINY) -> sim_cloth.SimResult:
    """The stored tiny simulated state (a 17 × 17 sheet dropped on a sphere)."""
    sim = sim_cloth.load_state(sim_cloth.SMALL, path)
    if sim is None:
        raise FileNotFoundError(f"{path}: no stored tiny state (python -m bench.sim --store-tiny)")
    return sim


def store_tiny(path: pathlib.Path = TINY) -> sim_cloth.SimResult:
    """Simulate :data:`sim_cloth.SMALL` and store it at ``path`` with its generation command
    and settings."""
    r = sim_cloth.simulate(sim_cloth.SMALL)
    r.info["command"] = "python -m bench.sim --store-tiny"
    r.info["key"] = sim_cloth.settings_key(sim_cloth.SMALL)
    sim_cloth.save_state(sim_cloth.SMALL, r, path)
    return load_tiny(path)


def tiny_case(kind: str = "scan") -> cases_mod.Case:
    """The CI case: the stored tiny sphere drape as a scan (400 points) or as a mesh target."""
    sim = load_tiny()
    occ = sim_cloth.collider_meshes(sim_cloth.SMALL)
    made = cases_of("sphere-tiny", sim, occ, 400, seed=2799, group="sim-tiny", kinds=(kind,), cache=False)
    return next(made)
