"""The dressed-body scans of bench/dressed.py (issue 26): the sources, the simulated
full-body scanner, the cases built from them and their cache. A garment template is fitted onto
a full-body scan that holds the garment *and* the visible skin, as a full-body scanner sees it.

This module holds everything but the command: the geometry helpers, the scanner
(:func:`scan`: cameras, exact visibility, fusion, noise, holes, labels), PNG previews, the
garment and body sources (:func:`load_source`, the two-garment transfer
:func:`transfer_to_body`), the placed and unplaced starts, :func:`build_source` (cached under
``bench/out/dressed/``), :func:`make_case` and :func:`dressed_cases` (bench/variants.py's group
``dressed``: the six whole scans with the placed template). bench/dressed.py (the command)
fits them and prints the report; tests/test_dressed.py checks the scans.

The cases (``../shared/data``, nothing made by us but the scans; see its README):

* ``tshirt-0000``, ``tshirt-0200``, ``tshirt-arm``: the ARCSim T-shirt template
  (``vto_tshirt.obj``) → the wrinkled frame (``{fr}_garment.obj``) worn by its SMPL body
  (``{fr}_body.obj``), metres;
* ``skirt-penetrate``, ``skirt-small``: the Garment-Pattern-Generator skirt pairs
  (``skirt_maya_coords_sim`` → ``skirt_maya_penetrate_sim``, ``midway`` →
  ``skirt_maya_coords_small_sim``) on ``f_smpl_templatex300.obj`` (1 unit ≈ 1/300 m);
* ``two-garment``: the T-shirt (frame 0000) and the ``too small`` skirt pair, the skirt
  carried from the GPG body onto the ARCSim 0000 body through the bodies' shared SMPL vertex
  order (:func:`transfer_to_body`); the template has two connected components (shirt, skirt),
  the truth is their concatenation.

The scan (:func:`scan`): 24 pinhole cameras (3 heights × 8 azimuths, 2 m from the body's
axis, looking at the centre of its bounding box) render garment + body; every pixel's first
surface hit is a point (exact visibility: what no camera sees, e.g. the skin under the
shirt, the soles, the inside of the armpits, is not in the scan); the 24 views are fused on
a 6 mm voxel grid (one point per voxel: a fused scanner's even density), then N(0, 1.5 mm²)
noise per coordinate and two holes (the points within 6 cm of two centres removed: a random
garment point and a random scan point). Each point keeps its label: 0 = body / skin, 1.. =
the garment it lies on. Distances are given in metres and converted with each source's
units. Shares of garment vertices inside the body are in each case's meta (the carried
skirt of the two-garment case: 1.1 %; skirt-penetrate's truth: 16 %, as in the source).

Variants per case: ``whole`` (garment + visible body), ``body-free`` (the same scan without
the body points), ``masked`` (the whole scan with ``target_weights`` = the 0/1 garment mask,
when ``fm.fit`` accepts it); the start ``placed`` (the template moved by the least-squares
similarity onto the truth, as bench/cases.py does) or ``unplaced`` (the template as given in
its file when that is a rough placement near the garment, otherwise the placed template
rotated by 10° about a random axis and shifted by 5 % of the garment's diagonal).

Split: tune on tshirt-0000, tshirt-arm, skirt-penetrate; hold out tshirt-0200, skirt-small,
two-garment (``meta["split"]``); bench/dressed.py's ``--seed`` draws other cameras, noise and holes (the
default scans use seed 0).
"""

from __future__ import annotations

import hashlib
import json
import pathlib
import sys
import time
import zlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench import cases as cases_mod

HERE = pathlib.Path(__file__).resolve().parent

OUT = HERE / "out" / "dressed"

#: Scanner settings, in metres (converted with each source's units).
SCANNER = {
    "rings": 3,  # camera heights
    "azimuths": 8,  # cameras per height
    "radius": 2.0,  # horizontal distance of the cameras from the body's vertical axis
    "heights": (-0.75, 0.0, 0.7),  # camera heights relative to the body's bbox centre
    "pixel": 0.0035,  # pixel footprint at the body's centre
    "voxel": 0.006,  # fusion grid: one point per voxel
    "noise": 0.0015,  # σ of the Gaussian noise, per coordinate
    "holes": 2,
    "hole_radius": 0.06,
}
#: Bump when the generation changes (invalidates the cache).
VERSION = 3

