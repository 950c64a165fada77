"""Benchmark cases for the comparison harness (``bench/compare.py``).

Every case is a template mesh ``(V, F)``, a target (points, optionally with faces) and, where
it is known, the ground truth: the true position of every template vertex on the target.

Generated cases (ground truth by construction, made here):

* ``sheet``: a flat sheet and the same sheet folded, rotated and moved
  (:func:`foldmatch_rs.folded_sheet`);
* ``skirt``: an A-line tube ("skirt") and the same tube with knife pleats that grow toward the
  hem, a sway and a twist (:func:`pleated_skirt`);
* ``shirt``: a shirt-like template of three components (an elliptic torso tube and two sleeve
  tubes, as garment segments in the paper's Fig. 1) and a folded version of it: compression
  folds at the waist, diagonal drape folds, sleeves bent down with ring wrinkles
  (:func:`folded_shirt`).

Each comes at a small size (≈1.5–1.7K template vertices, 2K scan points) and at the paper's size
(≈13K template vertices, 14.4K scan points), and in scan-like variants: ``clean`` (points
resampled uniformly on the true surface, a different count from the template), ``noisy``
(resampled + Gaussian noise, σ = 0.5 % of the bounding-box diagonal) and ``holes`` (resampled,
σ = 0.2 %, points removed in four random balls of radius 8 % of the diagonal).

Real cases come from ``../shared/data`` (see its README; none of it was made by us), loaded with
``process=False, maintain_order=True`` so vertex *i* stays the *i*-th ``v`` line. Ground truth
exists only for files that share the template's face list. Each target is given twice: as the
mesh (vertices + faces) and as a resampled noisy point cloud (5,000 area-uniform samples,
σ = 0.2 % of the diagonal) so that no method can use the target's vertex order.

Real templates are first placed by the least-squares similarity transform onto the ground truth
(Umeyama 1991). The same placed template is given to every method and is the "identity" row, so
the comparison measures non-rigid fitting only, not global pose search (which none of the
compared methods does: the raw frames are rotated by up to 150° against their templates).
"""

from __future__ import annotations

import os
import pathlib
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

REPO = pathlib.Path(__file__).resolve().parent.parent
SHARED_DATA = pathlib.Path(os.environ.get("FOLDMATCH_SHARED", REPO.parent / "shared")) / "data"

#: Scan noise of the real point-cloud targets, as a fraction of the target's bbox diagonal.
REAL_NOISE = 0.002
#: Number of points of the real point-cloud targets.
REAL_POINTS = 5000


@dataclass
class Case:
    """One benchmark case (all arrays float64 / int64)."""

    name: str
    group: str
    template_vertices: np.ndarray
    faces: np.ndarray
    target: np.ndarray
    target_faces: np.ndarray | None = None
    ground_truth: np.ndarray | None = None
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def sizes(self) -> str:
        return f"M={len(self.template_vertices)}, N={len(self.target)}"

    def save(self, path: pathlib.Path) -> None:
        arrays = {
            "template_vertices": self.template_vertices,
            "faces": self.faces,
            "target": self.target,
        }
        if self.target_faces is not None:
            arrays["target_faces"] = self.target_faces
        if self.ground_truth is not None:
            arrays["ground_truth"] = self.ground_truth
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        np.savez(tmp, **arrays)
        os.replace(tmp, path)


def load_case_arrays(path: pathlib.Path) -> dict[str, np.ndarray]:
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


# ---- geometry helpers ----------------------------------------------------------------------


def bbox_diagonal(points: np.ndarray) -> float:
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


