"""Ablation of the fidelity options beyond the paper (docs/method.md, issue "Fidelity").

Each option is switched on alone on top of the paper preset, then the chosen combination (the
default), on a generated sheet and real garment pairs from ../shared/data whose targets are
resampled as noisy 5,000-point clouds (no method sees the vertex order).

    .venv/bin/python -m bench.fidelity [--out bench/out/fidelity.json]
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

import foldmatch_rs as fm
import numpy as np

SHARED = pathlib.Path(__file__).resolve().parents[2] / "shared" / "data"

VARIANTS = [
    ("paper preset", {"preset": "paper"}),
    ("paper + two-way attraction", {"preset": "paper", "two_way": 1.0}),
    ("paper + rigid phase (30%)", {"preset": "paper", "rigid_fraction": 0.3}),
    ("paper + rigid 30% + coarse 30%", {"preset": "paper", "rigid_fraction": 0.3,
                                        "coarse_fraction": 0.3}),
    ("paper + softening annealing ×3", {"preset": "paper", "anneal": 3.0,
                                        "anneal_fraction": 0.6}),
    ("paper + 3-ring", {"preset": "paper", "rings": 3}),
    ("default (two-way + rigid + coarse)", {}),
    ("default + 3-ring", {"rings": 3}),
]


def load(rel):
    import trimesh

    m = trimesh.load(SHARED / rel, process=False, maintain_order=True, force="mesh")
    return np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)


def scan_of(v, f, n=5000, noise=0.002, seed=0):
    import trimesh

    pts, _ = trimesh.sample.sample_surface(trimesh.Trimesh(v, f, process=False), n, seed=seed)
    diag = np.linalg.norm(v.max(0) - v.min(0))
    return pts + np.random.default_rng(seed).normal(size=pts.shape) * noise * diag


def cases():
    c = fm.folded_sheet(nx=41, ny=41, scan_points=4000, noise=0.002)
    yield "generated sheet (8°, offset, noise)", (c["template_vertices"], c["faces"], c["scan"],
                                                  c["ground_truth"])
    if not SHARED.is_dir():
        print(f"skipping real cases: {SHARED} not found")
        return
    tv, tf = load("arcsim_smpl_vto_tshirt/vto_tshirt.obj")
    for frame in ("arm", "0000", "0200"):
        gv, _ = load(f"arcsim_smpl_vto_tshirt/{frame}_garment.obj")
        yield f"T-shirt → {frame} frame", (tv, tf, scan_of(gv, tf), gv)
    sv, sf = load("garment_pattern_generator/skirt_pair_basic_vs_penetrate/skirt_maya_coords_sim.obj")
    pv, _ = load("garment_pattern_generator/skirt_pair_basic_vs_penetrate/skirt_maya_penetrate_sim.obj")
    yield "skirt basic → penetrate", (sv, sf, scan_of(pv, sf), pv)
    w0, wf = load("diffcloth/tshirt1000_wind_sim/iter0/0.obj")
    for frame in (100, 250):
        wv, _ = load(f"diffcloth/tshirt1000_wind_sim/iter0/{frame}.obj")
        yield f"wind T-shirt frame 0 → {frame}", (w0, wf, scan_of(wv, wf), wv)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="bench/out/fidelity.json")
    args = ap.parse_args()
    rows = []
    print("| case | variant | f_R | f_F (truth's) | f_H | scan→fit / diag | f_λ | s |")
    print("|---|---|---|---|---|---|---|---|")
    for name, (t, f, x, g) in cases():
        truth_ff = fm.evaluate(t, f, g, x, g)["f_F"]
        ident = fm.evaluate(t, f, t, x, g)
        print(f"| {name} | identity | {ident['f_R']:.4f} | 0.000 ({truth_ff:.3f}) | 1.000 | "
              f"{ident['scan_to_fit_mean'] / ident['target_diagonal']:.4f} | "
              f"{ident['f_lambda']:.3f} | |")
        for label, opts in VARIANTS:
            start = time.perf_counter()
            r = fm.fit(t, f, x, **opts)
            secs = time.perf_counter() - start
            m = fm.evaluate(t, f, r.vertices, x, g)
            rows.append({"case": name, "variant": label, "seconds": secs, **m})
            print(f"| {name} | {label} | {m['f_R']:.4f} | {m['f_F']:.3f} ({truth_ff:.3f}) | "
                  f"{m['f_H']:.3f} | {m['scan_to_fit_mean'] / m['target_diagonal']:.4f} | "
                  f"{m['f_lambda']:.3f} | {secs:.1f} |", flush=True)
    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(rows, indent=1, default=float))


if __name__ == "__main__":
    main()