TUNE = ("tshirt-0000", "tshirt-arm", "skirt-penetrate")
HELD_OUT = ("tshirt-0200", "skirt-small", "two-garment")
SOURCES = ("tshirt-0000", "tshirt-0200", "tshirt-arm", "skirt-penetrate", "skirt-small", "two-garment")


# ---- geometry ---------------------------------------------------------------------------------


def face_normals(v: np.ndarray, f: np.ndarray, unit: bool = True) -> np.ndarray:
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    if unit:
        n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-300
    return n


def vertex_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    n = face_normals(v, f, unit=False)  # area-weighted
    out = np.zeros_like(v)
    for k in range(3):
        np.add.at(out, f[:, k], n)
    return out / (np.linalg.norm(out, axis=1, keepdims=True) + 1e-300)


def closest_on_triangles(
    p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Closest points of triangles ``(a, b, c)`` to points ``p`` (row-wise; Ericson,
    Real-Time Collision Detection 5.1.5): the points and their barycentrics ``(u, v, w)``."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
    bp = p - b
    d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
    cp = p - c
    d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    denom = va + vb + vc
    denom = np.where(np.abs(denom) < 1e-300, 1e-300, denom)
    v_ = vb / denom
    w_ = vc / denom
    bary = np.stack([1 - v_ - w_, v_, w_], -1)  # interior
    # edges and vertices (Voronoi regions), later conditions win where they overlap correctly
    with np.errstate(divide="ignore", invalid="ignore"):
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    m = (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0)
    bary[m] = np.stack([np.zeros(m.sum()), 1 - t_bc[m], t_bc[m]], -1)
    m = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
    bary[m] = np.stack([1 - t_ac[m], np.zeros(m.sum()), t_ac[m]], -1)
    m = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
    bary[m] = np.stack([1 - t_ab[m], t_ab[m], np.zeros(m.sum())], -1)
    m = (d6 >= 0) & (d5 <= d6)
    bary[m] = [0, 0, 1]
    m = (d3 >= 0) & (d4 <= d3)
    bary[m] = [0, 1, 0]
    m = (d1 <= 0) & (d2 <= 0)
    bary[m] = [1, 0, 0]
    q = bary[:, :1] * a + bary[:, 1:2] * b + bary[:, 2:] * c
    return q, bary


def closest_on_mesh(
    points: np.ndarray, v: np.ndarray, f: np.ndarray, k: int = 24
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest point of the mesh ``(v, f)`` to each point, among the ``k`` triangles with the
    nearest centroids: (triangle index, barycentrics, closest point)."""
    from scipy.spatial import cKDTree

    tree = cKDTree(v[f].mean(1))
    _, cand = tree.query(points, k=k)
    p = np.repeat(points[:, None, :], k, 1).reshape(-1, 3)
    tri = cand.reshape(-1)
    q, bary = closest_on_triangles(p, v[f[tri, 0]], v[f[tri, 1]], v[f[tri, 2]])
    d = ((p - q) ** 2).sum(-1).reshape(-1, k)
    best = d.argmin(1)
    rows = np.arange(len(points)) * k + best
    return tri[rows], bary[rows], q[rows]


def winding_numbers(points: np.ndarray, v: np.ndarray, f: np.ndarray, chunk: int = 128) -> np.ndarray:
    """Generalized winding number of a closed mesh at each point (≈1 inside, ≈0 outside;
    van Oosterom & Strackee's solid angle)."""
    out = np.empty(len(points))
    a0, b0, c0 = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    for s in range(0, len(points), chunk):
        p = points[s : s + chunk, None, :]
        a, b, c = a0 - p, b0 - p, c0 - p
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        det = (a * np.cross(b, c)).sum(-1)
        den = la * lb * lc + (a * b).sum(-1) * lc + (b * c).sum(-1) * la + (c * a).sum(-1) * lb
        out[s : s + chunk] = np.arctan2(det, den).sum(1) / (2 * np.pi)
    return out


def rotation_angle(r: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1))))