def grid_faces(n_u: int, n_v: int, periodic_u: bool, offset: int = 0) -> np.ndarray:
    """Triangles of an ``n_u × n_v`` vertex grid (index ``v * n_u + u``), closed in u if
    ``periodic_u`` (a tube), with alternating diagonals."""
    faces = []
    cols = n_u if periodic_u else n_u - 1
    for v in range(n_v - 1):
        for u in range(cols):
            u1 = (u + 1) % n_u
            a, b = v * n_u + u, v * n_u + u1
            c, d = (v + 1) * n_u + u, (v + 1) * n_u + u1
            if (u + v) % 2 == 0:
                faces += [(a, b, d), (a, d, c)]
            else:
                faces += [(a, b, c), (b, d, c)]
    return np.asarray(faces, dtype=np.int64) + offset


def rotation_matrix(axis: np.ndarray, degrees: float) -> np.ndarray:
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    t = np.radians(degrees)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * (k @ k)


def face_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The area of every triangle."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def surface_draws(
    vertices: np.ndarray, faces: np.ndarray, count: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``count`` area-uniform draws on a triangle mesh: (face index, r1, r2), the point of face
    (a, b, c) at a + r1 (b − a) + r2 (c − a) (:func:`at_draws`)."""
    area = face_areas(vertices, faces)
    fi = rng.choice(len(faces), size=count, p=area / area.sum())
    r1, r2 = rng.random(count), rng.random(count)
    flip = r1 + r2 > 1
    r1[flip], r2[flip] = 1 - r1[flip], 1 - r2[flip]
    return fi, r1, r2


def at_draws(
    values: np.ndarray, faces: np.ndarray, draws: tuple[np.ndarray, np.ndarray, np.ndarray]
) -> np.ndarray:
    """Per-vertex ``values`` (positions, or any chart of the mesh) interpolated at the
    :func:`surface_draws`."""
    fi, r1, r2 = draws
    a, b, c = (values[faces[fi, k]] for k in range(3))
    return a + r1[:, None] * (b - a) + r2[:, None] * (c - a)


def sample_surface(
    vertices: np.ndarray, faces: np.ndarray, count: int, rng: np.random.Generator
) -> np.ndarray:
    """``count`` points uniformly distributed on a triangle mesh (area-weighted)."""
    return at_draws(vertices, faces, surface_draws(vertices, faces, count, rng))


def scan_variant(
    truth: np.ndarray,
    faces: np.ndarray,
    variant: str,
    count: int,
    seed: int,
) -> tuple[np.ndarray, dict[str, Any]]:
    """A scan-like point cloud of the true surface ``(truth, faces)``.

    ``clean``: ``count`` resampled surface points; ``noisy``: + N(0, (0.005·diag)²) per
    coordinate; ``holes``: σ = 0.002·diag and every point within 0.08·diag of four random
    surface points removed. Returns the points and a description.
    """
    rng = np.random.default_rng(seed)
    diag = bbox_diagonal(truth)
    pts = sample_surface(truth, faces, count, rng)
    info: dict[str, Any] = {"variant": variant, "resampled_points": count}
    if variant == "noisy":
        sigma = 0.005 * diag
        pts = pts + rng.normal(scale=sigma, size=pts.shape)
        info["noise_sigma_rel"] = 0.005
    elif variant == "holes":
        sigma = 0.002 * diag
        pts = pts + rng.normal(scale=sigma, size=pts.shape)
        centers = pts[rng.choice(len(pts), size=4, replace=False)]
        keep = np.ones(len(pts), bool)
        for c in centers:
            keep &= np.linalg.norm(pts - c, axis=1) > 0.08 * diag
        info.update(
            noise_sigma_rel=0.002, holes=4, hole_radius_rel=0.08, removed_fraction=round(1 - keep.mean(), 4)
        )
        pts = pts[keep]
    elif variant != "clean":
        raise ValueError(f"unknown scan variant {variant!r}")
    return np.ascontiguousarray(pts), info


def umeyama(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Least-squares similarity ``dst ≈ s R src + t`` (Umeyama 1991)."""
    ms, md = src.mean(0), dst.mean(0)
    a, b = src - ms, dst - md
    u, sv, vt = np.linalg.svd(b.T @ a / len(src))
    d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
    r = u @ d @ vt
    s = float(np.trace(np.diag(sv) @ d) / ((a**2).sum() / len(src)))
    return s, r, md - s * r @ ms


