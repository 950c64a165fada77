"""Physically simulated cloth for the harness (issue 28): the scenes and the simulator run.

Each scene is a rest mesh (a flat sheet or an open tube, the garment as cut), rigid colliders
and a short script (drop, pin, gather, blow); the simulator drapes it and the final particle
positions are the per-vertex ground truth: vertex *i* of the rest mesh is particle *i*. The
cases built from these states (placement, clean mesh and scan targets) are
bench/sim_cases.py's; the simulator is only needed to regenerate them (docs/simulated.md).

Simulator: Newton (``pip install newton``, NVIDIA's GPU-optional physics engine on Warp; the
successor of ``warp.sim``, which warp-lang ≥ 1.10 no longer ships), its vertex block descent
cloth solver (``SolverVBD``: neo-Hookean membrane, dihedral bending, implicit contact with the
colliders, optional cloth self-contact) run on Warp's ``"cpu"`` device. Units: metres,
seconds, z up, gravity −9.81 m/s².

Scenes (:data:`SCENES`):

* ``sphere``: a 1 m square sheet (41 × 41) dropped flat from 0.75 m onto a sphere of radius
  0.25 m whose top is at 0.6 m; the corners reach the ground.
* ``box``: a 1.3 m table cloth (45 × 45) dropped onto a 0.7 × 0.7 × 0.5 m box (a table).
* ``heap``: a 0.8 m sheet (33 × 33) standing on its edge, thrown down into itself (its top at
  1.5 m/s, a smooth random sideways velocity field drawn from the seed starts the buckling):
  it collapses into a heap of folds, with cloth self-contact on.
* ``flag``: a 1.0 × 0.6 m flag (41 × 25), its pole edge pinned, blown by a gusty wind (the
  mean wind along +x, gusts every ≈0.3 s and a travelling ripple, all from the seed); the
  state after 1.5 s.
* ``skirt``: an open tube of radius 0.22 m and length 0.5 m (64 × 25) around a capsule body
  (radius 0.14 m); its waist ring is pinned and drawn in to radius 0.15 m (gathered) over the
  first 0.5 s, and the skirt falls onto the body.
* ``dress``: the paper-size case: an open tube of radius 0.26 m and length 1.0 m (160 × 70,
  11,200 vertices) whose top ring is drawn in to 0.17 m on a capsule torso with spherical
  hips (radius 0.2 m).

Every scene is deterministic for its seed (CPU kernels, fixed script); the cache key holds
the scene's settings and Newton's version.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import pathlib
import sys
import time
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from bench import cases as cases_mod

HERE = pathlib.Path(__file__).resolve().parent
#: The simulated states (one compact .npz per scene, kept in the repository so that the harness
#: needs no simulator), written by :func:`simulate_cached`.
STATES = HERE / "data" / "sim"
#: Runs made on the states (bench/sim.py's peers).
OUT = HERE / "out" / "sim"
#: Bump when the scripts change (invalidates the cache).
VERSION = 1


@dataclass(frozen=True)
class Collider:
    """A static rigid collider: ``kind`` sphere (radius), box (half extents) or capsule
    (radius, half height of the cylinder part, along z), centred at ``centre``."""

    kind: str
    centre: tuple[float, float, float]
    size: tuple[float, ...]


@dataclass(frozen=True)
class Scene:
    name: str
    mesh: str  # "sheet" or "tube"
    n_u: int
    n_v: int
    width: float  # sheet: side along u; tube: radius
    height: float  # sheet: side along v; tube: length
    origin: tuple[float, float, float]  # sheet: centre; tube: centre of the top ring
    colliders: tuple[Collider, ...]
    frames: int
    seed: int = 0
    fps: int = 60
    substeps: int = 5
    iterations: int = 10
    density: float = 0.5  # kg/m²
    stretch: float = 1.0e4  # membrane stiffness (tri_ke = tri_ka)
    bending: float = 1.0e-2  # dihedral bending stiffness (edge_ke)
    damping: float = 1.0e-1  # membrane damping (tri_kd)
    air_damping: float = 0.02  # share of every velocity removed per frame
    self_contact: bool = False
    vertical: bool = False  # sheet: hang in the x-z plane (a flag) instead of lying flat
    script: str = "drop"  # drop, crumple, wind, gather
    gather_radius: float = 0.0  # gather: the waist ring's final radius
    gather_frames: int = 30
    wind: float = 0.0  # wind: mean acceleration along +x, m/s²

    @property
    def vertices(self) -> int:
        return self.n_u * self.n_v


SPHERE = Collider("sphere", (0.0, 0.0, 0.35), (0.25,))
TABLE = Collider("box", (0.0, 0.0, 0.25), (0.35, 0.35, 0.25))
BODY = Collider("capsule", (0.0, 0.0, 0.55), (0.14, 0.3))
TORSO = Collider("capsule", (0.0, 0.0, 1.05), (0.15, 0.25))
HIPS = Collider("sphere", (0.0, 0.0, 0.72), (0.2,))

SCENES: dict[str, Scene] = {
    s.name: s
    for s in (
        Scene("sphere", "sheet", 41, 41, 1.0, 1.0, (0.0, 0.0, 0.75), (SPHERE,), frames=120),
        Scene("box", "sheet", 45, 45, 1.3, 1.3, (0.0, 0.0, 0.6), (TABLE,), frames=120),
        Scene(
            "heap",
            "sheet",
            33,
            33,
            0.8,
            0.8,
            (0.0, 0.0, 0.42),
            (),
            frames=100,
            seed=3,
            self_contact=True,
            vertical=True,
            script="crumple",
            bending=5.0e-3,
        ),
        Scene(
            "flag",
            "sheet",
            41,
            25,
            1.0,
            0.6,
            (0.5, 0.0, 1.2),
            (),
            frames=90,
            seed=5,
            vertical=True,
            script="wind",
            wind=12.0,
            air_damping=0.0,
        ),
        Scene(
            "skirt",
            "tube",
            64,
            25,
            0.22,
            0.5,
            (0.0, 0.0, 0.8),
            (BODY,),
            frames=100,
            script="gather",
            gather_radius=0.15,
        ),
        Scene(
            "dress",
            "tube",
            160,
            70,
            0.26,
            1.0,
            (0.0, 0.0, 1.3),
            (TORSO, HIPS),
            frames=90,
            script="gather",
            gather_radius=0.17,
        ),
    )
}
#: The small scene regenerated by the tests when Newton is installed, and stored as a compact
#: case in bench/data/ for CI (bench/sim_cases.py).
SMALL = Scene("sphere-tiny", "sheet", 17, 17, 1.0, 1.0, (0.0, 0.0, 0.75), (SPHERE,), frames=90, substeps=5)


def rest_mesh(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """The rest (undraped) mesh: vertex ``v * n_u + u`` of a flat sheet or an open tube, faces
    with alternating diagonals (``bench/cases.py``'s :func:`grid_faces`)."""
    u = np.linspace(0.0, 1.0, scene.n_u, endpoint=scene.mesh == "sheet")
    v = np.linspace(0.0, 1.0, scene.n_v)
    uu, vv = np.meshgrid(u, v)
    o = np.asarray(scene.origin, float)
    if scene.mesh == "sheet":
        a = (uu - 0.5) * scene.width
        b = (vv - 0.5) * scene.height
        if scene.vertical:  # the pole edge u = 0 at x = origin - width/2, v runs down
            pts = np.stack([a, np.zeros_like(a), -b], -1)
        else:
            pts = np.stack([a, b, np.zeros_like(a)], -1)
        faces = cases_mod.grid_faces(scene.n_u, scene.n_v, periodic_u=False)
    elif scene.mesh == "tube":
        th = 2 * np.pi * uu
        pts = np.stack([scene.width * np.cos(th), scene.width * np.sin(th), -scene.height * vv], -1)
        faces = cases_mod.grid_faces(scene.n_u, scene.n_v, periodic_u=True)
    else:
        raise ValueError(f"scene {scene.name}: unknown mesh kind {scene.mesh!r}")
    return pts.reshape(-1, 3) + o, faces


def pinned(scene: Scene) -> np.ndarray:
    """Indices of the kinematic vertices: the flag's pole edge, the tubes' top ring."""
    if scene.script == "wind":
        return np.arange(scene.n_v) * scene.n_u
    if scene.script == "gather":
        return np.arange(scene.n_u)
    return np.zeros(0, np.int64)


def settings_key(scene: Scene) -> str:
    import newton

    blob = json.dumps([VERSION, asdict(scene), newton.__version__], sort_keys=True)
    return hashlib.sha1(blob.encode()).hexdigest()[:12]


@dataclass
class SimResult:
    rest: np.ndarray
    faces: np.ndarray
    final: np.ndarray
    pinned: np.ndarray
    info: dict[str, Any] = field(default_factory=dict)
    #: The positions after every ``record_every``-th frame (``simulate(..., record_every=k)``),
    #: shape (frames, vertices, 3); None when not recorded.
    frames: np.ndarray | None = None


def _wind_field(scene: Scene, rng: np.random.Generator) -> Any:
    """The flag's wind, an acceleration per particle at time t: a mean along +x, gusts (a sum
    of three sines of random periods 0.25–0.6 s) and a ripple travelling along the flag."""
    periods = rng.uniform(0.25, 0.6, 3)
    phases = rng.uniform(0, 2 * np.pi, 3)
    lateral = rng.uniform(-0.3, 0.3)

    def accel(t: float, x: np.ndarray) -> np.ndarray:
        gust = 1.0 + 0.6 * np.mean(np.sin(2 * np.pi * t / periods + phases))
        ripple = 0.5 * np.sin(6.0 * x[:, 0] - 9.0 * t + phases[0]) * np.cos(4.0 * x[:, 2] + phases[1])
        a = np.zeros_like(x)
        a[:, 0] = scene.wind * gust * (1.0 + ripple)
        a[:, 1] = scene.wind * (lateral + 0.4 * ripple)
        return a

    return accel


def simulate(scene: Scene, verbose: bool = False, record_every: int = 0) -> SimResult:
    """Run the scene on Warp's CPU device; returns the rest mesh, the final positions and the
    run's figures (seconds, the largest speed at the end, edge-length ratios); with
    ``record_every`` = k > 0 also the positions after frames k, 2k, … (``SimResult.frames``)."""
    import warp as wp

    wp.config.quiet = True
    import newton

    rng = np.random.default_rng(scene.seed)
    rest, faces = rest_mesh(scene)
    pins = pinned(scene)
    t0 = time.perf_counter()
    b = newton.ModelBuilder()
    b.add_ground_plane()
    for c in scene.colliders:
        xf = wp.transform(wp.vec3(*c.centre), wp.quat_identity())
        if c.kind == "sphere":
            b.add_shape_sphere(-1, xform=xf, radius=c.size[0])
        elif c.kind == "box":
            b.add_shape_box(-1, xform=xf, hx=c.size[0], hy=c.size[1], hz=c.size[2])
        elif c.kind == "capsule":
            b.add_shape_capsule(-1, xform=xf, radius=c.size[0], half_height=c.size[1])
        else:
            raise ValueError(f"scene {scene.name}: unknown collider {c.kind!r}")
    edge = float(np.median(np.linalg.norm(rest[faces[:, 0]] - rest[faces[:, 1]], axis=1)))
    b.add_cloth_mesh(
        pos=wp.vec3(0.0, 0.0, 0.0),
        rot=wp.quat_identity(),
        scale=1.0,
        vel=wp.vec3(0.0, 0.0, 0.0),
        vertices=[wp.vec3(*p) for p in rest],
        indices=faces.reshape(-1).tolist(),
        density=scene.density,
        tri_ke=scene.stretch,
        tri_ka=scene.stretch,
        tri_kd=scene.damping,
        edge_ke=scene.bending,
        edge_kd=0.0,
        particle_radius=0.3 * edge,
    )
    for i in pins:
        b.particle_mass[i] = 0.0
        b.particle_flags[i] = b.particle_flags[i] & ~newton.ParticleFlags.ACTIVE
    b.color(include_bending=True)
    model = b.finalize(device="cpu")
    model.soft_contact_ke = 1.0e3
    model.soft_contact_kd = 1.0e-2
    model.soft_contact_mu = 0.5
    kw: dict[str, Any] = {"iterations": scene.iterations}
    if scene.self_contact:
        kw.update(
            particle_enable_self_contact=True,
            particle_self_contact_radius=0.2 * edge,
            particle_self_contact_margin=0.35 * edge,
        )
    solver = newton.solvers.SolverVBD(model, **kw)
    s0, s1, control = model.state(), model.state(), model.control()
    pipe = newton.CollisionPipeline(model)
    contacts = pipe.contacts()
    mass = model.particle_mass.numpy().copy()

    if scene.script == "crumple":
        # the standing sheet falls into itself: down at 1.5 m/s, with a smooth random sideways
        # field (three sines of random wave vectors and phases) that starts the buckling
        r = rest - rest.mean(0)
        k = rng.normal(size=(3, 3)) * 6.0
        ph = rng.uniform(0, 2 * np.pi, 3)
        vel = np.zeros_like(rest)
        vel[:, 1] = 0.6 * np.sin(r @ k + ph).sum(1)
        vel[:, 0] = 0.2 * np.sin(r @ k[::-1] + ph).sum(1)
        vel[:, 2] = -1.5 * (r[:, 2] - r[:, 2].min()) / np.ptp(r[:, 2])
        s0.particle_qd.assign(vel.astype(np.float32))
    wind = _wind_field(scene, rng) if scene.script == "wind" else None
    ring = rest[pins] if scene.script == "gather" else None

    dt = 1.0 / scene.fps / scene.substeps
    build_s = time.perf_counter() - t0
    recorded: list[np.ndarray] = []
    for frame in range(scene.frames):
        if ring is not None and frame <= scene.gather_frames:
            share = min(1.0, frame / scene.gather_frames)
            radius = scene.width + share * (scene.gather_radius - scene.width)
            xy = ring[:, :2] - np.asarray(scene.origin[:2])
            target = ring.copy()
            target[:, :2] = np.asarray(scene.origin[:2]) + xy * (radius / scene.width)
            q = s0.particle_q.numpy()
            q[pins] = target
            s0.particle_q.assign(q)
        for sub in range(scene.substeps):
            s0.clear_forces()
            if wind is not None:
                f = s0.particle_f.numpy()
                t = (frame * scene.substeps + sub) * dt
                f[:] = (mass[:, None] * wind(t, s0.particle_q.numpy().astype(float))).astype(np.float32)
                s0.particle_f.assign(f)
            pipe.collide(s0, contacts)
            solver.step(s0, s1, control, contacts, dt)
            s0, s1 = s1, s0
        if scene.air_damping > 0:
            qd = s0.particle_qd.numpy()
            s0.particle_qd.assign(qd * (1.0 - scene.air_damping))
        if record_every > 0 and (frame + 1) % record_every == 0:
            recorded.append(s0.particle_q.numpy().astype(float))
        if verbose and frame % 30 == 0:
            speed = np.linalg.norm(s0.particle_qd.numpy(), axis=1).max()
            print(
                f"  {scene.name}: frame {frame}, {time.perf_counter() - t0:.0f} s, max speed {speed:.3f} m/s"
            )
    final = s0.particle_q.numpy().astype(float)
    if not np.isfinite(final).all():
        raise RuntimeError(f"scene {scene.name}: the simulation diverged (non-finite positions)")
    ratios = edge_ratios(rest, final, faces, pins)
    info = {
        "simulator": f"newton {newton.__version__} (warp {wp.__version__}), SolverVBD on cpu",
        "seconds": round(time.perf_counter() - t0, 1),
        "build_seconds": round(build_s, 1),
        "final_max_speed": round(float(np.linalg.norm(s0.particle_qd.numpy(), axis=1).max()), 4),
        "edge_ratio_p01_p50_p99": [round(float(x), 4) for x in np.percentile(ratios, [1, 50, 99])],
        "scene": asdict(scene),
    }
    frames = np.stack(recorded) if recorded else None
    return SimResult(rest, faces, final, pins, info, frames)


def edge_ratios(rest: np.ndarray, final: np.ndarray, faces: np.ndarray, pins: np.ndarray) -> np.ndarray:
    """Final ÷ rest length of every mesh edge that does not join two pinned vertices (the
    gathered waist ring is shortened by the script, not by the cloth)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    free = ~(np.isin(e[:, 0], pins) & np.isin(e[:, 1], pins))
    e = e[free]
    return np.linalg.norm(final[e[:, 0]] - final[e[:, 1]], axis=1) / np.linalg.norm(
        rest[e[:, 0]] - rest[e[:, 1]], axis=1
    )


def collider_distance(points: np.ndarray, colliders: tuple[Collider, ...]) -> np.ndarray:
    """Signed distance of every point to the union of the colliders and the ground (z = 0):
    negative inside."""
    d = points[:, 2].copy()
    for c in colliders:
        p = points - np.asarray(c.centre)
        if c.kind == "sphere":
            dc = np.linalg.norm(p, axis=1) - c.size[0]
        elif c.kind == "box":
            q = np.abs(p) - np.asarray(c.size)
            dc = np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(1), 0)
        elif c.kind == "capsule":
            z = np.clip(p[:, 2], -c.size[1], c.size[1])
            dc = np.linalg.norm(p - np.stack([0 * z, 0 * z, z], -1), axis=1) - c.size[0]
        else:
            raise ValueError(f"unknown collider {c.kind!r}")
        d = np.minimum(d, dc)
    return d


def collider_meshes(scene: Scene) -> list[tuple[np.ndarray, np.ndarray]]:
    """Triangle meshes of the colliders and of the ground under the scene (for the
    scanner's visibility: what they hide is not scanned)."""
    import trimesh

    out = []
    for c in scene.colliders:
        if c.kind == "sphere":
            m = trimesh.creation.icosphere(subdivisions=3, radius=c.size[0])
        elif c.kind == "box":
            m = trimesh.creation.box(extents=2 * np.asarray(c.size))
        else:
            m = trimesh.creation.capsule(height=2 * c.size[1], radius=c.size[0], count=[24, 12])
        out.append((np.asarray(m.vertices) + np.asarray(c.centre), np.asarray(m.faces, np.int64)))
    # the ground: a 16-gon of radius 1.2 m about the scene (inside the scanner's 2 m ring)
    a = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    ring = np.stack([1.2 * np.cos(a) + scene.origin[0], 1.2 * np.sin(a) + scene.origin[1], 0 * a], -1)
    ground = np.concatenate([[[scene.origin[0], scene.origin[1], 0.0]], ring])
    fan = np.stack([np.zeros(16, np.int64), 1 + np.arange(16), 1 + (np.arange(16) + 1) % 16], -1)
    out.append((ground, fan))
    return out


def save_state(scene: Scene, r: SimResult, path: pathlib.Path | None = None) -> pathlib.Path:
    """Store a simulated state compactly: the final positions as float32 (the rest mesh and
    the faces are :func:`rest_mesh`'s), the pinned vertices and the run's figures."""
    path = path or STATES / f"{scene.name}.npz"
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez_compressed(
        tmp, final=r.final.astype(np.float32), pinned=r.pinned.astype(np.int32), info=json.dumps(r.info)
    )
    tmp.replace(path)
    return path


def load_state(scene: Scene, path: pathlib.Path | None = None) -> SimResult | None:
    """The stored state of ``scene`` (None when there is none); ``info["key"]`` says which
    settings made it (:func:`settings_key`)."""
    path = path or STATES / f"{scene.name}.npz"
    if not path.is_file():
        return None
    rest, faces = rest_mesh(scene)
    with np.load(path) as z:
        final = z["final"].astype(float)
        if final.shape != rest.shape:
            raise ValueError(f"{path}: {final.shape} positions for a {rest.shape} rest mesh")
        return SimResult(rest, faces, final, z["pinned"].astype(np.int64), json.loads(str(z["info"])))


def simulate_cached(scene: Scene, force: bool = False, verbose: bool = True) -> SimResult:
    """The scene's simulated state from :data:`STATES` (simulated and stored when missing or
    made with other settings)."""
    key = settings_key(scene)
    r = None if force else load_state(scene)
    if r is not None and r.info.get("key") == key:
        return r
    if verbose:
        print(f"simulating {scene.name} ({scene.vertices} vertices, {scene.frames} frames)", flush=True)
    r = simulate(scene, verbose=verbose)
    r.info["key"] = key
    save_state(scene, r)
    r.final = r.final.astype(np.float32).astype(float)  # as the harness reads it back
    if verbose:
        print(f"  {scene.name}: {r.info['seconds']} s, edge ratios {r.info['edge_ratio_p01_p50_p99']}")
    return r


def main() -> int:
    ap = argparse.ArgumentParser(description="Simulate the harness's cloth scenes (bench/data/sim/).")
    ap.add_argument("--scenes", default=",".join(SCENES), help="comma-separated: " + ", ".join(SCENES))
    ap.add_argument("--force", action="store_true", help="rerun cached scenes")
    args = ap.parse_args()
    for name in args.scenes.split(","):
        if name not in SCENES:
            raise SystemExit(f"unknown scene {name!r} ({', '.join(SCENES)})")
        simulate_cached(SCENES[name], force=args.force)
    return 0


if __name__ == "__main__":
    sys.exit(main())
