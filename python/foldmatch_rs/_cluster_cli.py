"""``foldmatch batch|sequence ... --scheduler ADDRESS|local`` from the Python console script.

The Rust grammar reads the command line (``cluster_request``: the same options, defaults and
errors as the local commands); this module runs it through :mod:`foldmatch_rs.distributed`
and returns the local command's exit code (0 all done, 1 fatal, 2 some files failed, 130
interrupted).
"""

from __future__ import annotations

import json
import os
import sys
from typing import Any

from ._foldmatch_rs import RunBook
from .errors import FoldMatchError

FATAL = 1
INTERRUPTED = 130


def run_on_cluster(spec_json: str) -> int:
    """Runs the ``cluster_request`` ``spec_json``; returns the exit code."""
    spec: dict[str, Any] = json.loads(spec_json)
    request: dict[str, Any] = spec["request"]
    scheduler: str = spec["scheduler"]
    try:
        from . import distributed
    except ImportError as error:
        _error(f"--scheduler {scheduler}: {error}")
        return FATAL
    for key in ("template", "input_dir", "output", "gt_dir", "params_file"):
        if request.get(key):
            request[key] = os.path.abspath(request[key])
    try:
        book = RunBook(json.dumps(request), spec["verbosity"])
    except FoldMatchError as error:
        _error(str(error))
        return FATAL
    if spec["workers"] is not None and scheduler != "local":
        book.info("warning: --jobs sets the workers of --scheduler local only; ignored")
    retries = distributed.DEFAULT_RETRIES
    client = None if scheduler == "local" else scheduler
    try:
        with distributed.connect(client, workers=spec["workers"], retries=retries) as c:
            ((code, _),) = distributed.run_books(
                c,
                request["command"],
                [book],
                ascii=request["ascii"],
                threads=spec["threads"],
                retries=retries,
            )
    except KeyboardInterrupt:
        book.finish(True)  # the report of an interrupted run (no-op once it is written)
        return INTERRUPTED
    except (OSError, TimeoutError) as error:
        _error(f"--scheduler {scheduler}: cannot reach the Dask scheduler: {error}")
        book.finish(True)
        return FATAL
    return code


def _error(message: str) -> None:
    print(f"error: {message}", file=sys.stderr, flush=True)
