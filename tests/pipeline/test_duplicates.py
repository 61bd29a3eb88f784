"""Duplicate recordings by sample content, and `--replace` for deliberate corrections (issue 17 point 4)."""
from __future__ import annotations

import json
from dataclasses import replace

import pytest

from stridelab.pipeline import runner
from stridelab.pipeline.formats.mcap_write import write_recording
from stridelab.pipeline.privacy import stored_name as N     # the catalog keeps a keyed hash of each file name
from tests.corpus import small_recording
from tests.pipeline.test_runner import cli
from stridelab.warehouse.read import connect_snapshot


def _q(root, sql, params=()):
    con = connect_snapshot(root)
    try:
        return con.execute(sql, list(params)).fetchall()
    finally:
        con.close()


@pytest.mark.slow
def test_the_same_recording_exported_under_other_names_is_reported_and_ingested_once(tmp_path):
    rec = small_recording(seconds=6, session="P001-lab-1", trial="walk-1")
    inbox = tmp_path / "inbox"
    inbox.mkdir()
    # twelve exports of the same samples: other names, compression levels and chunk sizes, so the file bytes differ
    files = [write_recording(rec, inbox / f"walk-1_export{k:02d}.mcap", zstd_level=1 + k % 6,
                             chunk_bytes=(1 << 16) * (1 + k)) for k in range(12)]
    assert len({f.read_bytes() for f in files}) == 12
    once = runner.run(tmp_path / "once", None, files=files[:1])
    s = runner.run(tmp_path / "wh", inbox)
    assert len(s.ingested) == 1 and len(s.reexports) == 11 and not s.quarantined and not s.failed
    assert all(f"same samples as {N('walk-1_export00.mcap')}" in m and "--replace" in m for m in s.reexports)
    for t in ("orientation", "sensors"):
        assert _q(tmp_path / "wh", f"SELECT count(*) FROM {t}") == _q(tmp_path / "once", f"SELECT count(*) FROM {t}")
    assert _q(tmp_path / "wh", "SELECT status, count(*) FROM recordings GROUP BY 1 ORDER BY 1") == \
        [("ingested", 1), ("reexport", 11)]
    assert not once.reexports
    # the next night: nothing new, nothing counted twice
    s = runner.run(tmp_path / "wh", inbox)
    assert not s.ingested and not s.reexports and len(s.duplicates) == 12 and s.stage_runs == 0


def test_a_re_export_with_other_metadata_is_still_the_same_recording(tmp_path):
    rec = small_recording(seconds=4)
    a = write_recording(rec, tmp_path / "a.mcap")
    b = write_recording(replace(rec, metadata=dict(rec.metadata, protocol="test-v2")), tmp_path / "b.mcap")
    s = runner.run(tmp_path / "wh", None, files=[a, b], stages=False)
    assert len(s.ingested) == 1 and len(s.reexports) == 1


@pytest.mark.slow
def test_replace_supersedes_the_old_recording_and_recomputes_what_depended_on_it(tmp_path):
    inbox = tmp_path / "inbox"
    inbox.mkdir()
    wrong = small_recording(seconds=6, participant="P001", session="P001-lab-1", trial="walk-1")
    other = small_recording(seconds=6, participant="P001", session="P001-lab-1", trial="walk-2", seed=5)
    write_recording(wrong, inbox / "walk-1.mcap")
    write_recording(other, inbox / "walk-2.mcap")
    args = ("--warehouse", tmp_path / "wh", "-j", "1", "--no-reports", "--json")
    r = cli("run", "--inbox", inbox, *args)
    assert r.returncode == 0, r.stderr
    n_orient = _q(tmp_path / "wh", "SELECT count(*) FROM orientation WHERE session_id = 'P001-lab-1'")[0][0]

    # walk-1 belonged to P003: the site re-exports it with the corrected participant and session
    fixed = replace(wrong, metadata=dict(wrong.metadata, participant="P003", session="P003-lab-1"))
    write_recording(fixed, inbox / "walk-1_fixed.mcap")
    r = cli("run", "--inbox", inbox, *args)                     # without --replace: reported, not ingested
    assert r.returncode == 0 and len(json.loads(r.stdout)["reexports"]) == 1, r.stderr
    assert f"walk-1_fixed.mcap: same samples as {N('walk-1.mcap')}" in r.stderr
    r = cli("run", "--inbox", inbox, "--replace", inbox / "walk-1_fixed.mcap", *args)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["ingested"] == 1 and out["stage_runs"] > 0, out
    wh = tmp_path / "wh"
    assert sorted(_q(wh, "SELECT file_name, status, session_id FROM recordings")) == sorted([
        (N("walk-1.mcap"), "superseded", "P001-lab-1"), (N("walk-1_fixed.mcap"), "ingested", "P003-lab-1"),
        (N("walk-2.mcap"), "ingested", "P001-lab-1")])
    assert f"superseded by {N('walk-1_fixed.mcap')}" in _q(wh, "SELECT reason FROM recordings WHERE file_name = ?",
                                                           [N("walk-1.mcap")])[0][0]
    # the old session is recomputed from walk-2 alone, the new one from the corrected file
    assert _q(wh, "SELECT DISTINCT st.stamp <> r.stamp FROM stage_state st JOIN ("
                  "SELECT session_id, stage, stamp FROM stage_runs WHERE status = 'ok' AND session_id = 'P001-lab-1' "
                  "ORDER BY started_at LIMIT 1) r USING (session_id, stage)") == [(True,)]
    assert _q(wh, "SELECT count(*) FROM stage_state WHERE session_id = 'P003-lab-1'")[0][0] > 0
    assert _q(wh, "SELECT count(*) FROM orientation WHERE session_id = 'P003-lab-1'")[0][0] > 0
    assert _q(wh, "SELECT count(*) FROM sensors s JOIN recordings r USING (content_hash) "
                  "WHERE r.status <> 'ingested'") == [(0,)]
    assert _q(wh, "SELECT participant_id FROM participants ORDER BY 1") == [("P001",), ("P003",)]
    assert 0 < _q(wh, "SELECT count(*) FROM orientation WHERE session_id = 'P001-lab-1'")[0][0] <= n_orient
    # the next night is a no-op: the old file in the inbox stays superseded
    r = cli("run", "--inbox", inbox, *args)
    out = json.loads(r.stdout)
    assert r.returncode == 0 and out["ingested"] == 0 and out["stage_runs"] == 0 and not out["reexports"], out


