"""Participant data protection at ingest: keyed pseudonyms, refused personal data, no path tricks."""
from __future__ import annotations

from dataclasses import replace

import pytest

from stridelab.pipeline import runner
from stridelab.pipeline.formats.mcap_write import write_recording
from stridelab.pipeline.pseudonym import create_key
from tests.corpus import small_recording
from stridelab.warehouse.catalog import first
from stridelab.warehouse.read import connect_snapshot


def test_site_identifier_becomes_a_keyed_pseudonym(tmp_path, monkeypatch):
    key = tmp_path / "secret" / "pseudonym.key"
    monkeypatch.setenv("STRIDELAB_PSEUDONYM_KEY", str(key))
    create_key(key)
    recs = []
    for i, trial in enumerate(("walk-1", "walk-2")):
        r = small_recording(seconds=3, seed=i, trial=trial, session=f"S{i}")
        meta = {k: v for k, v in r.metadata.items() if k != "participant"}
        recs.append(write_recording(replace(r, metadata=dict(meta, site_id="HOSP-12345")), tmp_path / f"{trial}.mcap"))
    s = runner.run(tmp_path / "wh", None, files=recs, stages=False)
    assert len(s.ingested) == 2
    con = connect_snapshot(tmp_path / "wh")
    pids = {p for (p,) in con.execute("SELECT participant_id FROM sessions").fetchall()}
    assert len(pids) == 1 and next(iter(pids)).startswith("PS-")
    # the site identifier is stored nowhere in the catalog
    for (t,) in con.execute("SELECT table_name FROM information_schema.tables").fetchall():
        rows = con.execute(f'SELECT * FROM "{t}"').fetchall()
        assert "HOSP-12345" not in repr(rows), t


def test_site_identifier_without_key_is_quarantined(tmp_path, monkeypatch):
    monkeypatch.setenv("STRIDELAB_PSEUDONYM_KEY", str(tmp_path / "missing.key"))
    r = small_recording(seconds=3)
    f = write_recording(replace(r, metadata=dict(r.metadata, site_id="HOSP-1")), tmp_path / "a.mcap")
    s = runner.run(tmp_path / "wh", None, files=[f], stages=False)
    assert len(s.quarantined) == 1 and "no pseudonymisation key" in s.quarantined[0]


@pytest.mark.parametrize("field,value,needle", [
    ("participant_name", "Jane Doe", "personal data"),
    ("contact", "jane.doe@example.org", "personal data"),
    ("session", "../../../etc/passwd", "not a safe identifier"),
    ("study", "x'; DROP TABLE recordings; --", "not a safe identifier"),
])
def test_personal_data_and_path_or_sql_tricks_in_metadata_are_refused(tmp_path, field, value, needle):
    r = small_recording(seconds=3)
    f = write_recording(replace(r, metadata=dict(r.metadata, **{field: value})), tmp_path / "a.mcap")
    s = runner.run(tmp_path / "wh", None, files=[f], stages=False)
    assert len(s.quarantined) == 1 and needle in s.quarantined[0]
    con = connect_snapshot(tmp_path / "wh")
    assert first(con.execute("SELECT count(*) FROM recordings"))[0] == 1    # the table survived
    assert not (tmp_path / "etc").exists() and not list(tmp_path.rglob("passwd*"))


def test_stage_fields_are_kept_and_checked():
    """``reference_frame`` and ``accelerometer_only`` are read by the orientation stage: stored as given (a dropped
    ``reference_frame`` once made the stage align BROAD's sensor-frame reference and score 1.263° vs the bench's
    1.329°), and refused with one line when they hold anything but their closed values."""
    from stridelab.pipeline.ingest import IngestRejected, check_session_metadata
    base = {"study": "public", "participant": "broad01", "session": "s1", "kind": "lab"}
    s = check_session_metadata({"session": {**base, "reference_frame": "sensor_enu", "accelerometer_only": "chest"}})
    assert s["reference_frame"] == "sensor_enu" and s["accelerometer_only"] == "chest"
    with pytest.raises(IngestRejected, match="reference_frame .* is not one of sensor_enu, segment_lab"):
        check_session_metadata({"session": {**base, "reference_frame": "lab_ned"}})
    with pytest.raises(IngestRejected, match="accelerometer_only must be comma-separated placements"):
        check_session_metadata({"session": {**base, "accelerometer_only": "Chest Sensor!"}})
