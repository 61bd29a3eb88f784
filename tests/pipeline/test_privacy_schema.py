"""The session schema, the screen and the vocabularies of pipeline/privacy.py, value by value (the corpus in
test_privacy_corpus.py runs them end to end): personal data refused or dropped, the project's own legitimate
values kept."""
from __future__ import annotations

import pytest

from stridelab.pipeline.privacy import screen_events, screen_session, shown_topic, stored_name, stored_path
from stridelab.studies.privacy import PrivacyPolicy, privacy_policy, value_problem

BASE = {"study": "testing", "participant": "P001", "session": "S01", "kind": "lab", "trial": "walk-1",
        "timezone": "UTC"}
POLICY = PrivacyPolicy(free_text_fields=("comment",))

PERSONAL = ["Łukasz Żółć", "Иван Петров", "王小明", "JANE DOE", "José Núñez", "Doe, Jane", "Dr. Weber",
            "12-MAR-1951", "born 12th March 1951", "12/31/51", "1951-03-12", "March 12th, 1951", "born 1951",
            "+41791234567", "MRN 00482913", "7561234567897", "MRN48291377", "call +41 79 123 45 67",
            "Bahnhofstrasse 12, 8001 Zürich", "221b Baker Street", "rue de Lausanne 5", "jane@hospital",
            "eva.roth@example.org", "Mobilise-D Karl Huber", "Jean-Pierre Dupont"]


@pytest.mark.parametrize("value", PERSONAL)
def test_the_screen_finds_personal_data_in_any_script_and_form(value):
    assert value_problem(value) is not None


@pytest.mark.parametrize("value", PERSONAL)
@pytest.mark.parametrize("field", ["protocol", "comment"])
def test_personal_data_in_a_kept_text_field_refuses_the_recording_without_repeating_it(field, value):
    with pytest.raises(ValueError) as e:
        screen_session({**BASE, field: value}, POLICY)
    assert f"'{field}'" in str(e.value)
    assert not any(p in str(e.value) for p in value.replace(",", " ").split() if len(p) >= 3)


LEGITIMATE = ["stridelab-lab-gait-v1", "x-io CSV", "APDM Opal", "Xsens MT Manager export", "PyShoe Vicon trial",
              "Voisard: stand, walk 10 m, U-turn, walk back", "gaitmap example: 2x20 m straight walk",
              "UCI chest activities", "BROAD disturbed", "Axivity CWA",
              "Qualisys markers (heel FCC position, foot orientation from FCC/TOE/FM5)",
              "OptiTrack orientation of the IMU case (BROAD opt_quat), movement mask",
              "Voisard et al. 2023 gait events", "C3D markers (foot_left = LHEE/LTOE/LMT5; mm -> m, 100 Hz, offset 0 s)",
              "walked well, no problems", "10m walk test, 3 repetitions", "Mobilise-D Test5 (straight walks)",
              "Mobilise-D INDIP (inertial + pressure insoles + distance sensors), Stereophoto",
              "C3D markers (21 on 7 segments; mm -> m, 100 Hz, offset 0.25 s)"]


@pytest.mark.parametrize("value", LEGITIMATE)
def test_the_projects_own_labels_pass_the_screen(value):
    assert value_problem(value) is None
    assert screen_session({**BASE, "protocol": value}, POLICY)["protocol"] == value


@pytest.mark.parametrize("field,value", [("note_s", "fritz weber"), ("remark_hz", "4711"),
                                         ("remark_hz", "12.5"), ("contact_id", "4711"), ("operator", "ok")])
def test_undeclared_fields_are_dropped_whatever_their_name_or_value(field, value):
    notes: list[dict] = []
    out = screen_session({**BASE, field: value}, POLICY, notes)
    assert field not in out and out["participant"] == "P001"
    assert len(notes) == 1 and f"'{field}' dropped" in notes[0]["message"] and value not in notes[0]["message"]


def test_an_undeclared_field_with_a_phone_number_refuses_the_recording():
    with pytest.raises(ValueError, match="'remark_hz' looks like personal data") as e:
        screen_session({**BASE, "remark_hz": "0041442681234"}, POLICY)
    assert "41442681234" not in str(e.value)


def test_declared_numbers_are_kept_and_numbers_that_look_like_record_numbers_are_not():
    out = screen_session({**BASE, "height_m": "1.66", "thigh_length_m": "0.41", "sampling_rate_hz": "100"}, POLICY)
    assert out["height_m"] == "1.66" and out["sampling_rate_hz"] == "100"
    with pytest.raises(ValueError, match="phone number or an identity or record number"):
        screen_session({**BASE, "height_m": "00482913"}, POLICY)
    policy = privacy_policy({"numeric_fields": ["walk_speed_m_s"]})
    assert screen_session({**BASE, "walk_speed_m_s": "1.2"}, policy)["walk_speed_m_s"] == "1.2"


def test_condition_comes_from_a_vocabulary_the_study_extends():
    assert screen_session({**BASE, "condition": "hemiparetic"}, POLICY)["condition"] == "hemiparetic"
    with pytest.raises(ValueError, match="not in the study's vocabulary"):
        screen_session({**BASE, "condition": "post-op knee"}, POLICY)
    assert screen_session({**BASE, "condition": "post_tka"},
                          privacy_policy({"conditions": ["post_tka"]}))["condition"] == "post_tka"


