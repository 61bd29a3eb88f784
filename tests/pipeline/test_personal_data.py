"""Personal data kept out (issue 17 point 6): pseudonym ids of the study's pattern, no names, birth dates,
phone numbers or e-mails in any field, free text only where the manifest allows it, reasons without the value."""
from __future__ import annotations

import json
import re
from dataclasses import replace

import pytest

from stridelab.pipeline import runner
from stridelab.pipeline.formats.mcap_write import write_recording
from stridelab.studies.manifest import load_manifest
from tests.corpus import small_recording
from stridelab.warehouse.read import connect_snapshot
from stridelab.warehouse.store import check_identifier


@pytest.fixture(autouse=True)
def _fresh_manifests():
    from stridelab.pipeline import config
    config.study_manifest.cache_clear()        # the study manifests some tests write must not leak
    yield
    config.study_manifest.cache_clear()


def _ingest(tmp_path, **meta):
    tmp_path.mkdir(parents=True, exist_ok=True)
    r = small_recording(seconds=3)
    f = write_recording(replace(r, metadata=dict(r.metadata, **meta)), tmp_path / "a.mcap")
    return runner.run(tmp_path / "wh", None, files=[f], stages=False)


def _parts(value: str) -> list[str]:
    """The value and every piece of it a reason must not repeat (words, digit groups)."""
    return [value.strip()] + [p for p in re.split(r"[\s,._@+()/-]+", value) if len(p) >= 3 and p != "tel"]


_RUN_ID = re.compile(r"\d{8}T\d{6}Z-[0-9a-f]{6}")


def _stored_nowhere(tmp_path, value: str) -> None:
    """No text column of the catalog and no file name holds the value or a piece of it."""
    con = connect_snapshot(tmp_path / "wh")
    cols = con.execute("SELECT table_name, column_name FROM information_schema.columns "
                       "WHERE data_type IN ('VARCHAR', 'JSON')").fetchall()
    for t, c in cols:
        # run ids are made of the run's start time and random hex (``20261205T012316Z-57f975``): nothing of the
        # recording, but a clock reading 01:23 holds the "123" of a phone number
        text = _RUN_ID.sub("<run>", repr(con.execute(f'SELECT "{c}" FROM "{t}"').fetchall()))
        for p in _parts(value):
            assert p not in text, (t, c, p)
    con.close()
    assert not [p for p in (tmp_path / "wh").rglob("*") if any(x in p.name for x in _parts(value))]


CASES = [
    ("participant", "Jane.Doe", "pseudonym pattern"),
    ("participant", "Doe_Jane_1950-03-02", "date"),
    ("participant", "Jane", "looks like a name"),
    ("participant", "P001\n", "pseudonym pattern"),
    ("session", "S01\n", "pseudonym pattern"),
    ("trial", "Doe-Jane", "looks like a name"),
    ("comment", "walked with Jane Doe", "person's name"),
    ("comment", "born 02.03.1950, fine otherwise", "calendar date"),
    ("comment", "born 2 March 1950", "calendar date"),
    ("comment", "call back on +41 79 123 45 67", "phone number"),
    ("comment", "Jane Doe, born 1950-03-02, tel 079 123 45 67", "personal data"),
    ("geburtsdatum", "02.03.1950", "its name announces personal data"),
    ("tel", "0791234567", "its name announces personal data"),
    ("contact", "jane.doe@hospital", "e-mail address"),
    ("contact", "jane.doe@hospital.example.org", "e-mail address"),
]


@pytest.mark.parametrize("field,value,why", CASES, ids=[f"{f}={v!r}" for f, v, _ in CASES])
def test_personal_data_is_refused_with_a_reason_that_does_not_repeat_it(tmp_path, field, value, why):
    s = _ingest(tmp_path, **{field: value})
    assert not s.ingested and len(s.quarantined) == 1
    reason = s.quarantined[0]
    assert why in reason, reason
    assert f"'{field}'" in reason                        # the field is named ...
    for p in _parts(value):                              # ... the value, or any piece of it, is not
        assert p not in reason, (p, reason)
    assert "\n" not in reason
    _stored_nowhere(tmp_path, value)


