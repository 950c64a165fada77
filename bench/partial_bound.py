"""How far the seen half of a front-only scan determines the unseen half (issue 27's
half-scan figure; docs/notes/partial-scans.md "What the seen half determines").

For every case of ``bench.partial``: the truth's vertices the rig saw (within two scan spacings
of its half scan, ``partial.seen_vertices``) are fixed at the truth, and the
others are placed by the as-rigid-as-possible deformation of the template (Sorkine & Alexa
2007, cotangent weights, 30 local/global rounds from the template's rigid fit onto the seen
vertices) — the completion that keeps the template's shape where nothing is seen. Its f_R is
what a fit that placed every seen vertex exactly would reach with the template's shape as its
only prior for the rest; printed as a ratio to the default's whole-scan fit, next to the
default's own half fit.

    python -m bench.partial_bound [--groups real,small] [--cases NAME,...]

Needs scipy (requirements-dev.txt).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from bench import partial, variants
from bench.cases import umeyama

ROUNDS = 30


def cotangent_weights(v: np.ndarray, f: np.ndarray):
    """The cotangent Laplacian's edge weights (each ½ Σ cot of the opposite angles), clamped
    at a small positive value (obtuse triangles), as a symmetric sparse matrix."""
    import scipy.sparse as sp

    rows, cols, vals = [], [], []
    for a, b, c in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        i, j, k = f[:, a], f[:, b], f[:, c]
        u, w = v[i] - v[k], v[j] - v[k]
        cross = np.linalg.norm(np.cross(u, w), axis=1)
        cot = np.einsum("ij,ij->i", u, w) / np.maximum(cross, 1e-12)
        rows += [i, j]
        cols += [j, i]
        vals += [0.5 * cot, 0.5 * cot]
    n = len(v)
    ij = (np.concatenate(rows), np.concatenate(cols))
    weights = sp.coo_matrix((np.concatenate(vals), ij), shape=(n, n)).tocsr()
    weights.data = np.maximum(weights.data, 1e-4)
    return weights


def arap_completion(rest: np.ndarray, faces: np.ndarray, start: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """``start`` with its vertices outside ``fixed`` moved to the as-rigid-as-possible
    deformation of ``rest`` that keeps the ``fixed`` ones where they are."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spl

    w = cotangent_weights(rest, faces).tocoo()
    n = len(rest)
    i, j, wij = w.row, w.col, w.data
    lap = (sp.diags(np.asarray(w.tocsr().sum(1)).ravel()) - w.tocsr()).tocsr()
    free = ~fixed
    # A tiny pull to the start keeps free parts with no fixed vertex solvable.
    eps = 1e-6 * lap.diagonal().mean()
    solve = spl.factorized((lap[free][:, free] + eps * sp.identity(int(free.sum()))).tocsc())
    coupling = lap[free][:, fixed]
    pos = start.copy()
    edges = rest[i] - rest[j]
    for _ in range(ROUNDS):
        # Local step: each vertex's rotation, the Kabsch fit of its rest edges onto its current ones.
        cov = np.zeros((n, 3, 3))
        np.add.at(cov, i, wij[:, None, None] * edges[:, :, None] * (pos[i] - pos[j])[:, None, :])
        u, _, vt = np.linalg.svd(cov)
        flip = np.linalg.det(np.einsum("nji,nkj->nik", vt, u)) < 0
        vt[flip, 2, :] *= -1
        rot = np.einsum("nji,nkj->nik", vt, u)
        # Global step: the positions whose edges best match the rotated rest edges.
        rhs = np.zeros((n, 3))
        np.add.at(rhs, i, (0.5 * wij[:, None]) * np.einsum("nij,nj->ni", rot[i] + rot[j], edges))
        b = rhs[free] - coupling @ pos[fixed] + eps * start[free]
        pos[free] = np.column_stack([solve(b[:, d]) for d in range(3)])
    return pos


def rigid_onto(a: np.ndarray, b: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``points`` moved by the rigid motion that best takes ``a`` onto ``b`` (the rotation of
    ``cases.umeyama``, its scale left at 1)."""
    _, rot, _ = umeyama(a, b)
    return (points - a.mean(0)) @ rot.T + b.mean(0)


def main() -> int:
    import foldmatch_rs as fm

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--groups", default="real,small")
    ap.add_argument("--cases", default="", help="comma-separated case names (default: all)")
    args = ap.parse_args()
    names = {c for c in args.cases.split(",") if c}
    print("| case | f_R whole | half fit ÷ whole | seen at the truth, rest ARAP ÷ whole | unseen |")
    print("| :--- | ---: | ---: | ---: | ---: |")
    bound = []
    for group in args.groups.split(","):
        for case in variants.group_cases(group):
            if case.ground_truth is None or (names and case.name not in names):
                continue
            x, f, truth = case.template_vertices, case.faces, case.ground_truth
            half = partial.half_scan(case)
            seen = partial.seen_vertices(truth, half)

            def f_r(v: np.ndarray, case=case) -> float:
                e = fm.evaluate(case.template_vertices, case.faces, v, case.target, case.ground_truth)
                return e["f_R"]

            whole = f_r(fm.fit(x, f, case.target, target_faces=case.target_faces).vertices)
            fitted = f_r(fm.fit(x, f, half).vertices)
            start = rigid_onto(x[seen], truth[seen], x)
            start[seen] = truth[seen]
            completed = f_r(arap_completion(x, f, start, seen))
            bound.append(completed / whole)
            print(
                f"| {case.name} | {whole:.4f} | {fitted / whole:.2f} | {completed / whole:.2f} "
                f"| {1 - seen.mean():.1%} |",
                flush=True,
            )
    within = sum(b <= 2 for b in bound)
    print(f"\nseen at the truth, rest ARAP: within 2× of the whole fit on {within} of {len(bound)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