def components(n_vertices: int, f: np.ndarray) -> np.ndarray:
    """Connected component id of every vertex (by shared faces)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    i = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
    j = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
    g = coo_matrix((np.ones(len(i)), (i, j)), shape=(n_vertices, n_vertices))
    return connected_components(g, directed=False)[1]


# ---- the scanner ------------------------------------------------------------------------------


def cameras(
    center: np.ndarray, up: int, units: float, rng: np.random.Generator, settings: dict[str, Any] = SCANNER
) -> list[tuple[np.ndarray, np.ndarray]]:
    """(position, look-at point) of every camera: ``rings`` heights × ``azimuths`` around the
    ``up`` axis, each ring staggered by half a step, the rig turned by a random angle and each
    camera jittered by a few centimetres (``rng``)."""
    h_axes = [k for k in range(3) if k != up]
    start = rng.uniform(0, 2 * np.pi)
    out = []
    n_az = settings["azimuths"]
    for ring, h in enumerate(settings["heights"][: settings["rings"]]):
        for k in range(n_az):
            az = start + 2 * np.pi * (k + 0.5 * (ring % 2)) / n_az + rng.normal(0, 0.03)
            pos = center.copy()
            pos[h_axes[0]] += settings["radius"] * units * np.cos(az)
            pos[h_axes[1]] += settings["radius"] * units * np.sin(az)
            pos[up] += (h + rng.normal(0, 0.03)) * units
            out.append((pos, center + rng.normal(0, 0.02, 3) * units))
    return out


def render_view(
    v: np.ndarray, f: np.ndarray, eye: np.ndarray, look: np.ndarray, up: int, pixel: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One pinhole camera at ``eye`` looking at ``look``; ``pixel``: the pixel footprint at
    the look-at distance. Returns, per pixel that sees the mesh, the first surface hit (world
    coordinates), the triangle hit and the pixel's (row, column)."""
    fwd = look - eye
    dist = np.linalg.norm(fwd)
    fwd /= dist
    upv = np.zeros(3)
    upv[up] = 1.0
    right = np.cross(fwd, upv)
    right /= np.linalg.norm(right)
    cup = np.cross(right, fwd)
    rel = v - eye
    cam = np.stack([rel @ right, rel @ cup, rel @ fwd], -1)
    if (cam[:, 2] <= 1e-9).any():
        raise ValueError("a vertex lies behind the camera")
    focal = dist / pixel
    px = focal * cam[:, 0] / cam[:, 2]
    py = focal * cam[:, 1] / cam[:, 2]
    tx, ty = px[f], py[f]  # (T, 3)
    x0 = np.ceil(tx.min(1) - 0.5).astype(np.int64)
    x1 = np.floor(tx.max(1) - 0.5).astype(np.int64)
    y0 = np.ceil(ty.min(1) - 0.5).astype(np.int64)
    y1 = np.floor(ty.max(1) - 0.5).astype(np.int64)
    w = np.maximum(x1 - x0 + 1, 0)
    h = np.maximum(y1 - y0 + 1, 0)
    count = w * h
    tri = np.repeat(np.arange(len(f)), count)
    starts = np.cumsum(count) - count
    local = np.arange(count.sum()) - np.repeat(starts, count)
    ix = x0[tri] + local % w[tri]
    iy = y0[tri] + local // w[tri]
    cx, cy = ix + 0.5, iy + 0.5
    ax, ay = tx[tri, 0], ty[tri, 0]
    bx, by = tx[tri, 1], ty[tri, 1]
    qx, qy = tx[tri, 2], ty[tri, 2]
    e0 = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    e1 = (qx - bx) * (cy - by) - (qy - by) * (cx - bx)
    e2 = (ax - qx) * (cy - qy) - (ay - qy) * (cx - qx)
    inside = ((e0 >= 0) & (e1 >= 0) & (e2 >= 0)) | ((e0 <= 0) & (e1 <= 0) & (e2 <= 0))
    tri, ix, iy = tri[inside], ix[inside], iy[inside]
    # exact hit: the pixel's ray against the triangle's plane
    ray = np.stack([(ix + 0.5) / focal, (iy + 0.5) / focal, np.ones(len(ix))], -1)
    n = face_normals(cam, f, unit=False)[tri]
    a = cam[f[tri, 0]]
    den = (n * ray).sum(-1)
    ok = np.abs(den) > 1e-12
    t = np.where(ok, (n * a).sum(-1) / np.where(ok, den, 1.0), np.inf)
    key = (iy - iy.min()) * (ix.max() - ix.min() + 1) + (ix - ix.min())
    order = np.lexsort((t, key))
    first = order[np.r_[True, key[order][1:] != key[order][:-1]]]
    first = first[np.isfinite(t[first])]
    hit_cam = ray[first] * t[first, None]
    hit = eye + hit_cam[:, :1] * right + hit_cam[:, 1:2] * cup + hit_cam[:, 2:] * fwd
    return hit, tri[first], np.stack([iy[first], ix[first]], -1)


