"""Shared fixtures: project paths, the public data folder, small real MCAP recordings."""
from __future__ import annotations

import importlib.abc
import importlib.machinery
import sys
from pathlib import Path

import pytest

PROJECT_ROOT = Path(__file__).resolve().parent.parent
SHARED_DATA = PROJECT_ROOT.parent / "shared" / "data"
LAYERS = ("estimators", "warehouse", "pipeline", "reports", "dashboard", "validation", "studies")


class _NoBareLayerImports(importlib.abc.MetaPathFinder):
    """The layers are installed as ``stridelab.<layer>`` only; pytest puts the repository root on ``sys.path``, where
    ``import stridelab.pipeline`` would still find the folder and load a second copy of it beside ``stridelab.pipeline``. A
    bare layer name (an import, a ``mock.patch`` target, a pickled reference) fails here as it would installed.
    tests/test_layers.py checks the import statements; this catches the names in strings."""

    def find_spec(self, fullname, path=None, target=None):
        if path is None and fullname in LAYERS:
            spec = importlib.machinery.PathFinder.find_spec(fullname)
            if spec is not None and spec.origin and Path(spec.origin).resolve().is_relative_to(PROJECT_ROOT):
                raise ModuleNotFoundError(f"import stridelab.{fullname}, not {fullname}: the layers are installed "
                                          f"under the stridelab namespace (docs/architecture.md)", name=fullname)
        return None


sys.meta_path.insert(0, _NoBareLayerImports())


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
    from stridelab.pipeline import runner
    from stridelab.validation.simulate import simulate_to_dir
    home = tmp_path_factory.mktemp("home")
    simulate_to_dir(home / "inbox", participants=1, hours=0.1, jobs=2)
    summary = runner.run(home / "warehouse", home / "inbox", jobs=2, command="run")
    assert not summary.failed and not summary.quarantined, summary.as_dict()
    return home