def test_replace_of_the_only_recording_of_a_session_removes_the_session_and_its_outputs(tmp_path):
    wrong = small_recording(seconds=5, participant="P001", session="P001-lab-9")
    a = write_recording(wrong, tmp_path / "a.mcap")
    runner.run(tmp_path / "wh", None, files=[a])
    fixed = write_recording(replace(wrong, metadata=dict(wrong.metadata, participant="P007", session="P007-lab-1")),
                            tmp_path / "a_fixed.mcap")
    s = runner.run(tmp_path / "wh", None, files=[fixed], replace=[fixed])
    assert len(s.ingested) == 1 and f"superseding {N('a.mcap')}" in s.messages[0], s.messages
    wh = tmp_path / "wh"
    assert _q(wh, "SELECT session_id FROM sessions") == [("P007-lab-1",)]
    assert _q(wh, "SELECT participant_id FROM participants") == [("P007",)]
    assert _q(wh, "SELECT DISTINCT session_id FROM orientation") == [("P007-lab-1",)]
    assert _q(wh, "SELECT DISTINCT session_id FROM stage_state") == [("P007-lab-1",)]


#: ``recordings.sample_hash`` of ``small_recording(seconds=4)`` as the code before the XXH3 identity stored it
#: (SHA-256, computed with commit 2729324's ``ingest.sample_hash``): warehouses ingested then hold such values
LEGACY_SAMPLE_HASH_4S = "7c0fe591af53942146044943e42f8948fbe68059cd791161b7157a5aa905ba8e"


def test_re_exports_of_recordings_hashed_before_xxh3_are_still_found_and_replaceable(tmp_path):
    from stridelab.pipeline import ingest
    from stridelab.warehouse.catalog import Warehouse
    rec = small_recording(seconds=4)
    a = write_recording(rec, tmp_path / "a.mcap")
    b = write_recording(replace(rec, metadata=dict(rec.metadata, protocol="test-v2")), tmp_path / "b.mcap")
    wh = tmp_path / "wh"
    runner.run(wh, None, files=[a], stages=False)
    [(h,)] = _q(wh, "SELECT sample_hash FROM recordings")
    assert h.startswith(ingest.SAMPLE_HASH_PREFIX) and len(h) == len(ingest.SAMPLE_HASH_PREFIX) + 32
    with Warehouse.open(wh) as w:
        assert not ingest.has_legacy_sample_hashes(w.con)        # a new warehouse: no SHA-256 pass at ingest
    p = ingest.prepare(a, tmp_path / "scratch", {"legacy_sample_hash": True})
    assert (p.sample_hash, p.legacy_sample_hash) == (h, LEGACY_SAMPLE_HASH_4S)
    # the warehouse as the earlier code left it
    with Warehouse.open(wh) as w:
        w.con.execute("UPDATE recordings SET sample_hash = ?", [LEGACY_SAMPLE_HASH_4S])
        w.publish_snapshot()
        assert ingest.has_legacy_sample_hashes(w.con)
    s = runner.run(wh, None, files=[b], stages=False)
    assert not s.ingested and len(s.reexports) == 1 and f"same samples as {N('a.mcap')}" in s.reexports[0]
    s = runner.run(wh, None, files=[b], stages=False, replace=[b])
    assert len(s.ingested) == 1, s.messages
    assert sorted(_q(wh, "SELECT file_name, status FROM recordings")) == sorted([(N("a.mcap"), "superseded"),
                                                                                (N("b.mcap"), "ingested")])
