"""Shared fixtures: generated cases and the location of ../shared/data."""

from __future__ import annotations

import os
import pathlib
import sys

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).parent))

REPO = pathlib.Path(__file__).resolve().parent.parent
SHARED_DATA = pathlib.Path(os.environ.get("FOLDMATCH_SHARED", REPO.parent / "shared")) / "data"


@pytest.fixture
def shared_data() -> pathlib.Path:
    """../shared/data, or skip with the reason when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared data not found at {SHARED_DATA} (set FOLDMATCH_SHARED)")
    return SHARED_DATA
