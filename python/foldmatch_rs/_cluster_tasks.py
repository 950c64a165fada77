"""The tasks that Dask workers run for :mod:`foldmatch_rs.distributed`.

Each task fits one file with the Rust ``FileFitter`` (the code path of ``foldmatch batch`` and
``foldmatch sequence``), which reads the scan, fits it and writes the output atomically on the
worker; what comes back is the file's report entry (JSON) and, for a sequence frame, the fit
that warm-starts the next frame. This module imports no Dask at import time, so that the
tasks unpickle on any worker that has ``foldmatch_rs``.
"""

from __future__ import annotations

import json
import os
import threading
from typing import Any, Optional, Union

import numpy as np

from . import _foldmatch_rs as _core

#: Fit threads per task: a number, or ``{worker address: number}`` chosen by the driver.
Threads = Union[int, dict]
#: The previous frame's fit and its name (``None``: start from the template).
Warm = Optional[tuple]

# The fitters of the runs this worker process has served, by template file and parameters: a
# template is read and its neighbourhoods computed once per run, not once per scan.
_FITTERS: dict[tuple, Any] = {}
_FITTERS_LOCK = threading.Lock()
_MAX_FITTERS = 4


def _fitter(template: str, params_json: str, threads: int) -> Any:
    stat = os.stat(template)
    key = (template, stat.st_mtime_ns, stat.st_size, params_json, threads)
    with _FITTERS_LOCK:
        fitter = _FITTERS.get(key)
    if fitter is None:
        fitter = _core.FileFitter(template, params_json, threads)
        with _FITTERS_LOCK:
            if len(_FITTERS) >= _MAX_FITTERS:
                _FITTERS.clear()
            _FITTERS[key] = fitter
    return fitter


def _threads(threads: Threads) -> int:
    """This task's fit threads: the driver's choice for this worker, or the cores of this
    machine shared by the worker's task slots."""
    if isinstance(threads, int):
        return threads
    from distributed import get_worker

    worker = get_worker()
    chosen = threads.get(worker.address)
    if chosen:
        return int(chosen)
    return max(1, (os.cpu_count() or 1) // max(1, worker.state.nthreads))


def fit_file(template: str, params_json: str, file_json: str, ascii: bool, threads: Threads) -> str:
    """One scan of a batch: its report entry (JSON). A scan that fails is an ``error`` entry."""
    fitter = _fitter(template, params_json, _threads(threads))
    entry, _ = fitter.fit(file_json, ascii)
    return entry


def track_frame(
    template: str,
    params_json: str,
    file_json: str,
    ascii: bool,
    threads: Threads,
    previous: Optional[tuple[str, Warm]],
) -> tuple[str, Warm]:
    """One frame of a sequence, warm-started from ``previous`` (the previous frame's task
    result): ``(entry JSON, warm start of the next frame)``. As ``foldmatch sequence``: a frame
    that fails leaves the next one starting from the last successful fit, and a frame done by an
    earlier run (``resume``) is read back instead of fitted."""
    fitter = _fitter(template, params_json, _threads(threads))
    warm: Warm = None if previous is None else previous[1]
    warm_name = None if warm is None else warm[1]
    resumed = fitter.resume_frame(file_json, warm_name)
    name = _name(file_json)
    if resumed is not None:
        entry, vertices = resumed
        return entry, (vertices, name)
    entry, fitted = fitter.fit(file_json, ascii, _warm_arg(warm))
    return entry, (warm if fitted is None else (fitted, name))


def _warm_arg(warm: Warm) -> Optional[tuple[np.ndarray, str]]:
    if warm is None:
        return None
    vertices, name = warm
    return np.ascontiguousarray(vertices, dtype=np.float64), str(name)


def _name(file_json: str) -> str:
    return str(json.loads(file_json)["name"])