@pytest.mark.parametrize("pid", ["MRN48291377", "JANE_DOE", "Jane", "Łukasz", "c30-1950-11-30"])
def test_identifiers_that_look_like_names_dates_or_record_numbers_are_refused(pid):
    with pytest.raises(ValueError) as e:
        screen_session({**BASE, "participant": pid}, POLICY)
    assert pid not in str(e.value)


def test_event_labels_from_the_vocabulary_payloads_without_free_text():
    notes: list[dict] = []
    ev = screen_events([{"t_ns": 1, "type": "IC", "side": "left", "placement": "foot_left", "label": "Hildegard Müller"},
                        {"t_ns": 2, "type": "activity", "label": "walking", "code": 3,
                         "note": "born 1948-07-21, tel +41 79 555 66 77"},
                        {"t_ns": 3, "type": "score", "label": "trial", "source": "Voisard TrialBoundaries",
                         "placement": "karl_huber"}], PrivacyPolicy(), notes)
    assert ev == [{"t_ns": 1, "type": "IC", "side": "left", "placement": "foot_left"},
                  {"t_ns": 2, "type": "activity", "label": "walking", "code": 3},
                  {"t_ns": 3, "type": "score", "label": "trial", "source": "Voisard TrialBoundaries"}]
    assert len(notes) == 1 and "3 reference-event values dropped" in notes[0]["message"]
    with pytest.raises(ValueError):
        screen_events([{"t_ns": 1, "type": "Hildegard Müller"}], PrivacyPolicy())


def test_the_reference_field_is_a_screened_label_kept_without_warning():
    notes: list[dict] = []
    ref = "Vicon foot position (PyShoe gt, y flipped to right-handed z up)"
    assert screen_session({**BASE, "reference": ref}, POLICY, notes)["reference"] == ref and not notes
    with pytest.raises(ValueError, match="'reference' looks like personal data"):
        screen_session({**BASE, "reference": "Vicon, operator Dr. Weber"}, POLICY)


def test_mobilised_reference_events_keep_their_system_label_and_numbers():
    notes: list[dict] = []
    src = "Mobilise-D INDIP MicroWB (data.mat Standards)"
    ev = screen_events([{"t_ns": 1, "end_ns": 9, "type": "walking_bout", "label": "INDIP", "placement": "lower_back",
                         "source": src, "n_strides": 7, "cadence_spm": 104.34782608695652, "stride_length_m": None,
                         "walking_speed_m_s": 1.1},
                        {"t_ns": 2, "end_ns": 3, "type": "turn", "label": "Stereophoto", "angle_deg": -92.5},
                        {"t_ns": 4, "type": "walking_bout", "cadence_spm": 41791234567.0, "n_strides": True}],
                       PrivacyPolicy(), notes)
    assert ev[0] == {"t_ns": 1, "end_ns": 9, "type": "walking_bout", "label": "INDIP", "placement": "lower_back",
                     "source": src, "n_strides": 7, "cadence_spm": 104.347826, "stride_length_m": None,
                     "walking_speed_m_s": 1.1}
    assert ev[1] == {"t_ns": 2, "end_ns": 3, "type": "turn", "label": "Stereophoto", "angle_deg": -92.5}
    assert ev[2] == {"t_ns": 4, "type": "walking_bout"}          # a phone-like number and a bool are not stored
    assert len(notes) == 1 and "2 reference-event values dropped" in notes[0]["message"]


def test_topics_are_shown_only_when_made_of_known_words():
    for t in ("/imu/foot_left", "/foot_left/imu/data_raw", "/range/foot_left/A", "/imu0/data", "/reference/events"):
        assert shown_topic(t) == t
    for t in ("/imu/karl_huber", "/Otto_Brandt/imu", "/imu/anna.keller@clinic.ch"):
        s = shown_topic(t)
        assert s.startswith("a topic (name not shown") and not any(p in s for p in ("karl", "Otto", "anna"))


def test_stored_names_are_keyed_hashes_stable_per_name(tmp_path, monkeypatch):
    monkeypatch.setenv("STRIDELAB_PSEUDONYM_KEY", str(tmp_path / "none.key"))
    a = stored_name(tmp_path / "Jane_Doe_1951-03-12.mcap")
    assert a == stored_name("elsewhere/Jane_Doe_1951-03-12.mcap") and a.startswith("rec-") and a.endswith(".mcap")
    assert "Jane" not in a and "1951" not in a and a != stored_name("Jane_Doe_1951-03-13.mcap")
    assert stored_name(tmp_path / "hans_mueller_bag") .startswith("rec-")
    p = stored_path(tmp_path / "Jane_Doe_1951-03-12.mcap")
    assert "Jane" not in p and p != stored_path(tmp_path / "x" / "Jane_Doe_1951-03-12.mcap")
    from stridelab.pipeline.pseudonym import create_key
    create_key(tmp_path / "k.key")
    monkeypatch.setenv("STRIDELAB_PSEUDONYM_KEY", str(tmp_path / "k.key"))
    assert stored_name("Jane_Doe_1951-03-12.mcap") != a          # with the key, a guess cannot be confirmed
