"""Shared fixtures: project paths, the public data folder, small real MCAP recordings."""
from __future__ import annotations

from pathlib import Path

import pytest

PROJECT_ROOT = Path(__file__).resolve().parent.parent
SHARED_DATA = PROJECT_ROOT.parent / "shared" / "data"


def shared_data(name: str) -> Path:
    """Folder of a public data set in ../shared/data, or skip the test with the reason."""
    p = SHARED_DATA / name
    if not p.is_dir():
        pytest.skip(f"public data '{name}' not found at {p}; see DESIGN.md 'Real data' (needs ../shared/data)")
    return p
