"""Every development recording of the public gait data runs through ``stridelab import`` + ``stridelab run`` with
no failed stage run (issue 43: one Voisard trial once stopped the gait stage with an IndexError; a repeated packet
counter stopped the importer). The real CLI in a subprocess, one import and one run per data set."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from tests.conftest import shared_data

STRIDELAB = [sys.executable, "-m", "stridelab"]


def _cli(*args):
    return subprocess.run([*STRIDELAB, *map(str, args)], capture_output=True, text=True, env=dict(os.environ),
                          timeout=3600)


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.parametrize("dataset, fmt", [("voisard_gait", "voisard"), ("gaitmap_example", "gaitmap")])
def test_every_development_recording_imports_and_runs_without_a_failed_stage(tmp_path, dataset, fmt):
    src = shared_data(dataset)
    inbox, wh = tmp_path / "inbox", tmp_path / "wh"
    r = _cli("import", fmt, src, "--inbox", inbox, "--study", "public", "--json")
    assert r.returncode == 0, r.stderr
    imported = json.loads(r.stdout)
    assert imported["written"] and not imported["errors"]
    if fmt == "voisard":
        assert len(imported["written"]) == len(list(src.glob("*-*.json")))          # one recording per trial
    r = _cli("run", "--inbox", inbox, "--warehouse", wh, "--no-reports", "--json")
    summary = json.loads(r.stdout)
    assert summary["failed"] == [], summary["failed"]
    assert r.returncode == 0, r.stderr[-2000:]
    assert summary["ingested"] == len(imported["written"]) and not summary["quarantined"]
    from stridelab.warehouse.read import connect_snapshot
    con = connect_snapshot(wh)
    runs = dict(con.execute("SELECT status, count(*) FROM stage_runs GROUP BY 1").fetchall())
    assert set(runs) <= {"ok", "skipped"} and runs.get("ok", 0) > 0, runs
    gait_ok = con.execute("SELECT count(*) FROM stage_runs WHERE stage = 'gait' AND status = 'ok'").fetchone()[0]
    assert gait_ok == len(imported["written"])