def test_check_identifier_refuses_a_trailing_newline_and_does_not_echo():
    with pytest.raises(ValueError) as e:
        check_identifier("P001\n", "participant")
    assert "P001" not in str(e.value)
    assert check_identifier("P001", "participant") == "P001"


def _study(tmp_path, monkeypatch, privacy: str):
    from stridelab.pipeline import config
    d = tmp_path / "studies" / "testing"
    d.mkdir(parents=True)
    (d / "study.toml").write_text(f"[privacy]\n{privacy}\n")
    monkeypatch.setenv("STRIDELAB_STUDIES", str(tmp_path / "studies"))
    config.study_manifest.cache_clear()


def test_free_text_is_dropped_with_a_warning_unless_the_manifest_allow_lists_it(tmp_path, monkeypatch):
    s = _ingest(tmp_path, comment="walked well, no problems", operator_note="sensor re-taped")
    assert len(s.ingested) == 1, s.quarantined
    con = connect_snapshot(tmp_path / "wh")
    meta = json.loads(con.execute("SELECT metadata FROM recordings").fetchall()[0][0])
    assert "comment" not in meta and "operator_note" not in meta
    assert meta["trial"] == "walk-1" and meta["protocol"] == "test"          # the format's fields stay
    msgs = [m for (m,) in con.execute("SELECT message FROM recording_issues").fetchall()]
    assert any("'comment' dropped" in m for m in msgs) and not any("walked" in m for m in msgs)
    con.close()

    _study(tmp_path, monkeypatch, 'free_text_fields = ["comment"]')
    s = _ingest(tmp_path / "b", comment="walked well, no problems")
    assert len(s.ingested) == 1, s.quarantined
    con = connect_snapshot(tmp_path / "b" / "wh")
    assert json.loads(con.execute("SELECT metadata FROM recordings").fetchall()[0][0])["comment"] == \
        "walked well, no problems"
    # an allow-listed field is still screened
    s = _ingest(tmp_path / "c", comment="walked well with Jane Doe")
    assert len(s.quarantined) == 1 and "Jane" not in s.quarantined[0]


def test_the_study_chooses_its_pattern_and_may_allow_date_like_ids(tmp_path, monkeypatch):
    _study(tmp_path, monkeypatch, "id_pattern = '^(SUBJ[0-9]{3}|S-[0-9-]+|walk-1)\\Z'\nallow_date_like_ids = true")
    s = _ingest(tmp_path / "a", participant="SUBJ001", session="S-2026-03-02")
    assert len(s.ingested) == 1, s.quarantined
    s = _ingest(tmp_path / "b", participant="P001")                  # the default pattern's id is refused here
    assert len(s.quarantined) == 1 and "pseudonym pattern" in s.quarantined[0]


def test_the_default_policy_refuses_date_like_session_ids(tmp_path):
    s = _ingest(tmp_path, session="S-2026-03-02")
    assert len(s.quarantined) == 1 and "allow_date_like_ids" in s.quarantined[0]


@pytest.mark.parametrize("privacy,needle", [("id_pattern = '.*'", "accepts unsafe ids"),
                                            ("id_pattern = '(['", "not a regular expression"),
                                            ("free_text_fields = 'comment'", "list of field names"),
                                            ("allow_names = true", "unknown field")])
def test_a_bad_privacy_table_is_refused_by_the_manifest_loader(tmp_path, privacy, needle):
    text = (load_manifest().path).read_text()
    text = re.sub(r"\[privacy\].*?(?=\n# Participants)", f"[privacy]\n{privacy}\n", text, flags=re.S)
    (tmp_path / "study.toml").write_text(text)
    with pytest.raises(ValueError, match=re.escape(needle)):
        load_manifest(tmp_path / "study.toml")


@pytest.mark.parametrize("pid", ["Jane.Doe", "Doe_Jane_1950-03-02", "P001\\n"])
def test_the_manifest_refuses_name_and_date_like_participant_ids_without_echoing_them(tmp_path, pid):
    text = load_manifest().path.read_text().replace('id = "P002"', f'id = "{pid}"')
    (tmp_path / "study.toml").write_text(text)
    with pytest.raises(ValueError) as e:
        load_manifest(tmp_path / "study.toml")
    assert "participants[1].id" in str(e.value)
    assert not any(p in str(e.value) for p in ("Jane", "Doe", "1950"))
