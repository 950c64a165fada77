"""Shared fixtures: generated cases and the location of ../shared/data."""

from __future__ import annotations

import os
import pathlib
import signal
import sys

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).parent))

# A suite started in the background of a non-interactive shell (`make test &`) inherits SIGINT
# ignored, and so would the processes the Ctrl-C tests start: Python's own handler instead, as
# in a terminal.
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

REPO = pathlib.Path(__file__).resolve().parent.parent
SHARED_DATA = pathlib.Path(os.environ.get("FOLDMATCH_SHARED", REPO.parent / "shared")) / "data"


@pytest.fixture
def shared_data() -> pathlib.Path:
    """../shared/data, or skip with the reason when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared data not found at {SHARED_DATA} (set FOLDMATCH_SHARED)")
    return SHARED_DATA