@dataclass
class Scan:
    points: np.ndarray  # (N, 3)
    labels: np.ndarray  # (N,) 0 = body, k = garment k
    info: dict[str, Any] = field(default_factory=dict)


def scan(
    meshes: list[tuple[np.ndarray, np.ndarray, int]],
    units: float,
    seed: int,
    up: int = 1,
    settings: dict[str, Any] = SCANNER,
) -> Scan:
    """What the scanner sees of the labelled meshes ``(vertices, faces, label)`` (label 0 = the
    body): see the module's docstring. ``units``: source units per metre."""
    rng = np.random.default_rng(seed)
    v = np.concatenate([m[0] for m in meshes])
    offs = np.cumsum([0] + [len(m[0]) for m in meshes])
    f = np.concatenate([m[1] + o for m, o in zip(meshes, offs)])
    flab = np.concatenate([np.full(len(m[1]), m[2]) for m in meshes])
    center = (v.min(0) + v.max(0)) / 2
    hits, labs = [], []
    for eye, look in cameras(center, up, units, rng, settings):
        p, t, _ = render_view(v, f, eye, look, up, settings["pixel"] * units)
        hits.append(p)
        labs.append(flab[t])
    p = np.concatenate(hits)
    lab = np.concatenate(labs)
    raw = len(p)
    # fuse: one point per voxel, a random one
    perm = rng.permutation(len(p))
    p, lab = p[perm], lab[perm]
    vox = np.floor((p - p.min(0)) / (settings["voxel"] * units)).astype(np.int64)
    key = (vox[:, 0] * (vox[:, 1].max() + 1) + vox[:, 1]) * (vox[:, 2].max() + 1) + vox[:, 2]
    _, keep = np.unique(key, return_index=True)
    keep.sort()
    p, lab = p[keep], lab[keep]
    p = p + rng.normal(scale=settings["noise"] * units, size=p.shape)
    # two holes: one centred on a garment point, one on any point
    garment = np.flatnonzero(lab > 0)
    centres = [p[rng.choice(garment)], p[rng.integers(len(p))]][: settings["holes"]]
    keep = np.ones(len(p), bool)
    for c in centres:
        keep &= np.linalg.norm(p - c, axis=1) > settings["hole_radius"] * units
    info = {
        "cameras": settings["rings"] * settings["azimuths"],
        "rendered_hits": int(raw),
        "fused_points": int(len(p)),
        "points": int(keep.sum()),
        "removed_by_holes": int((~keep).sum()),
        "hole_centres": [c.round(4).tolist() for c in centres],
        "noise_sigma": settings["noise"] * units,
        "units_per_metre": units,
        "seed": seed,
        "garment_points": int((lab[keep] > 0).sum()),
    }
    return Scan(np.ascontiguousarray(p[keep]), lab[keep].astype(np.int64), info)


# ---- previews ---------------------------------------------------------------------------------

#: Colours of labels 0 (body), 1, 2, … in previews.
COLOURS = np.array([[0.85, 0.72, 0.62], [0.25, 0.45, 0.80], [0.80, 0.30, 0.30], [0.30, 0.65, 0.35]])


