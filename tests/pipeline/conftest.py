"""Fixtures of the pipeline tests shared across modules (tests/conftest.py keeps each on one pytest-xdist worker)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def cli_study(tmp_path_factory) -> dict:
    """The real command line end to end, once for the tests that read what it leaves: ``stridelab simulate`` of one
    participant of the demo study (its visits: lab sessions and 0.1 h home days) then ``stridelab run`` with its
    default worker count, reports included. Keys: ``root`` (inbox/, wh/), ``files`` (simulate's JSON list),
    ``summary`` (run's JSON). test_cli_e2e, test_stage_gait and test_stage_calibration each simulated and ran the
    same study on their own before (≈ 35 CPU-s of make test)."""
    from tests.pipeline.test_runner import cli
    root: Path = tmp_path_factory.mktemp("cli_study")
    r = cli("simulate", root / "inbox", "--participants", "1", "--hours", "0.1", "--json")
    assert r.returncode == 0, r.stderr
    files = json.loads(r.stdout)["files"]
    r = cli("run", "--inbox", root / "inbox", "--warehouse", root / "wh", "--json")
    assert r.returncode == 0, r.stderr
    return {"root": root, "files": files, "summary": json.loads(r.stdout)}
