"""Ingest of real MCAP files: round trip, idempotency, and every bad input of the platform issue."""
from __future__ import annotations

import duckdb
import numpy as np
import pytest

from stridelab.pipeline import runner
from stridelab.pipeline.formats.mcap_write import write_recording
from stridelab.pipeline.privacy import stored_name
from tests.corpus import build_bad_corpus, gap_recording, small_recording
from stridelab.warehouse.read import connect_snapshot, read_imu
from stridelab.warehouse.catalog import first


def _ingest(root, files):
    return runner.run(root, None, files=files, stages=False, command="ingest")


def test_roundtrip_values_equal_the_recording(tmp_path):
    rec = small_recording()
    f = write_recording(rec, tmp_path / "in" / "a.mcap") if (tmp_path / "in").mkdir() is None else None
    s = _ingest(tmp_path / "wh", [f])
    assert s.ingested == ["a.mcap"] and not s.quarantined
    con = connect_snapshot(tmp_path / "wh")
    h = first(con.execute("SELECT content_hash FROM recordings"))[0]
    for pl, x in rec.imu.items():
        got = read_imu(con, tmp_path / "wh", h, pl)
        np.testing.assert_array_equal(got.t_ns, x.t_ns)
        np.testing.assert_array_equal(got.acc, x.acc)
        np.testing.assert_array_equal(got.gyr, x.gyr)
        np.testing.assert_allclose(got.mag, x.mag, rtol=1e-12)   # tesla on the wire
        assert got.sampling_rate_hz == pytest.approx(100.0)
    ev = con.execute("SELECT type, side FROM reference_events ORDER BY t_ns").fetchall()
    assert ev == [("IC", "left"), ("TC", "left")]
    assert first(con.execute("SELECT count(*) FROM sensors WHERE kind = 'reference_pose'"))[0] == 1


def test_reingest_is_a_noop(tmp_path):
    f = write_recording(small_recording(), tmp_path / "a.mcap")
    _ingest(tmp_path / "wh", [f])
    con = duckdb.connect(str(tmp_path / "wh" / "catalog.duckdb"))
    before = con.execute("SELECT * FROM recordings ORDER BY ALL").fetchall()
    files_before = sorted(p.name for p in (tmp_path / "wh" / "series").rglob("*.parquet"))
    con.close()
    s = _ingest(tmp_path / "wh", [f])
    assert s.ingested == [] and s.duplicates == ["a.mcap"]
    # also a copy under another name and mtime: same content -> no change
    g = tmp_path / "copy" / "a_copy.mcap"
    g.parent.mkdir()
    g.write_bytes(f.read_bytes())
    s = _ingest(tmp_path / "wh", [g])
    assert s.ingested == [] and len(s.duplicates) == 1
    con = duckdb.connect(str(tmp_path / "wh" / "catalog.duckdb"))
    assert con.execute("SELECT * FROM recordings ORDER BY ALL").fetchall() == before
    assert sorted(p.name for p in (tmp_path / "wh" / "series").rglob("*.parquet")) == files_before


EXPECTED_REASONS = {
    "empty": "empty file",
    "truncated": "truncated",
    "bad_crc": "CRC mismatch",
    "unknown_schema": "custom_msgs/msg/FancyImu",
    "no_session": "no session metadata",
    "no_time_base": "no usable time base",
    "nan": "NaN/inf",
    "acc_in_g": "looks like g",
    "gyr_in_deg": "looks like deg/s",
    "personal_data": "personal data",
    "path_traversal": "not a safe identifier",
}