def preview(
    meshes: list[tuple[np.ndarray, np.ndarray, int]],
    path: pathlib.Path,
    up: int = 1,
    units: float = 1.0,
    azimuths: tuple[float, ...] = (0.0, 90.0, 180.0, 270.0),
    points: tuple[np.ndarray, np.ndarray] | None = None,
) -> pathlib.Path:
    """A PNG of the labelled meshes seen from a few azimuths (flat shading, colour by label),
    with this module's own rasterizer (no matplotlib needed); ``points``: a scan
    ``(points, labels)`` drawn as a second row of dots."""
    from PIL import Image

    v = np.concatenate([m[0] for m in meshes])
    offs = np.cumsum([0] + [len(m[0]) for m in meshes])
    f = np.concatenate([m[1] + o for m, o in zip(meshes, offs)])
    flab = np.concatenate([np.full(len(m[1]), m[2]) for m in meshes])
    center = (v.min(0) + v.max(0)) / 2
    h_axes = [k for k in range(3) if k != up]
    size = 360
    extent = np.ptp(v, axis=0).max()
    tiles = []
    for row in range(2 if points is not None else 1):
        line = []
        for az in np.radians(azimuths):
            eye = center.copy()
            eye[h_axes[0]] += 3 * extent * np.cos(az)
            eye[h_axes[1]] += 3 * extent * np.sin(az)
            pixel = 1.1 * extent / size
            img = np.ones((size, size, 3))
            if row == 0:
                hit, tri, pix = render_view(v, f, eye, center, up, pixel)
                n = face_normals(v, f)[tri]
                d = eye - hit
                d /= np.linalg.norm(d, axis=1, keepdims=True)
                shade = 0.35 + 0.65 * np.abs((n * d).sum(1))
                rgb = COLOURS[flab[tri] % len(COLOURS)] * shade[:, None]
            else:
                p, lab = points
                fwd = center - eye
                fwd /= np.linalg.norm(fwd)
                upv = np.zeros(3)
                upv[up] = 1.0
                right = np.cross(fwd, upv)
                right /= np.linalg.norm(right)
                cup = np.cross(right, fwd)
                rel = p - eye
                z = rel @ fwd
                focal = np.linalg.norm(center - eye) / pixel
                pix = np.stack(
                    [np.floor(focal * (rel @ cup) / z), np.floor(focal * (rel @ right) / z)], -1
                ).astype(int)
                order = np.argsort(-z)  # far first, near overwrite
                pix, lab_o = pix[order], lab[order]
                rgb = (
                    COLOURS[lab_o % len(COLOURS)]
                    * (0.6 + 0.4 * (1 - (z[order] - z.min()) / (np.ptp(z) + 1e-12)))[:, None]
                )
            r = size // 2 - pix[:, 0]
            c = size // 2 + pix[:, 1]
            ok = (r >= 0) & (r < size) & (c >= 0) & (c < size)
            img[r[ok], c[ok]] = rgb[ok]
            line.append(img)
        tiles.append(np.concatenate(line, 1))
    im = np.concatenate(tiles, 0)
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray((np.clip(im, 0, 1) * 255).astype(np.uint8)).save(path)
    return path


# ---- the garments and bodies -----------------------------------------------------------------


def _arcsim(fr: str) -> dict[str, Any]:
    a = cases_mod.SHARED_DATA / "arcsim_smpl_vto_tshirt"
    tv, tf = cases_mod.load_mesh(a / "vto_tshirt.obj")
    gv, gf = cases_mod.load_mesh(a / f"{fr}_garment.obj")
    bv, bf = cases_mod.load_mesh(a / f"{fr}_body.obj")
    return {
        "template": tv,
        "faces": tf,
        "truth": gv,
        "body": (bv, bf),
        "units": 1.0,
        "template_labels": np.ones(len(tv), np.int64),
        "files": {
            "template": "arcsim_smpl_vto_tshirt/vto_tshirt.obj",
            "truth": f"arcsim_smpl_vto_tshirt/{fr}_garment.obj",
            "body": f"arcsim_smpl_vto_tshirt/{fr}_body.obj",
        },
    }


GPG_PAIRS = {
    "skirt-penetrate": (
        "skirt_pair_basic_vs_penetrate/skirt_maya_coords_sim.obj",
        "skirt_pair_basic_vs_penetrate/skirt_maya_penetrate_sim.obj",
    ),
    "skirt-small": (
        "skirt_pair_too_small/midway.obj",
        "skirt_pair_too_small/skirt_maya_coords_small_sim.obj",
    ),
}
GPG_BODY = "body/f_smpl_templatex300.obj"
#: GPG units per metre (the SMPL female template ×300).
GPG_UNITS = 300.0


def _gpg(name: str) -> dict[str, Any]:
    g = cases_mod.SHARED_DATA / "garment_pattern_generator"
    tpl, tru = GPG_PAIRS[name]
    tv, tf = cases_mod.load_mesh(g / tpl)
    gv, gf = cases_mod.load_mesh(g / tru)
    bv, bf = cases_mod.load_mesh(g / GPG_BODY)
    return {
        "template": tv,
        "faces": tf,
        "truth": gv,
        "body": (bv, bf),
        "units": GPG_UNITS,
        "template_labels": np.ones(len(tv), np.int64),
        "files": {
            "template": f"garment_pattern_generator/{tpl}",
            "truth": f"garment_pattern_generator/{tru}",
            "body": f"garment_pattern_generator/{GPG_BODY}",
        },
    }


