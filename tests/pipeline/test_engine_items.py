"""The engines take their items from a generator while the first ones already run, and commits no result
before the generator is drained (pipeline/engines.py ``LocalEngine.run_all``; the runner builds each stage task's
inputs from the catalog that way)."""
from __future__ import annotations

import time
from pathlib import Path

import pytest

from stridelab.pipeline.engines import DaskEngine, LocalEngine


def _mark(path: str) -> str:
    Path(path).write_text("ran")
    return path


def _items(tmp_path: Path, done: list, seen: list):
    yield (str(tmp_path / "first"),)
    # the next item only once the first has run in a worker: an engine that drained the generator before
    # starting anything would wait here until the deadline
    deadline = time.monotonic() + 120
    while not (tmp_path / "first").exists():
        assert time.monotonic() < deadline, "the first item did not run while the generator was producing"
        time.sleep(0.02)
    time.sleep(0.2)                       # time for the first result to come back (it must be held)
    seen.append(len(done))
    yield (str(tmp_path / "second"),)
    seen.append(len(done))


@pytest.mark.parametrize("engine", ["local", "dask"])
@pytest.mark.slow
def test_engines_run_the_first_items_while_the_generator_produces_the_next(tmp_path, engine):
    done, seen = [], []
    eng = LocalEngine(2) if engine == "local" else DaskEngine(2)
    try:
        eng.run_all(_mark, _items(tmp_path, done, seen), lambda it, r: done.append((it, r)))
    finally:
        eng.close()
    assert seen == [0, 0]                 # no result handed on while the generator still produced items
    assert sorted(r for _, r in done) == [str(tmp_path / "first"), str(tmp_path / "second")]
    assert all(it == (r,) for it, r in done)


def test_a_single_job_drains_the_generator_before_it_runs_anything(tmp_path):
    done, seen = [], []

    def items():
        for k in range(3):
            seen.append(len(done))
            yield (str(tmp_path / f"f{k}"),)

    LocalEngine(1).run_all(_mark, items(), lambda it, r: done.append(r))
    assert seen == [0, 0, 0] and len(done) == 3
