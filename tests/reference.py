"""A small, readable NumPy implementation of one FoldMatch iteration (SPEC §2), kept as the
independent reference the Rust core is tested against (and as the same-algorithm baseline of
the benchmarks). Loops over vertices for clarity, LAPACK (numpy.linalg) for the 3×3 algebra.
"""

from __future__ import annotations

from collections import deque

import numpy as np

DEFAULTS = dict(
    gravity=1.67,
    softening=0.1,
    damping=0.1,
    time_step=0.006,
    template_mass=1.0,
    target_mass=1.0,
    alpha_floor=0.1,
    numerator="centered",
    summation="mean",
    damping_mode="fraction",
    psi=0.05,
    normal_completion=0.3,
    rings=2,
    regularization="affine_invariant",
    rotation_source="regularized",
)


# ---- N-body step (Eq. 2–3) ----------------------------------------------------------------


def nbody_step(y, v, x, neighbours, kappa, **kw):
    p = {**DEFAULTS, **kw}
    omega = p["gravity"] * p["template_mass"] * p["target_mass"]
    v_new = np.empty_like(v)
    proposed = np.empty_like(y)
    for k in range(len(y)):
        f = np.zeros(3)
        for j in neighbours[k]:
            diff = y[k] - x[j]
            d2 = diff @ diff
            alpha = max(1.0 - 0.5 * kappa[j] * d2, p["alpha_floor"])
            num = alpha * diff if p["numerator"] == "centered" else alpha * y[k] - x[j]
            f -= omega * num / ((d2 + p["softening"] ** 2) ** 1.5 * alpha**1.5)
        if p["summation"] == "mean":
            f /= len(neighbours[k])
        dt, m, eta = p["time_step"], p["template_mass"], p["damping"]
        if p["damping_mode"] == "fraction":
            v_new[k] = (1 - eta) * v[k] + f / m * dt
        else:
            v_new[k] = v[k] + (f - eta * v[k]) / m * dt
        proposed[k] = y[k] + v_new[k] * dt
    return v_new, proposed


# ---- mesh helpers -------------------------------------------------------------------------


def n_rings(faces, n_vertices, rings):
    adj = [set() for _ in range(n_vertices)]
    for a, b, c in faces:
        for u, w in ((a, b), (b, c), (c, a)):
            adj[u].add(w)
            adj[w].add(u)
    out = []
    for s in range(n_vertices):
        dist = {s: 0}
        q = deque([s])
        while q:
            u = q.popleft()
            if dist[u] == rings:
                continue
            for w in adj[u]:
                if w not in dist:
                    dist[w] = dist[u] + 1
                    q.append(w)
        out.append(sorted(dist, key=lambda w: (dist[w], w)))
    return out


def vertex_normals(p, faces):
    n = np.zeros_like(p)
    for f in faces:
        a, b, c = p[f]
        cr = np.cross(b - a, c - a)
        n[f] += cr
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)


# ---- 3×3 algebra --------------------------------------------------------------------------


def sym_fn(m, fn):
    w, v = np.linalg.eigh(0.5 * (m + m.T))
    return (v * fn(w)) @ v.T


def nearest_rotation(m):
    u, _, vt = np.linalg.svd(m)
    d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
    return u @ d @ vt


def polar(h):
    _, s, vt = np.linalg.svd(h)
    return nearest_rotation(h), vt.T @ np.diag(s) @ vt


# ---- FoldMatch update (Eq. 4–8) -----------------------------------------------------------


def deformation_gradient(k, ring, old, new, n_old, n_new, completion):
    beta = 1.0 / len(ring)
    d = old[ring] - old[k]
    dn = new[ring] - new[k]
    a = beta * dn.T @ d
    b = beta * d.T @ d
    if completion > 0 and n_old[k] @ n_old[k] > 0.5 and n_new[k] @ n_new[k] > 0.5:
        len_old, len_new = beta * (d**2).sum(), beta * (dn**2).sum()
        w = max(completion * np.trace(b) / 3 - max(np.linalg.eigvalsh(b)[0], 0.0), 0.0)
        if w > 0 and len_old > 0:
            s = np.sqrt(len_new / len_old)
            a = a + w * s * np.outer(n_new[k], n_old[k])
            b = b + w * np.outer(n_old[k], n_old[k])
    w, v = np.linalg.eigh(b)
    keep = w > 1e-9 * w.max()
    inv = (v[:, keep] / w[keep]) @ v[:, keep].T
    null = v[:, ~keep] @ v[:, ~keep].T
    return a @ inv + null


def modified_stretch(u, psi):
    w, v = np.linalg.eigh(u)
    w, v = w[::-1], v[:, ::-1]
    raw = np.array([w[0] + psi, w[1] - psi / 2, w[2] - psi / 2])
    s = np.sqrt((raw**2).sum() / 3)
    u_hat = (v * (raw / s)) @ v.T
    e1 = v[:, 0]
    first = e1[np.abs(e1) > 1e-12][0]
    if first < 0:
        e1 = -e1
    return u_hat, raw[0] / s * e1


def foldmatch_update(old, new, faces, **kw):
    """Returns (updated positions, per-step wrinkle-vector field)."""
    p = {**DEFAULTS, **kw}
    m = len(old)
    rings = n_rings(faces, m, p["rings"])
    n_old, n_new = vertex_normals(old, faces), vertex_normals(new, faces)
    raw = [
        deformation_gradient(k, rings[k], old, new, n_old, n_new, p["normal_completion"]) for k in range(m)
    ]
    rot, stretch = zip(*(polar(h) for h in raw))
    out = np.empty_like(old)
    wvf = np.empty_like(old)
    for k in range(m):
        ring = rings[k]
        beta = 1.0 / len(ring)
        if p["regularization"] == "log_euclidean":
            u_bar = sym_fn(sum(beta * sym_fn(stretch[j], np.log) for j in ring), np.exp)
        else:  # affine-invariant (Eq. 5 on the stretch part)
            root = sym_fn(stretch[k], np.sqrt)
            inv_root = sym_fn(stretch[k], lambda x: 1 / np.sqrt(x))
            logs = sum(beta * sym_fn(inv_root @ stretch[j] @ inv_root, np.log) for j in ring)
            u_bar = root @ sym_fn(logs, np.exp) @ root
        r_bar = nearest_rotation(sum(beta * rot[j] for j in ring))
        u_hat, wvf[k] = modified_stretch(u_bar, p["psi"])
        h = r_bar @ u_bar if p["rotation_source"] == "regularized" else raw[k]
        r_star = nearest_rotation(h @ u_hat.T)
        c_old, c_new = old[ring].mean(0), new[ring].mean(0)
        out[k] = c_new + r_star @ (old[k] - c_old)
    return out, wvf