def vertex_rotations(src: np.ndarray, dst: np.ndarray, f: np.ndarray, rings: int = 2) -> np.ndarray:
    """Per vertex, the rotation that best maps its ``rings``-ring neighbourhood on the mesh
    ``(src, f)`` onto the same vertices of ``dst`` (Kabsch, centred on the neighbourhood)."""
    from scipy.sparse import coo_matrix, identity

    n = len(src)
    i = np.concatenate([f[:, 0], f[:, 1], f[:, 2], f[:, 1], f[:, 2], f[:, 0]])
    j = np.concatenate([f[:, 1], f[:, 2], f[:, 0], f[:, 0], f[:, 1], f[:, 2]])
    adj = coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n)).tocsr()
    reach = identity(n, format="csr")
    for _ in range(rings):
        reach = reach + reach @ adj
    reach = (reach > 0).astype(float).tocsr()
    deg = np.asarray(reach.sum(1)).ravel()
    ms, md = (reach @ src) / deg[:, None], (reach @ dst) / deg[:, None]
    # H_i = Σ_j (d_j − md_i)(s_j − ms_i)ᵀ = Σ_j d_j s_jᵀ − deg·md_i ms_iᵀ
    outer = (dst[:, :, None] * src[:, None, :]).reshape(n, 9)
    h = (reach @ outer).reshape(n, 3, 3) - deg[:, None, None] * md[:, :, None] * ms[:, None, :]
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(u @ vt))
    u[:, :, 2] *= d[:, None]
    return u @ vt


def transfer_to_body(
    points: np.ndarray,
    src_body: tuple[np.ndarray, np.ndarray],
    dst_body: tuple[np.ndarray, np.ndarray],
    scale: float,
    k: int = 64,
    width: float = 0.05,
) -> np.ndarray:
    """Carries points lying around one body onto another body with the same vertex order and
    faces (SMPL) by a smooth space deformation: each body vertex ``i`` carries the rigid map
    ``p ↦ v'_i + scale · R_i (p − v_i)`` (``R_i``: the rotation of its 2-ring neighbourhood
    between the bodies, Kabsch), and a point moves by the blend of the maps of its ``k``
    nearest body vertices, Gaussian weights of width ``max(2 d_min, width · units)`` (``d_min``
    its distance to the nearest body vertex; ``width`` in metres, ``1/scale`` source units
    per metre). Smooth (unlike a closest-point map, which jumps across the legs' medial
    plane), so a template and its truth, carried by the same map, stay near-isometric; an
    identical destination body leaves the points in place, a rigidly moved one moves them
    rigidly (``scale`` 1)."""
    from scipy.spatial import cKDTree

    sv, f = src_body
    dv, df = dst_body
    if len(sv) != len(dv) or not np.array_equal(f, df):
        raise ValueError("the bodies do not share a vertex order and faces")
    rot = vertex_rotations(sv, dv, f)
    d, nb = cKDTree(sv).query(points, k=k)
    h = np.maximum(2 * d[:, :1], width / scale)
    w = np.exp(-((d / h) ** 2))
    w /= w.sum(1, keepdims=True)
    local = points[:, None, :] - sv[nb]  # (n, k, 3)
    moved = dv[nb] + scale * np.einsum("nkij,nkj->nki", rot[nb], local)
    return (w[:, :, None] * moved).sum(1)


def _two_garment() -> dict[str, Any]:
    """Shirt (ARCSim frame 0000) + the ``too small`` GPG skirt pair carried onto the 0000
    body (:func:`transfer_to_body`, template and truth by the same map). Template as given:
    the shirt template as in its file (turned by 92° against its truth) and the skirt's own
    template (``midway``) carried onto the body; the placed start places each component
    onto its own truth by its similarity (as the single-garment cases)."""
    shirt = _arcsim("0000")
    skirt = _gpg("skirt-small")
    body = shirt["body"]
    tpl = transfer_to_body(skirt["template"], skirt["body"], body, 1 / GPG_UNITS)
    tru = transfer_to_body(skirt["truth"], skirt["body"], body, 1 / GPG_UNITS)
    m = len(shirt["template"])
    return {
        "template": np.concatenate([shirt["template"], tpl]),
        "faces": np.concatenate([shirt["faces"], skirt["faces"] + m]),
        "truth": np.concatenate([shirt["truth"], tru]),
        "body": body,
        "units": 1.0,
        "template_labels": np.r_[np.ones(m, np.int64), np.full(len(tpl), 2)],
        "files": {
            "shirt": shirt["files"],
            "skirt": skirt["files"],
            "skirt transferred": f"{skirt['files']['body']} → {shirt['files']['body']}",
        },
    }


