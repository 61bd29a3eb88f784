"""Integrity end to end (issue #47): a flipped byte in a stored series file is detected by the next read and by
`stridelab verify`, never served, and recomputed from the recording (raw samples) or by the next run (stage
outputs)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from stridelab.pipeline import runner
from stridelab.pipeline.formats.mcap_write import write_recording
from stridelab.pipeline.privacy import stored_name
from stridelab.pipeline.verify import verify
from tests.corpus import small_recording
from tests.pipeline.test_runner import cli
from stridelab.warehouse.catalog import first
from stridelab.warehouse.read import connect_snapshot, read_imu
from stridelab.warehouse.store import SeriesDamaged, read_table


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


@pytest.mark.slow
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
    r = cli("verify", "--warehouse", wh, "--repair", "--json")          # the catalog keeps no path (privacy):
    assert r.returncode == 1 and json.loads(r.stdout)["unrepaired"] == [rel], r.stderr   # the file is not found
    r = cli("verify", "--warehouse", wh, "--repair", "--json", "--search", tmp_path / "in")
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
    from stridelab.pipeline.stages import orientation
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

    from stridelab.warehouse.catalog import Warehouse
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


def _two_runs(tmp_path):
    (tmp_path / "inbox").mkdir()
    for k in range(2):
        write_recording(small_recording(seconds=5.0, seed=k, session=f"S0{k}", trial=f"walk-{k}"),
                        tmp_path / "inbox" / f"r{k}.mcap")
        r = cli("ingest", tmp_path / "inbox", "--warehouse", tmp_path / "wh")
        assert r.returncode == 0, r.stderr
    return tmp_path / "wh"


@pytest.mark.slow
def test_a_corrupt_catalog_names_the_file_and_is_rebuilt_from_the_newest_snapshot(tmp_path):
    wh = _two_runs(tmp_path)
    con = connect_snapshot(wh)
    before = sorted(con.execute("SELECT file_name, n_samples FROM recordings").fetchall())
    con.close()
    cat = wh / "catalog.duckdb"
    b = bytearray(cat.read_bytes())
    b[:64] = bytes(x ^ 0xFF for x in b[:64])
    cat.write_bytes(bytes(b))
    import duckdb
    for snap in (wh / "snapshots").glob("catalog-*.duckdb"):       # the snapshots that hold r1 too: the rebuild
        with duckdb.connect(str(snap), read_only=True) as c:        # falls back to one from before it
            has_r1 = c.execute("SELECT count(*) FROM recordings WHERE file_name = ?",        # a keyed hash
                               [stored_name("r1.mcap")]).fetchall()[0][0]
        if has_r1:
            snap.write_bytes(b"\0" * 4096)
    r = cli("ingest", tmp_path / "inbox", "--warehouse", wh)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert str(cat) in r.stderr and "damaged" in r.stderr and "repair-catalog" in r.stderr
    assert "free disk space" not in r.stderr
    r = cli("repair-catalog", "--warehouse", wh)
    assert r.returncode == 0 and "rebuilt from snapshot" in r.stderr, r.stderr
    assert list(wh.glob("catalog.damaged-*.duckdb"))
    con = connect_snapshot(wh)
    assert len(con.execute("SELECT file_name FROM recordings").fetchall()) == 1      # r1 came after that snapshot
    con.close()
    r = cli("ingest", tmp_path / "inbox", "--warehouse", wh)
    assert r.returncode == 0, r.stderr
    con = connect_snapshot(wh)
    assert sorted(con.execute("SELECT file_name, n_samples FROM recordings").fetchall()) == before
    con.close()


@pytest.mark.slow
def test_a_corrupt_newest_snapshot_falls_back_to_the_previous_one_with_a_message(tmp_path):
    from stridelab.warehouse.read import latest_snapshot, snapshot_status
    wh = _two_runs(tmp_path)
    snaps = sorted((wh / "snapshots").glob("catalog-*.duckdb"))
    assert len(snaps) >= 2
    newest = snaps[-1]
    b = bytearray(newest.read_bytes())
    b[:64] = bytes(x ^ 0xFF for x in b[:64])
    newest.write_bytes(bytes(b))
    snap, msg = snapshot_status(wh)
    assert snap == snaps[-2] and latest_snapshot(wh) == snaps[-2]
    assert newest.name in msg and "damaged" in msg and snaps[-2].name in msg
    con = connect_snapshot(wh)
    assert con.execute("SELECT count(*) FROM recordings").fetchall()[0][0] >= 1
    con.close()
    r = cli("report", "P001", "--warehouse", wh, "--out", tmp_path / "reports")
    assert "Traceback" not in r.stderr and f"the newest snapshot {newest.name} is damaged" in r.stderr, r.stderr
    r = cli("verify", "--warehouse", wh)
    assert r.returncode == 1 and newest.name in r.stderr
