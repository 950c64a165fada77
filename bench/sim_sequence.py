"""Physically simulated 4D sequences with per-frame ground truth, for the tracking benchmark
(issue 28; bench/tracking.py ``--sequence sim-flag|sim-flag2|sim-drape``).

``sim-flag``: the harness's ``flag`` scene (bench/sim_cloth.py: a 1.0 × 0.6 m flag, 41 × 25
vertices, its pole edge pinned, blown by a gusty wind) run for 2 s at 60 frames per second by
the same simulator (Newton's VBD cloth solver on Warp's CPU device), its positions recorded
every :data:`EVERY` frames (a 30 Hz capture). The frames after 1.2 s (once the flag has left its
flat rest state and flaps) are the sequence, 24 frames: its first frame's mesh is the tracking
template, every frame's positions its truth. The flag moves 1–4 % of its diagonal between
frames (mean vertex motion; the DiffCloth wind T-shirt about 0.6 %), twisting and flapping.

``sim-flag2``: the same flag in another wind (seed 7, mean 10 m/s²), 24 frames from 1.2 s.
``sim-drape``: the harness's ``sphere`` scene (a 1 × 1 m sheet, 41 × 41 vertices, dropped onto
a sphere) from 0.3 s, as it lands and folds over the sphere, 32 frames at 30 Hz (the first
moving up to 4 % of the diagonal a frame, the last settling).

Unlike the DiffCloth sequences they were made by code in the repository, with other cloth,
motion and density; they are held out (the tracking settings were chosen on ``iter0``).

The recorded frames are stored in ``bench/data/sim/<scene>.npz`` (float32) so that the
benchmark needs no simulator; ``python -m bench.sim_sequence [--sequence NAME]`` regenerates
them (Newton, bench/requirements-sim.txt; 15–60 s each on 2 cores once Warp's kernels are
compiled, about 2 minutes more on the first run).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import sys
from typing import Any

import numpy as np

from bench import sim_cloth

#: Record the positions after every this many simulated frames (60 per second): 30 per second.
EVERY = 2


@dataclasses.dataclass(frozen=True)
class Sequence:
    """A recorded stretch of a simulated scene: its frames after simulated frame ``first``."""

    scene: sim_cloth.Scene
    first: int

    @property
    def path(self) -> Any:
        return sim_cloth.STATES / f"{self.scene.name}.npz"


#: The simulated sequences by their benchmark name.
_FLAG, _SPHERE = sim_cloth.SCENES["flag"], sim_cloth.SCENES["sphere"]
SEQUENCES: dict[str, Sequence] = {
    "sim-flag": Sequence(dataclasses.replace(_FLAG, name="flag-sequence", frames=120), 72),
    "sim-flag2": Sequence(
        dataclasses.replace(_FLAG, name="flag2-sequence", frames=120, seed=7, wind=10.0), 72
    ),
    "sim-drape": Sequence(dataclasses.replace(_SPHERE, name="drape-sequence", frames=80), 16),
}
#: The first sequence (its scene and file, as earlier code names them).
SCENE = SEQUENCES["sim-flag"].scene
PATH = SEQUENCES["sim-flag"].path


def settings_key(seq: Sequence) -> str:
    blob = json.dumps([sim_cloth.settings_key(seq.scene), EVERY, seq.first], sort_keys=True)
    return hashlib.sha1(blob.encode()).hexdigest()[:12]


def load(seq: Sequence) -> tuple[np.ndarray, np.ndarray, dict] | None:
    """(recorded frames (T, V, 3), faces, info), or None when not stored yet."""
    if not seq.path.is_file():
        return None
    _, faces = sim_cloth.rest_mesh(seq.scene)
    with np.load(seq.path) as z:
        return z["frames"].astype(float), faces, json.loads(str(z["info"]))


def generate(seq: Sequence, force: bool = False) -> tuple[np.ndarray, np.ndarray, dict]:
    """The recorded frames, simulated and stored when missing or made with other settings."""
    stored = None if force else load(seq)
    key = settings_key(seq)
    if stored is not None and stored[2].get("key") == key:
        return stored
    scene = seq.scene
    print(f"simulating {scene.name} ({scene.vertices} vertices, {scene.frames} frames)", flush=True)
    r = sim_cloth.simulate(scene, verbose=True, record_every=EVERY)
    assert r.frames is not None
    kept = r.frames[seq.first // EVERY :]
    info = {**r.info, "key": key, "record_every": EVERY, "first_frame": seq.first + EVERY}
    seq.path.parent.mkdir(parents=True, exist_ok=True)
    tmp = seq.path.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, frames=kept.astype(np.float32), info=json.dumps(info))
    tmp.replace(seq.path)
    print(f"  {len(kept)} frames stored in {seq.path} ({r.info['seconds']} s)")
    return kept.astype(np.float32).astype(float), r.faces, info


def frames(name: str = "sim-flag") -> list[tuple[int, np.ndarray, np.ndarray]]:
    """(simulated frame number, positions, faces) of the sequence's frames, in order."""
    stored = load(SEQUENCES[name])
    if stored is None:
        path = SEQUENCES[name].path
        raise SystemExit(f"{path} is missing: run `python -m bench.sim_sequence` (needs Newton)")
    recorded, faces, info = stored
    first = int(info["first_frame"])
    return [(first + i * EVERY, recorded[i], faces) for i in range(len(recorded))]


def chart(name: str) -> np.ndarray:
    """The sequence's sheet in its flat rest state as (M, 2) coordinates (its two largest
    principal axes): where a scanner's mesh of a frame is triangulated (bench/tracking.py
    ``--scans mesh``)."""
    rest, _ = sim_cloth.rest_mesh(SEQUENCES[name].scene)
    centred = rest - rest.mean(axis=0)
    axes = np.linalg.svd(centred, full_matrices=False)[2]
    return centred @ axes[:2].T


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--force", action="store_true", help="simulate again even when stored")
    ap.add_argument("--sequence", choices=list(SEQUENCES), action="append", help="only these (default: all)")
    args = ap.parse_args()
    for name in args.sequence or SEQUENCES:
        generate(SEQUENCES[name], force=args.force)
    return 0


if __name__ == "__main__":
    sys.exit(main())