def load_source(name: str) -> dict[str, Any]:
    if name.startswith("tshirt-"):
        return _arcsim(name.split("-", 1)[1])
    if name in GPG_PAIRS:
        return _gpg(name)
    if name == "two-garment":
        return _two_garment()
    raise ValueError(f"unknown dressed source {name!r}")


def place(template: np.ndarray, truth: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """The template moved by the least-squares similarity onto the truth, per component
    label."""
    out = np.empty_like(template)
    for k in np.unique(labels):
        m = labels == k
        s, r, t = cases_mod.umeyama(template[m], truth[m])
        out[m] = template[m] @ (s * r).T + t
    return out


#: When the template as given counts as a rough placement (else it is perturbed).
ROUGH = {"rotation_deg": 20.0, "offset_rel": 0.10, "scale": (0.8, 1.25)}
#: The perturbation of the placed template (when the file's placement is not usable).
PERTURB = {"rotation_deg": 10.0, "shift_rel": 0.05}


def unplaced_start(
    name: str, template: np.ndarray, placed: np.ndarray, truth: np.ndarray, labels: np.ndarray
) -> tuple[np.ndarray, dict[str, Any]]:
    """The template as given when it lies near the garment (per component: the similarity
    onto the truth turns it by ≤ 20°, scales it by 0.8–1.25 and its centroid lies within 10 %
    of the garment's diagonal); otherwise the placed template rotated by 10° about a random
    axis (through its centroid) and shifted by 5 % of the truth's diagonal in a random
    direction (seeded by the case's name)."""
    checks = []
    for k in np.unique(labels):
        m = labels == k
        s, r, _ = cases_mod.umeyama(template[m], truth[m])
        diag = cases_mod.bbox_diagonal(truth[m])
        checks.append(
            {
                "component": int(k),
                "rotation_deg": round(rotation_angle(r), 1),
                "scale": round(s, 3),
                "centroid_offset_rel": round(
                    float(np.linalg.norm(template[m].mean(0) - truth[m].mean(0)) / diag), 3
                ),
            }
        )
    ok = all(
        c["rotation_deg"] <= ROUGH["rotation_deg"]
        and c["centroid_offset_rel"] <= ROUGH["offset_rel"]
        and ROUGH["scale"][0] <= c["scale"] <= ROUGH["scale"][1]
        for c in checks
    )
    if ok:
        return template.copy(), {"unplaced": "the template as given in its file", "as_given": checks}
    rng = np.random.default_rng(zlib.crc32(name.encode()))
    axis = rng.normal(size=3)
    rot = cases_mod.rotation_matrix(axis, PERTURB["rotation_deg"])
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    shift = PERTURB["shift_rel"] * cases_mod.bbox_diagonal(truth) * direction
    c = placed.mean(0)
    out = (placed - c) @ rot.T + c + shift
    return out, {
        "unplaced": f"the placed template turned by {PERTURB['rotation_deg']:g}° "
        f"about a random axis and shifted by {PERTURB['shift_rel']:.0%} "
        "of the truth's diagonal (the file's own placement is not a "
        "rough one)",
        "as_given": checks,
    }


def inside_share(points: np.ndarray, body: tuple[np.ndarray, np.ndarray]) -> float:
    """The share of the points inside the closed body: behind the body's surface at their
    closest point (by the barycentric blend of its vertex normals)."""
    bv, bf = body
    tri, bary, q = closest_on_mesh(points, bv, bf)
    n = (bary[:, :, None] * vertex_normals(bv, bf)[bf[tri]]).sum(1)
    return float((((points - q) * n).sum(1) < 0).mean())


# ---- the cases ---------------------------------------------------------------------------------


@dataclass
class DressedCase(cases_mod.Case):
    """A dressed-body case: a :class:`cases.Case` (``target`` = the scan of this variant) with
    the scan's per-point labels (0 = body) and the template's per-vertex component labels."""

    labels: np.ndarray | None = None
    template_labels: np.ndarray | None = None

    @property
    def mask(self) -> np.ndarray:
        """The 0/1 garment mask of the scan (for ``fm.fit(..., target_weights=mask)``)."""
        return (self.labels > 0).astype(np.float64)


def _settings_key(seed: int) -> str:
    blob = json.dumps([VERSION, SCANNER, ROUGH, PERTURB, seed], sort_keys=True, default=str)
    return hashlib.sha1(blob.encode()).hexdigest()[:10]


def build_source(name: str, seed: int = 0, cache: bool = True) -> dict[str, Any]:
    """Everything about one dressed source for one scanner seed (cached under
    ``bench/out/dressed/``): template (as given), faces, truth, placed and unplaced starts,
    template component labels, scan points and labels, and the meta."""
    path = OUT / f"{name}-seed{seed}-{_settings_key(seed)}.npz"
    if cache and path.is_file():
        with np.load(path) as z:
            out = {k: z[k] for k in z.files if k != "meta"}
            out["meta"] = json.loads(str(z["meta"]))
        return out
    t0 = time.perf_counter()
    src = load_source(name)
    tl = src["template_labels"]
    placed = place(src["template"], src["truth"], tl)
    unplaced, how = unplaced_start(name, src["template"], placed, src["truth"], tl)
    bv, bf = src["body"]
    meshes = [(bv, bf, 0)] + [
        (src["truth"], src["faces"][tl[src["faces"][:, 0]] == k], int(k)) for k in np.unique(tl)
    ]
    sc = scan(meshes, src["units"], seed=zlib.crc32(f"{name}/{seed}".encode()))
    split = "tune" if name in TUNE else "held-out"
    if seed != 0:
        split = "held-out (seed)"
    meta = {
        "source": name,
        "split": split,
        "units_per_metre": src["units"],
        "files": src["files"],
        "scan": sc.info,
        **how,
        "garment_inside_body": round(inside_share(src["truth"], src["body"]), 4),
    }
    if name == "two-garment":
        for key in ("template", "truth"):  # the carried skirt's vertices inside the body
            meta[f"skirt_{key}_inside_body"] = round(inside_share(src[key][tl == 2], src["body"]), 4)
    meta["build_s"] = round(time.perf_counter() - t0, 2)
    out = {
        "template": src["template"],
        "faces": src["faces"],
        "truth": src["truth"],
        "placed": placed,
        "unplaced": unplaced,
        "template_labels": tl,
        "scan": sc.points,
        "labels": sc.labels,
        "meta": meta,
    }
    if cache:
        OUT.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        np.savez(tmp, **{k: v for k, v in out.items() if k != "meta"}, meta=np.array(json.dumps(meta)))
        tmp.replace(path)
        for stale in OUT.glob(f"{name}-seed{seed}-*.npz"):  # other settings' scans
            if stale != path:
                stale.unlink(missing_ok=True)
    return out


#: Case variants: (scan, start).
VARIANTS = {
    "whole": ("whole", "placed"),
    "body-free": ("body-free", "placed"),
    "whole-unplaced": ("whole", "unplaced"),
    "body-free-unplaced": ("body-free", "unplaced"),
}


def make_case(name: str, built: dict[str, Any], variant: str, group: str = "dressed") -> DressedCase:
    scan_kind, start = VARIANTS[variant]
    keep = slice(None) if scan_kind == "whole" else built["labels"] > 0
    return DressedCase(
        name=f"dressed-{name}-{variant}",
        group=group,
        template_vertices=np.ascontiguousarray(built[start]),
        faces=built["faces"],
        target=np.ascontiguousarray(built["scan"][keep]),
        ground_truth=built["truth"],
        meta={**built["meta"], "variant": variant, "start": start, "scan_kind": scan_kind},
        labels=built["labels"][keep],
        template_labels=built["template_labels"],
    )


def dressed_cases(
    variants: tuple[str, ...] = ("whole",), seed: int = 0, sources: tuple[str, ...] = SOURCES
) -> list[DressedCase]:
    """The dressed cases (bench/variants.py's group ``dressed``: the whole scans, placed
    template); none (and a note on stderr) when ../shared/data is missing."""
    why = cases_mod.real_data_missing()
    if why:
        print(f"group dressed: dressed-body cases skipped: {why}", file=sys.stderr)
        return []
    out = []
    for name in sources:
        built = build_source(name, seed)
        out += [make_case(name, built, v) for v in variants]
    return out


def rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(((a - b) ** 2).sum(1).mean()))
