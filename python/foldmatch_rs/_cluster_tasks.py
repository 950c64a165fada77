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

from . import _foldmatch_rs as _core

#: Fit threads per task: a number, or ``{worker address: number}`` chosen by the driver.
Threads = Union[int, dict]
#: What a sequence's next frame continues from: the tracker's state (JSON) and the name of
#: the last fitted frame (``None``: the first frame, from the template).
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
    return fitter.fit(file_json, ascii)


def track_frame(
    template: str,
    params_json: str,
    file_json: str,
    ascii: bool,
    threads: Threads,
    tracking_json: str,
    previous: Optional[tuple[str, Warm]],
) -> tuple[str, Warm]:
    """One frame of a sequence, tracked on from ``previous`` (the previous frame's task
    result): ``(entry JSON, what the next frame continues from)``. As ``foldmatch sequence``,
    whose tracker this task continues (its state: the last fits, the first frame's figures):
    a frame that fails leaves the next one starting from the last successful fit, and a frame
    done by an earlier run (``resume``) is read back instead of fitted."""
    fitter = _fitter(template, params_json, _threads(threads))
    state, warm_name = (None, None) if previous is None or previous[1] is None else previous[1]
    name = _name(file_json)
    resumed = fitter.resume_frame(file_json, state, warm_name)
    if resumed is not None:
        entry, state = resumed
        return entry, (state, name)
    entry, state, fitted = fitter.track(file_json, tracking_json, state, warm_name, ascii)
    return entry, (state, name if fitted else warm_name)


def _name(file_json: str) -> str:
    return str(json.loads(file_json)["name"])
