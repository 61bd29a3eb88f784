"""Integrity end to end (issue #47): a flipped byte in a stored series file is detected by the next read and by
`stridelab verify`, never served, and recomputed from the recording (raw samples) or by the next run (stage
outputs)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from pipeline import runner
from pipeline.formats.mcap_write import write_recording
from pipeline.verify import verify
from tests.corpus import small_recording
from tests.pipeline.test_runner import cli
from warehouse.catalog import first
from warehouse.read import connect_snapshot, read_imu
from warehouse.store import SeriesDamaged, read_table


def flip_data_bytes(path, n: int = 16, seed: int = 0) -> None:
    """Flip ``n`` bytes inside the pages of a Parquet file (between the magic and the footer)."""
    b = bytearray(path.read_bytes())
    footer = int.from_bytes(b[-8:-4], "little")
    rng = np.random.default_rng(seed)
    for pos in rng.integers(4, len(b) - 8 - footer, n):
        b[pos] ^= 0x5A
    path.write_bytes(bytes(b))


def _ingested(tmp_path):
    (tmp_path / "in").mkdir()
    f = write_recording(small_recording(), tmp_path / "in" / "a.mcap")
    s = runner.run(tmp_path / "wh", None, files=[f], stages=False, command="ingest")
    assert s.ingested == ["a.mcap"]
    con = connect_snapshot(tmp_path / "wh")
    h = first(con.execute("SELECT content_hash FROM recordings"))[0]
    rel = first(con.execute("SELECT series_path FROM sensors WHERE placement = 'foot_left' AND kind = 'imu'"))[0]
    return con, h, rel


def test_flipped_bytes_in_a_series_file_are_never_served_and_are_recomputed(tmp_path):
    con, h, rel = _ingested(tmp_path)
    wh = tmp_path / "wh"
    before = read_imu(con, wh, h, "foot_left")
    flip_data_bytes(wh / rel)
    with pytest.raises(SeriesDamaged, match="damaged"):
        read_imu(con, wh, h, "foot_left")
    with pytest.raises(SeriesDamaged):
        read_table(wh, rel)
    r = cli("verify", "--warehouse", wh)
    assert r.returncode == 1, r.stderr
    assert rel in r.stderr and "damaged" in r.stderr and "Traceback" not in r.stderr
    r = cli("verify", "--warehouse", wh, "--repair", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["repaired"] == [rel] and not out["unrepaired"]
    after = read_imu(con, wh, h, "foot_left")
    np.testing.assert_array_equal(after.acc, before.acc)
    np.testing.assert_array_equal(after.t_ns, before.t_ns)
    assert cli("verify", "--warehouse", wh).returncode == 0


def test_a_damaged_series_whose_recording_is_gone_is_reported_not_repaired(tmp_path):
    con, h, rel = _ingested(tmp_path)
    (tmp_path / "in" / "a.mcap").unlink()
    flip_data_bytes(tmp_path / "wh" / rel)
    rep = verify(tmp_path / "wh", repair=True)
    assert [d["path"] for d in rep.damaged] == [rel] and rep.unrepaired == [rel]
    assert "no longer at" in rep.damaged[0]["repair"]


def test_a_damaged_stage_output_is_recomputed_by_the_next_run(tmp_path, monkeypatch):
    from pipeline.stages import orientation
    from tests.pipeline._lab import use_registry
    use_registry(monkeypatch, [orientation.STAGE])
    (tmp_path / "in").mkdir()
    f = write_recording(small_recording(), tmp_path / "in" / "a.mcap")
    wh = tmp_path / "wh"
    assert not runner.run(wh, None, files=[f]).failed
    con = connect_snapshot(wh)
    rel = first(con.execute("SELECT series_path FROM orientation ORDER BY placement"))[0]
    good = read_table(wh, rel)
    flip_data_bytes(wh / rel)
    s = runner.run(wh, None)                      # nothing stale: the damage is found by verify, not by a stamp
    assert s.stage_runs == 0
    rep = verify(wh, repair=True)
    assert rep.scheduled == [rel] and not rep.unrepaired
    s = runner.run(wh, None)
    assert s.stage_runs == 1 and not s.failed
    assert read_table(wh, rel).equals(good)
    assert verify(wh).ok


def test_a_run_whose_final_snapshot_fails_is_not_recorded_ok(tmp_path, monkeypatch):
    """The run's recorded status matches its exit: the final snapshot copy hitting a full disk used to leave
    the run recorded 'ok' while the command exited 2."""
    import errno

    import duckdb

    from warehouse.catalog import Warehouse
    (tmp_path / "in").mkdir()
    f = write_recording(small_recording(), tmp_path / "in" / "a.mcap")
    calls = {"n": 0}
    real = Warehouse.publish_snapshot

    def publish(self):
        calls["n"] += 1
        if calls["n"] >= 2:                     # the first is the ingest phase's; the run's final copy fails
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self)

    monkeypatch.setattr(Warehouse, "publish_snapshot", publish)
    with pytest.raises(OSError, match="No space"):
        runner.run(tmp_path / "wh", None, files=[f], stages=False, command="ingest")
    con = duckdb.connect(str(tmp_path / "wh" / "catalog.duckdb"), read_only=True)
    assert con.execute("SELECT status FROM pipeline_runs").fetchall() == [("failed",)]
