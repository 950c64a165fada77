"""A physically simulated 4D sequence with per-frame ground truth, for the tracking benchmark
(issue 28; bench/tracking.py ``--sequence sim-flag``).

The harness's ``flag`` scene (bench/sim_cloth.py: a 1.0 × 0.6 m flag, 41 × 25 vertices, its
pole edge pinned, blown by a gusty wind) run for 2 s at 60 frames per second by the same
simulator (Newton's VBD cloth solver on Warp's CPU device), its positions recorded every
:data:`EVERY` frames (a 30 Hz capture). The frames after :data:`FIRST` (1.2 s, once the flag
has left its flat rest state and flaps) are the sequence, 24 frames: its first frame's mesh is
the tracking template, every frame's positions its truth. The flag moves 1–4 % of its diagonal
between frames (mean vertex motion; the DiffCloth wind T-shirt about 0.6 %), twisting and
flapping. Unlike the DiffCloth sequences it was made by code in the repository, with other
cloth, motion and density; no tracking setting was chosen on it (a held-out sequence).

The recorded frames are stored in ``bench/data/sim/flag-sequence.npz`` (float32, 0.27 MB) so
that the benchmark needs no simulator; ``python -m bench.sim_sequence`` regenerates them
(Newton, bench/requirements-sim.txt; 14 s on 2 cores once Warp's kernels are compiled, about
2 minutes on the first run).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import sys

import numpy as np

from bench import sim_cloth

#: Record the positions after every this many simulated frames (60 per second): 30 per second.
EVERY = 2
#: The sequence starts after this simulated frame (1.2 s: the flag flaps).
FIRST = 72
#: The scene: the harness's flag, simulated for 2 s.
SCENE = dataclasses.replace(sim_cloth.SCENES["flag"], name="flag-sequence", frames=120)
PATH = sim_cloth.STATES / "flag-sequence.npz"


def settings_key() -> str:
    blob = json.dumps([sim_cloth.settings_key(SCENE), EVERY, FIRST], sort_keys=True)
    return hashlib.sha1(blob.encode()).hexdigest()[:12]


def load() -> tuple[np.ndarray, np.ndarray, dict] | None:
    """(recorded frames (T, V, 3), faces, info), or None when not stored yet."""
    if not PATH.is_file():
        return None
    _, faces = sim_cloth.rest_mesh(SCENE)
    with np.load(PATH) as z:
        return z["frames"].astype(float), faces, json.loads(str(z["info"]))


def generate(force: bool = False) -> tuple[np.ndarray, np.ndarray, dict]:
    """The recorded frames, simulated and stored when missing or made with other settings."""
    stored = None if force else load()
    key = settings_key()
    if stored is not None and stored[2].get("key") == key:
        return stored
    print(f"simulating {SCENE.name} ({SCENE.vertices} vertices, {SCENE.frames} frames)", flush=True)
    r = sim_cloth.simulate(SCENE, verbose=True, record_every=EVERY)
    assert r.frames is not None
    kept = r.frames[FIRST // EVERY :]
    info = {**r.info, "key": key, "record_every": EVERY, "first_frame": FIRST + EVERY}
    PATH.parent.mkdir(parents=True, exist_ok=True)
    tmp = PATH.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, frames=kept.astype(np.float32), info=json.dumps(info))
    tmp.replace(PATH)
    print(f"  {len(kept)} frames stored in {PATH} ({r.info['seconds']} s)")
    return kept.astype(np.float32).astype(float), r.faces, info


def frames() -> list[tuple[int, np.ndarray, np.ndarray]]:
    """(simulated frame number, positions, faces) of the sequence's frames, in order."""
    stored = load()
    if stored is None:
        raise SystemExit(f"{PATH} is missing: run `python -m bench.sim_sequence` (needs Newton)")
    recorded, faces, info = stored
    first = int(info["first_frame"])
    return [(first + i * EVERY, recorded[i], faces) for i in range(len(recorded))]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--force", action="store_true", help="simulate again even when stored")
    args = ap.parse_args()
    generate(force=args.force)
    return 0


if __name__ == "__main__":
    sys.exit(main())
