"""The figures of the full comparison (docs/notes/comparison-full-run.md; matplotlib, headless):
box plots of every metric per method over sample sets (paper Fig. 6), f_λ per iteration (Fig. 4),
the accumulated wrinkle-field magnitude for 1- to 4-ring neighborhoods (Fig. 5) and before/after overlays."""

from __future__ import annotations

import pathlib
from typing import Any

import numpy as np

from bench import render
from bench.render import plt
from bench.report import NAMES, label

COLORS = {
    "foldmatch": "#d62728",
    "nrga": "#ff9896",
    "cpd_pycpd": "#1f77b4",
    "cpd_probreg": "#6baed6",
    "cpd_rustcpd": "#08519c",
    "bcpd_probreg": "#9467bd",
    "nricp_amberg": "#2ca02c",
    "nricp_sumner": "#98df8a",
    "identity": "#bbbbbb",
    "oracle": "#555555",
}


def _save(fig, path: pathlib.Path, dpi: int = 90) -> pathlib.Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return path


def boxplots(records: list[dict], methods: list[str], path: pathlib.Path, title: str) -> pathlib.Path:
    keys = ["f_R", "s2f_p95_rel", "f_H", "f_S", "f_E", "f_F", "f_lambda", "wall_s"]
    order = ["identity", "oracle"] + methods
    fig, axes = plt.subplots(2, 4, figsize=(17, 7.5))
    for ax, k in zip(axes.ravel(), keys):
        data, names, cols = [], [], []
        for m in order:
            if k == "wall_s" and m in ("identity", "oracle"):
                continue
            v = [
                r["rows"][m][k]
                for r in records
                if r["rows"].get(m, {}).get("status") == "ok"
                and r["rows"][m].get(k) is not None
                and np.isfinite(r["rows"][m][k])
            ]
            if v:
                data.append(v)
                names.append(label(m))
                cols.append(COLORS.get(m, "#999999"))
        if not data:
            ax.set_visible(False)
            continue
        bp = ax.boxplot(data, patch_artist=True, widths=0.6, showfliers=True, flierprops={"markersize": 3})
        for patch, c in zip(bp["boxes"], cols):
            patch.set_facecolor(c)
            patch.set_alpha(0.85)
        for med in bp["medians"]:
            med.set_color("k")
        ax.set_xticks(range(1, len(names) + 1))
        ax.set_xticklabels(names, rotation=55, ha="right", fontsize=8)
        ax.set_title(NAMES.get(k, k) + (" (log)" if k == "wall_s" else ""), fontsize=10)
        if k == "wall_s":
            ax.set_yscale("log")
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(title, fontsize=12)
    fig.tight_layout()
    return _save(fig, path, dpi=80)


def traces(
    curves: dict[str, dict[str, dict[str, list[float]]]], path: pathlib.Path, title: str
) -> pathlib.Path:
    """``curves[case][method] = {"f_lambda": [...], "f_R": [...]}`` (index = iteration)."""
    cases = list(curves)
    fig, axes = plt.subplots(2, len(cases), figsize=(6.2 * len(cases), 7.5), squeeze=False)
    for j, c in enumerate(cases):
        for i, k in enumerate(("f_lambda", "f_R")):
            ax = axes[i, j]
            for m, cv in curves[c].items():
                if m in ("oracle", "identity"):
                    continue
                y = cv.get(k)
                if y:
                    ax.plot(np.arange(len(y)), y, color=COLORS.get(m), label=label(m), lw=1.6)
            if "oracle" in curves[c] and curves[c]["oracle"].get(k):
                ax.axhline(curves[c]["oracle"][k][0], color="k", ls="--", lw=1, label="oracle (truth)")
            ax.set_xlabel("iteration")
            ax.set_ylabel(NAMES[k])
            ax.set_title(f"{c}: {NAMES[k]} per iteration", fontsize=10)
            ax.grid(alpha=0.3)
            if i == 0 and j == 0:
                ax.legend(fontsize=8)
    fig.suptitle(title, fontsize=12)
    fig.tight_layout()
    return _save(fig, path)


def _front(points: np.ndarray, up: int) -> tuple[np.ndarray, np.ndarray, float]:
    r, elev = render.principal_frame(points, up)
    return r, points.mean(0), elev