def test_every_bad_input_is_quarantined_with_a_one_line_reason(tmp_path):
    corpus = build_bad_corpus(tmp_path / "inbox")
    good = write_recording(small_recording(session="S09", trial="ok"), tmp_path / "inbox" / "good.mcap")
    s = _ingest(tmp_path / "wh", list(corpus.values()) + [good])
    assert s.ingested == ["good.mcap"]                       # the good file is not lost
    con = connect_snapshot(tmp_path / "wh")
    rows = dict(con.execute("SELECT file_name, reason FROM recordings WHERE status = 'quarantined'").fetchall())
    for name, needle in EXPECTED_REASONS.items():
        reason = rows[stored_name(f"{name}.mcap")]
        assert needle in reason, (name, reason)
        assert "\n" not in reason and len(reason) < 300
    # nothing of a quarantined file reaches the catalog or the store
    assert first(con.execute("SELECT count(DISTINCT content_hash) FROM sensors"))[0] == 1
    n_files = len([p for p in (tmp_path / "wh" / "series").rglob("*") if p.is_file()])
    assert n_files == first(con.execute("SELECT count(*) FROM sensors"))[0]
    assert not list((tmp_path / "wh" / "series").rglob(".tmp-*"))


def test_gap_is_kept_with_a_warning(tmp_path):
    f = write_recording(gap_recording(), tmp_path / "gap.mcap")
    s = _ingest(tmp_path / "wh", [f])
    assert s.ingested == ["gap.mcap"]
    con = connect_snapshot(tmp_path / "wh")
    msgs = [r[0] for r in con.execute("SELECT message FROM recording_issues").fetchall()]
    assert any("gap of 600.0 s" in m for m in msgs), msgs
    assert first(con.execute("SELECT min(sampling_rate_hz) FROM sensors WHERE kind = 'imu'"))[0] == pytest.approx(100)


def test_same_name_different_content_is_quarantined(tmp_path):
    a = write_recording(small_recording(seed=1), tmp_path / "one" / "rec.mcap") if (tmp_path / "one").mkdir() is None else None
    (tmp_path / "two").mkdir()
    b = write_recording(small_recording(seed=2, session="S03"), tmp_path / "two" / "rec.mcap")
    s = _ingest(tmp_path / "wh", [a])
    assert s.ingested == ["rec.mcap"]
    s = _ingest(tmp_path / "wh", [b])
    assert s.ingested == [] and len(s.quarantined) == 1
    assert "same name" in s.quarantined[0]
    con = connect_snapshot(tmp_path / "wh")
    assert first(con.execute("SELECT count(*) FROM recordings WHERE status = 'ingested'"))[0] == 1


def test_session_id_claimed_by_another_participant_is_quarantined(tmp_path):
    a = write_recording(small_recording(seed=1, session="S07", participant="P001", trial="t1"), tmp_path / "a.mcap")
    b = write_recording(small_recording(seed=2, session="S07", participant="P002", trial="t2"), tmp_path / "b.mcap")
    s = _ingest(tmp_path / "wh", [a, b])
    assert s.ingested == ["a.mcap"] and "already belongs to testing/P001" in s.quarantined[0]


def test_hostile_file_names_are_stored_as_data(tmp_path):
    """A file name carrying SQL or a path is never even stored (only a keyed hash of it): the file is ingested
    under its content hash, its series land inside the warehouse, and the catalog is intact."""
    inbox = tmp_path / "in"
    inbox.mkdir()
    names = ["x'; DROP TABLE recordings; --.mcap", "..%2F..%2Fetc%2Fpasswd.mcap"]
    files = [write_recording(small_recording(seed=i, session=f"S{i}", trial=f"walk-{i}"), inbox / n)
             for i, n in enumerate(names)]
    s = _ingest(tmp_path / "wh", files)
    assert sorted(s.ingested) == sorted(names) and not s.quarantined
    con = connect_snapshot(tmp_path / "wh")
    # stored under a keyed hash of the name (stridelab.pipeline.privacy.stored_name), never the name itself
    assert sorted(r[0] for r in con.execute("SELECT file_name FROM recordings").fetchall()) == \
        sorted(stored_name(n) for n in names)
    root = (tmp_path / "wh").resolve()
    for (p,) in con.execute("SELECT series_path FROM sensors").fetchall():
        assert (root / p).resolve().is_relative_to(root) and (root / p).is_file()