# ---- generated shapes ----------------------------------------------------------------------


def folded_sheet(n: int, seed: int = 1, **kw: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n × n`` flat sheet and its folded ground truth (``foldmatch_rs.folded_sheet``)."""
    import foldmatch_rs as fm

    c = fm.folded_sheet(nx=n, ny=n, seed=seed, **kw)
    return (
        np.asarray(c["template_vertices"], float),
        np.asarray(c["faces"], np.int64),
        np.asarray(c["ground_truth"], float),
    )


def pleated_skirt(
    n_theta: int, n_z: int, pleats: int = 10, amplitude: float = 0.02, seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An A-line tube skirt (top radius 0.16, hem radius 0.26, length 0.6) and its pleated
    ground truth: knife pleats ``A s(z)^1.2 (sin + 0.35 sin 2·)`` growing toward the hem (each
    row's base radius shrunk so the row keeps its circumference: cloth barely stretches), a
    twist of 0.25 rad, a sideways sway of 0.05 at the hem, 4 % vertical shortening, and a small
    rigid motion. Vertex (θ, z) keeps its θ (plus twist): the material correspondence."""
    rng = np.random.default_rng(seed)
    theta = np.linspace(0, 2 * np.pi, n_theta, endpoint=False)
    zs = np.linspace(0, 1, n_z)  # 0 = waist, 1 = hem
    th, s = np.meshgrid(theta, zs)
    r0, r1, length = 0.16, 0.26, 0.6
    r = r0 + (r1 - r0) * s
    template = np.stack([r * np.cos(th), r * np.sin(th), -length * s], -1).reshape(-1, 3)
    faces = grid_faces(n_theta, n_z, periodic_u=True)

    phase = rng.uniform(0, 2 * np.pi)
    grow = s**1.2
    x = pleats * th + phase
    pleat = amplitude * grow * (np.sin(x) + 0.35 * np.sin(2 * x))
    # Cloth barely stretches: shrink every row's base radius until the pleated row has the
    # template row's circumference (fixed point on the polygon perimeter).
    base = r.copy()
    for _ in range(30):
        rr = base + pleat
        ring = np.stack([rr * np.cos(th), rr * np.sin(th)], -1)
        perim = np.linalg.norm(np.roll(ring, -1, axis=1) - ring, axis=-1).sum(1, keepdims=True)
        target = 2 * np.pi * r[:, :1] * np.sin(np.pi / n_theta) * n_theta / np.pi
        base = np.maximum(base * (target / perim), 0.5 * r)
    rr = base + pleat
    tw = th + 0.25 * s**1.5
    zz = -length * s * (1 - 0.04 * s)
    sway = 0.05 * s**2
    truth = np.stack([rr * np.cos(tw) + sway, rr * np.sin(tw), zz], -1).reshape(-1, 3)
    rot = rotation_matrix([0.3, 1.0, 0.2], 6.0)
    truth = truth @ rot.T + np.array([0.02, -0.015, 0.03])
    return template, faces, truth


def folded_shirt(
    n_theta: int, n_z: int, s_theta: int, s_len: int, seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A shirt-like template of three open tubes: an elliptic torso (half-axes 0.18 × 0.11,
    height 0.6) and two sleeves (radius 0.06, length 0.25, horizontal at shoulder height,
    starting 1 cm off the torso), and its folded ground truth: horizontal compression folds
    around the waist, diagonal drape folds across the torso, 3 % shortening; each sleeve bent
    down by 40° progressively along its length, with ring wrinkles and a slight twist; then a
    small rigid motion."""
    rng = np.random.default_rng(seed)
    a_ax, b_ax, height = 0.18, 0.11, 0.6
    theta = np.linspace(0, 2 * np.pi, n_theta, endpoint=False)
    zs = np.linspace(0, 1, n_z)
    th, s = np.meshgrid(theta, zs)
    torso = np.stack([a_ax * np.cos(th), b_ax * np.sin(th), height * s], -1).reshape(-1, 3)
    faces = [grid_faces(n_theta, n_z, periodic_u=True)]

    ph1, ph2 = rng.uniform(0, 2 * np.pi, 2)
    waist = np.exp(-(((s - 0.12) / 0.14) ** 2))  # compression folds low on the torso
    d_r = 0.012 * waist * np.sin(2 * np.pi * 7 * s + 0.8 * np.cos(th) + ph1)
    diag_fold = 0.008 * np.sin(6 * th + 9 * s + ph2) * np.sin(np.pi * s)  # diagonal drape folds
    scale_r = 1 + (d_r + diag_fold) / np.hypot(a_ax * np.cos(th), b_ax * np.sin(th))
    torso_t = np.stack(
        [a_ax * np.cos(th) * scale_r, b_ax * np.sin(th) * scale_r, height * s * 0.97], -1
    ).reshape(-1, 3)

    verts, truths = [torso], [torso_t]
    offset = len(torso)
    radius, length, z0 = 0.06, 0.25, 0.48
    for side in (-1.0, 1.0):
        phi = np.linspace(0, 2 * np.pi, s_theta, endpoint=False)
        t = np.linspace(0, 1, s_len)
        ph, tt = np.meshgrid(phi, t)
        x0 = side * (a_ax + 0.01)
        sleeve = np.stack(
            [x0 + side * length * tt, radius * np.cos(ph), z0 + radius * np.sin(ph)], -1
        ).reshape(-1, 3)
        # Folded: bend down about the shoulder (angle grows along the sleeve), ring wrinkles.
        wr = radius * (1 + 0.12 * np.sin(2 * np.pi * 4.5 * tt + 0.6 * np.cos(ph)) * tt**0.7)
        twist = ph + 0.3 * tt
        local = np.stack([length * tt, wr * np.cos(twist), wr * np.sin(twist)], -1)
        bend = np.radians(40.0) * tt  # bend angle at each station
        # integrate the centre line of a sleeve whose direction turns down by `bend`
        ds = length / (s_len - 1)
        ang = np.radians(40.0) * t
        cx = np.concatenate([[0.0], np.cumsum(np.cos(ang[:-1]) * ds)])
        cz = np.concatenate([[0.0], np.cumsum(-np.sin(ang[:-1]) * ds)])
        cxx, czz = cx[:, None] * np.ones_like(ph), cz[:, None] * np.ones_like(ph)
        # local frame: axis (cos b, −sin b), radial in y and in the bent normal
        ly, lz = local[..., 1], local[..., 2]
        px = cxx + lz * np.sin(bend)
        pz = czz + lz * np.cos(bend)
        sleeve_t = np.stack([x0 + side * px, ly, z0 + pz], -1).reshape(-1, 3)
        m = len(sleeve)
        verts.append(sleeve)
        truths.append(sleeve_t)
        f = grid_faces(s_theta, s_len, periodic_u=True, offset=offset)
        if side < 0:  # keep outward normals consistent with the mirrored geometry
            f = f[:, [0, 2, 1]]
        faces.append(f)
        offset += m
    template = np.concatenate(verts)
    truth = np.concatenate(truths)
    rot = rotation_matrix([0.2, 0.1, 1.0], 7.0)
    truth = truth @ rot.T + np.array([0.015, 0.02, -0.02])
    return template, np.concatenate(faces), truth


#: Generator settings per (shape, size): template ≈1.5–1.7K vertices (small) or ≈13K (paper).
SHAPES = {
    ("sheet", "small"): lambda: folded_sheet(41),
    ("sheet", "paper"): lambda: folded_sheet(115),
    ("skirt", "small"): lambda: pleated_skirt(64, 25),
    ("skirt", "paper"): lambda: pleated_skirt(240, 55),
    ("shirt", "small"): lambda: folded_shirt(48, 24, 16, 12),
    ("shirt", "paper"): lambda: folded_shirt(160, 64, 48, 30),
}
SCAN_POINTS = {"small": 2000, "paper": 14400}


def generated_cases(size: str, variants: tuple[str, ...] = ("clean", "noisy", "holes")) -> Iterator[Case]:
    for shape in ("sheet", "skirt", "shirt"):
        v, f, gt = SHAPES[(shape, size)]()
        for i, variant in enumerate(variants):
            pts, info = scan_variant(gt, f, variant, SCAN_POINTS[size], seed=1000 + i)
            yield Case(
                name=f"{shape}-{size}-{variant}",
                group=size,
                template_vertices=v,
                faces=f,
                target=pts,
                ground_truth=gt,
                meta={"source": "generated (bench/cases.py)", "shape": shape, **info},
            )


def quick_case() -> Case:
    """The tiny CI case: a 17 × 17 sheet on 400 noisy resampled points."""
    v, f, gt = folded_sheet(17)
    pts, info = scan_variant(gt, f, "noisy", 400, seed=7)
    return Case(
        "sheet-tiny-noisy",
        "quick",
        v,
        f,
        pts,
        None,
        gt,
        {"source": "generated (bench/cases.py)", "shape": "sheet", **info},
    )


def sheet_samples(count: int = 24, seed: int = 500) -> Iterator[Case]:
    """Random small folded sheets (the analogue of the paper's flat-cloth samples, Fig. 6):
    fold amplitude 0.03–0.10, 1.5–4 folds, rotation 0–20°, offsets up to 0.05, scanned as
    2,000 resampled points with 0.2 % noise."""
    rng = np.random.default_rng(seed)
    for i in range(count):
        v, f, gt = folded_sheet(
            41,
            seed=int(seed + i),
            fold_amplitude=float(rng.uniform(0.03, 0.10)),
            folds=float(rng.uniform(1.5, 4.0)),
            rotation_degrees=float(rng.uniform(0, 20)),
            offset=tuple(float(x) for x in rng.uniform(-0.05, 0.05, 3)),
        )
        pts = sample_surface(gt, f, 2000, rng)
        pts = pts + rng.normal(scale=0.002 * bbox_diagonal(gt), size=pts.shape)
        yield Case(
            f"sheet-sample-{i:02d}",
            "samples-sheet",
            v,
            f,
            pts,
            None,
            gt,
            {
                "source": "generated (bench/cases.py)",
                "shape": "sheet",
                "variant": "noisy",
                "noise_sigma_rel": 0.002,
                "resampled_points": 2000,
            },
        )


# ---- real data (../shared/data) ------------------------------------------------------------


def load_mesh(path: pathlib.Path) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # trimesh's UV handling warns on some files
        m = trimesh.load(path, process=False, maintain_order=True, force="mesh")
    return np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)


def _real_pair(
    name: str,
    group: str,
    tpl: pathlib.Path,
    tgt: pathlib.Path,
    seed: int,
    kinds: tuple[str, ...],
    points: int = REAL_POINTS,
) -> Iterator[Case]:
    tv, tf = load_mesh(tpl)
    gv, gf = load_mesh(tgt)
    if len(tv) != len(gv) or not np.array_equal(tf, gf):
        raise ValueError(f"{tgt}: no vertex correspondence with {tpl}")
    s, r, t = umeyama(tv, gv)
    placed = tv @ (s * r).T + t
    meta = {
        "up": 1,  # every real source is y-up (SMPL, Maya, DiffCloth)
        "source": f"../shared/data/{tgt.relative_to(SHARED_DATA)}",
        "template": f"../shared/data/{tpl.relative_to(SHARED_DATA)}",
        "prealign": {
            "scale": round(s, 4),
            "rotation_deg": round(float(np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1)))), 1),
        },
    }
    if "mesh" in kinds:
        yield Case(
            f"{name}-mesh",
            group,
            placed,
            tf,
            gv,
            gf,
            gv,
            {**meta, "variant": "mesh target (vertices + faces)"},
        )
    if "points" in kinds:
        rng = np.random.default_rng(seed)
        pts = sample_surface(gv, gf, points, rng)
        pts = pts + rng.normal(scale=REAL_NOISE * bbox_diagonal(gv), size=pts.shape)
        yield Case(
            f"{name}-pts",
            group,
            placed,
            tf,
            pts,
            None,
            gv,
            {
                **meta,
                "variant": f"{points} resampled points, noise {REAL_NOISE * 100:.1f}% of diagonal",
                "resampled_points": points,
                "noise_sigma_rel": REAL_NOISE,
            },
        )


def real_cases(kinds: tuple[str, ...] = ("mesh", "points"), points: int = REAL_POINTS) -> Iterator[Case]:
    """The garments of ../shared/data with ground truth (arcsim T-shirt template → its 3
    wrinkled frames; the 2 skirt pairs; the T-shirt folding states from the rest shape;
    wind-sequence frames 50, 150, 250 from frame 0); `points`: the point-cloud variants' size."""
    d = SHARED_DATA
    a = d / "arcsim_smpl_vto_tshirt"
    for i, fr in enumerate(("0000", "0200", "arm")):
        yield from _real_pair(
            f"vto-tshirt-{fr}", "real", a / "vto_tshirt.obj", a / f"{fr}_garment.obj", 10 + i, kinds, points
        )
    g = d / "garment_pattern_generator"
    yield from _real_pair(
        "skirt-penetrate",
        "real",
        g / "skirt_pair_basic_vs_penetrate/skirt_maya_coords_sim.obj",
        g / "skirt_pair_basic_vs_penetrate/skirt_maya_penetrate_sim.obj",
        20,
        kinds,
        points,
    )
    yield from _real_pair(
        "skirt-small",
        "real",
        g / "skirt_pair_too_small/midway.obj",
        g / "skirt_pair_too_small/skirt_maya_coords_small_sim.obj",
        21,
        kinds,
        points,
    )
    f = d / "diffcloth/tshirt1900_folding"
    for i, st in enumerate(("flattened", "folding-biFolded", "folding-triFolded")):
        yield from _real_pair(
            f"tshirt-{st.replace('folding-', '')}",
            "real",
            f / "tshirt1900.obj",
            f / f"tshirt1900-{st}.obj",
            30 + i,
            kinds,
            points,
        )
    w = d / "diffcloth/tshirt1000_wind_sim/iter0"
    for i, fr in enumerate((50, 150, 250)):
        yield from _real_pair(f"wind-{fr}", "real", w / "0.obj", w / f"{fr}.obj", 40 + i, kinds, points)


def wind_samples() -> Iterator[Case]:
    """Every stored wind-sequence frame (iter0: 10…250, iter17: 50…250) as a noisy point cloud,
    template = frame 0 of the same run (the rest shirt in the simulation's frame)."""
    base = SHARED_DATA / "diffcloth/tshirt1000_wind_sim"
    for run, frames in (("iter0", range(10, 251, 10)), ("iter17", range(50, 251, 50))):
        for fr in frames:
            yield from _real_pair(
                f"wind-{run}-{fr:03d}",
                "samples-wind",
                base / run / "0.obj",
                base / run / f"{fr}.obj",
                1000 + fr + (7 if run == "iter17" else 0),
                ("points",),
            )


def real_data_missing() -> str | None:
    """Why real cases cannot be built here, or None."""
    if not SHARED_DATA.is_dir():
        return f"shared data not found at {SHARED_DATA} (set FOLDMATCH_SHARED)"
    try:
        import trimesh  # noqa: F401
    except ImportError:
        return "trimesh is not installed (needed to read the OBJ files)"
    return None
