"""Watching fits in the Rerun viewer (https://rerun.io), with the optional ``viz`` extra
(``rerun-sdk``: ``pip install rerun-sdk`` beside the wheel, or ``pip install '.[viz]'`` from
the repository).

* :func:`rerun_callback` is a ``callback`` for :func:`foldmatch_rs.fit` that logs each
  iteration's mean and max displacement on the ``iteration`` timeline while the fit runs.
* :func:`log_fit` logs a finished fit: the scan as points, the template, every snapshot
  (``fit(..., params={"snapshot_every": N})``) and the fitted mesh as meshes on the same
  timeline, the fitted mesh with the wrinkle-field colors of the CLI's PLY and ``fm.render``.

Both take the recording to log to (default: Rerun's global recording, which
``rerun.init("foldmatch", spawn=True)`` starts) and ``sdk``, the ``rerun`` module itself (the
default) or an object with the same ``Scalars``, ``Points3D`` and ``Mesh3D`` constructors.

Examples
--------
>>> import rerun as rr                                              # doctest: +SKIP
>>> from foldmatch_rs import viz                                    # doctest: +SKIP
>>> rr.init("foldmatch", spawn=True)                                # doctest: +SKIP
>>> every_10 = {"snapshot_every": 10}                                # doctest: +SKIP
>>> result = fm.fit(t, f, scan, callback=viz.rerun_callback(), params=every_10)  # doctest: +SKIP
>>> viz.log_fit(result, scan=scan, template=t)                      # doctest: +SKIP
"""

from __future__ import annotations

from typing import Any, Callable, Optional

import numpy as np

from . import _foldmatch_rs as _core

TIMELINE = "iteration"


def _sdk(sdk: Any) -> Any:
    if sdk is not None:
        return sdk
    try:
        import rerun
    except ImportError as e:
        raise ImportError("foldmatch_rs.viz needs rerun-sdk: pip install rerun-sdk") from e
    return rerun


def _recording(recording: Any, sdk: Any) -> Any:
    """The recording to log to: the one given, else the SDK module (its global recording)."""
    return sdk if recording is None else recording


def rerun_callback(
    recording: Any = None,
    *,
    entity: str = "fit",
    every: int = 1,
    then: Optional[Callable[[dict[str, Any]], Optional[bool]]] = None,
    sdk: Any = None,
) -> Callable[[dict[str, Any]], Optional[bool]]:
    """A ``callback`` for :func:`foldmatch_rs.fit` logging ``ENTITY/mean_displacement`` and
    ``ENTITY/max_displacement`` (normalized units) every ``every`` iterations (and the last).

    ``then`` is another callback called after logging; its return value is passed on
    (``False`` stops the fit)."""
    rr = _sdk(sdk)
    rec = _recording(recording, rr)
    if every < 1:
        raise ValueError(f"every: must be >= 1, got {every}")

    def callback(info: dict[str, Any]) -> Optional[bool]:
        i = int(info["iteration"])
        if i % every == 0 or i == int(info["iterations"]):
            rec.set_time(TIMELINE, sequence=i)
            for key in ("mean_displacement", "max_displacement"):
                rec.log(f"{entity}/{key}", rr.Scalars(float(info[key])))
        return None if then is None else then(info)

    return callback


def log_fit(
    result: Any,
    scan: Any = None,
    template: Any = None,
    recording: Any = None,
    *,
    entity: str = "fit",
    sdk: Any = None,
) -> None:
    """Logs a finished :class:`foldmatch_rs.FitResult` on the ``iteration`` timeline: the
    template at 0 (when given), each of ``result.snapshots`` at its iteration and the fitted
    mesh at ``result.iterations`` as ``ENTITY/mesh`` (the fitted one colored by the
    accumulated wrinkle field, viridis over its 2nd–98th percentiles), and the scan as
    ``ENTITY/scan`` points (static)."""
    rr = _sdk(sdk)
    rec = _recording(recording, rr)
    faces = np.asarray(result.faces)
    if scan is not None:
        points = np.asarray(getattr(scan, "vertices", scan), dtype=np.float64)
        rec.log(f"{entity}/scan", rr.Points3D(points, colors=[150, 150, 150]), static=True)
    frames: list[tuple[int, np.ndarray]] = []
    if template is not None:
        frames.append((0, np.asarray(getattr(template, "vertices", template), dtype=np.float64)))
    frames.extend((int(i), np.asarray(v)) for i, v in result.snapshots)
    for i, vertices in frames:
        rec.set_time(TIMELINE, sequence=i)
        rec.log(f"{entity}/mesh", rr.Mesh3D(vertex_positions=vertices, triangle_indices=faces))
    colors, _ = _core.wrinkle_colors(np.ascontiguousarray(result.wvf_accumulated_magnitude, dtype=np.float64))
    rec.set_time(TIMELINE, sequence=int(result.iterations))
    rec.log(
        f"{entity}/mesh",
        rr.Mesh3D(vertex_positions=result.vertices, triangle_indices=faces, vertex_colors=colors),
    )


__all__ = ["rerun_callback", "log_fit", "TIMELINE"]