def rings(
    target: np.ndarray,
    target_faces: np.ndarray | None,
    fits: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]],
    path: pathlib.Path,
    title: str,
    up: int = 1,
    azim: float = -90,
) -> pathlib.Path:
    """The target and the fitted mesh colored by the accumulated WVF magnitude per ring."""
    r, c, elev = _front(target, up)

    def tf(p: np.ndarray) -> np.ndarray:
        return (p - c) @ r.T

    allm = np.concatenate([m for _, _, m in fits.values()])
    lo, hi = np.percentile(allm, [2, 98])
    n = len(fits) + 1
    fig = plt.figure(figsize=(4.2 * n, 4.8))
    ax = fig.add_subplot(1, n, 1, projection="3d")
    if target_faces is not None:
        render.draw_mesh(ax, tf(target), target_faces, elev=elev, azim=azim)
    else:
        render.draw_points(ax, tf(target), size=0.6, alpha=0.6)
    render.frame_axes(ax, tf(target))
    ax.set_title("target", fontsize=10)
    for i, (ring, (v, f, mag)) in enumerate(sorted(fits.items())):
        ax = fig.add_subplot(1, n, i + 2, projection="3d")
        render.draw_mesh(ax, tf(v), f, values=mag, vmin=lo, vmax=hi, cmap="inferno", elev=elev, azim=azim)
        render.frame_axes(ax, tf(target))
        ax.set_title(f"{ring}-ring: |v| accumulated", fontsize=10)
    sm = plt.cm.ScalarMappable(cmap="inferno", norm=plt.Normalize(lo, hi))
    fig.colorbar(sm, ax=fig.axes, fraction=0.015, pad=0.01, label="|v| (accumulated WVF)")
    fig.suptitle(title, fontsize=11)
    return _save(fig, path, dpi=75)


def overlay(
    case: Any,
    fits: dict[str, np.ndarray],
    stats: dict[str, dict],
    path: pathlib.Path,
    up: int = 2,
    azim: float = -90,
) -> pathlib.Path:
    """Before (template + target points) and after (each fit colored by its distance to the
    ground truth, in % of the target diagonal; the color scale ends at the 90th percentile
    of all shown fits' errors)."""
    tgt = case.target
    r, c, elev = _front(tgt, up)

    def tf(p: np.ndarray) -> np.ndarray:
        return (p - c) @ r.T

    diag = float(np.linalg.norm(tgt.max(0) - tgt.min(0)))
    both = np.concatenate([tf(tgt), tf(case.template_vertices)])
    n = len(fits) + 2
    fig = plt.figure(figsize=(3.9 * n, 4.4))
    ax = fig.add_subplot(1, n, 1, projection="3d")
    render.draw_mesh(ax, tf(case.template_vertices), case.faces, alpha=0.55, elev=elev, azim=azim)
    render.draw_points(ax, tf(tgt), color="k", size=0.25, alpha=0.35)
    render.frame_axes(ax, both)
    ax.set_title("before: template + scan points", fontsize=9)
    ax = fig.add_subplot(1, n, 2, projection="3d")
    if case.target_faces is not None:
        render.draw_mesh(ax, tf(tgt), case.target_faces, elev=elev, azim=azim)
    elif case.ground_truth is not None:
        render.draw_mesh(ax, tf(case.ground_truth), case.faces, elev=elev, azim=azim)
    else:
        render.draw_points(ax, tf(tgt), size=0.5)
    render.frame_axes(ax, both)
    ax.set_title("truth" if case.ground_truth is not None else "target", fontsize=9)
    vmax = 3.0
    if case.ground_truth is not None and fits:
        errs = (
            np.concatenate([np.linalg.norm(v - case.ground_truth, axis=1) for v in fits.values()])
            / diag
            * 100
        )
        vmax = float(max(0.5, np.ceil(np.percentile(errs, 90) * 2) / 2))
    for i, (m, v) in enumerate(fits.items()):
        ax = fig.add_subplot(1, n, i + 3, projection="3d")
        err = (
            np.linalg.norm(v - case.ground_truth, axis=1) / diag * 100
            if case.ground_truth is not None
            else None
        )
        render.draw_mesh(
            ax, tf(v), case.faces, values=err, vmin=0, vmax=vmax, cmap="turbo", elev=elev, azim=azim
        )
        render.frame_axes(ax, both)
        s = stats.get(m, {})
        ax.set_title(
            f"{label(m)}\nf_R={s.get('f_R', float('nan')):.4f}  f_F={s.get('f_F', float('nan')):.3f}",
            fontsize=9,
        )
    if case.ground_truth is not None:
        sm = plt.cm.ScalarMappable(cmap="turbo", norm=plt.Normalize(0, vmax))
        fig.colorbar(sm, ax=fig.axes, fraction=0.012, pad=0.01, label="distance to truth (% of diagonal)")
    fig.suptitle(f"{case.name} ({case.sizes})", fontsize=11)
    return _save(fig, path, dpi=70)
