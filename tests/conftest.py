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


@pytest.fixture(scope="session")
def small_home(tmp_path_factory) -> Path:
    """A StrideLab home made the real way: the demo study cut to one participant with 6-min chest days,
    simulated to MCAP and run through every stage (``home/warehouse``, ``home/inbox``). For the Python API,
    export and examples tests."""
    from pipeline import runner
    from validation.simulate import simulate_to_dir
    home = tmp_path_factory.mktemp("home")
    simulate_to_dir(home / "inbox", participants=1, hours=0.1, jobs=2)
    summary = runner.run(home / "warehouse", home / "inbox", jobs=2, command="run")
    assert not summary.failed and not summary.quarantined, summary.as_dict()
    return home
