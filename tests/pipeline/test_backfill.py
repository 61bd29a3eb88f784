"""Backfill: bumping one stage's version recomputes that stage and its dependants only."""
from __future__ import annotations

from dataclasses import replace

import pytest

from stridelab.pipeline import runner, stages
from stridelab.pipeline.formats.mcap_write import write_recording
from stridelab.pipeline.stages import Stage, StageOutput
from stridelab.pipeline.stages import orientation as orientation_stage
from tests.corpus import small_recording
from stridelab.warehouse.catalog import Warehouse


def _count_rows(inp, params):
    return StageOutput(rows={"fake_" + params["name"]: [{"session_id": inp.session["session_id"],
                                                          "value": float(len(inp.upstream.get("orientation", [])))}]})


def _fake(name, needs):
    return Stage(name=name, version="1", needs=needs, tables=(f"fake_{name}",), session_kinds=("lab",),
                 compute=_count_rows, default_params=lambda name=name: {"name": name})


@pytest.fixture
def warehouse_with_fakes(tmp_path, monkeypatch):
    with Warehouse.open(tmp_path / "wh") as wh:
        for n in ("down", "independent"):
            wh.con.execute(f"CREATE TABLE fake_{n} (session_id VARCHAR, value DOUBLE)")
    reg = [orientation_stage.STAGE, _fake("down", ("orientation",)), _fake("independent", ())]
    monkeypatch.setattr(runner, "registry", lambda: reg)
    monkeypatch.setattr(stages, "registry", lambda: reg)
    files = [write_recording(small_recording(seconds=5, session=f"S{i}", trial=f"t{i}", seed=i), tmp_path / f"{i}.mcap")
             for i in range(2)]
    runner.run(tmp_path / "wh", None, files=files)
    return tmp_path / "wh", reg


def _ran(root, run_id):
    with Warehouse.open(root) as wh:
        return sorted(wh.con.execute("SELECT stage, session_id FROM stage_runs WHERE run_id = ? AND status = 'ok'",
                                     [run_id]).fetchall())


def test_bumping_a_stage_version_recomputes_it_and_its_dependants_only(warehouse_with_fakes):
    root, reg = warehouse_with_fakes
    assert _ran(root, runner.run(root, None).run_id) == []                  # everything fresh
    reg[0] = replace(reg[0], version="999")                                  # orientation code changed
    ran = _ran(root, runner.run(root, None).run_id)
    assert ran == [("down", "S0"), ("down", "S1"), ("orientation", "S0"), ("orientation", "S1")]
    reg[1] = replace(reg[1], version="2")                                    # only the dependant changed
    assert _ran(root, runner.run(root, None).run_id) == [("down", "S0"), ("down", "S1")]
