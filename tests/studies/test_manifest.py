"""Study manifest loading and validation."""
from __future__ import annotations

import pytest

from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest


def test_default_manifest():
    m = load_manifest()
    assert m.name == "demo" and len(m.participants) == 4
    assert sum(p.hemiparetic for p in m.participants) >= 1
    assert m.free_living.hours == 6.0 and m.with_free_living_hours(0.2).free_living.hours == 0.2
    assert m.visits == 2 and m.visit_interval_days == 42           # a programme: baseline and follow-up
    assert load_manifest(DEFAULT_MANIFEST.parent) == m


@pytest.mark.parametrize("edit, field", [
    (("speed_m_s = 1.25", "speed_m_s = \"fast\""), "participants[0].speed_m_s"),
    (("condition = \"hemiparetic\"\nparetic_side = \"left\"", "condition = \"hemiparetic\""), "paretic_side"),
    (("hours = 6.0", "hours = -1.0"), "free_living.hours"),
    (("timezone = \"Europe/Zurich\"", "timezone = \"Mars/Olympus\""), "study.timezone"),
    (("noise_scale = 1.0", "noise_scle = 1.0"), "sensor_model"),
    (("name = \"demo\"", "name = \"../../etc\""), "study.name"),                 # path traversal
    (("name = \"demo\"", "name = \"x'; DROP TABLE sessions; --\""), "study.name"),  # SQL
    (("id = \"P001\"", "id = \"P001'; DROP TABLE x; --\""), "participants[0]"),
])
def test_bad_manifest_names_file_and_field(tmp_path, edit, field):
    text = DEFAULT_MANIFEST.read_text()
    assert edit[0] in text
    p = tmp_path / "study.toml"
    p.write_text(text.replace(edit[0], edit[1], 1))
    with pytest.raises(ValueError) as e:
        load_manifest(p)
    assert str(p) in str(e.value) and field in str(e.value)


def test_missing_and_invalid_toml(tmp_path):
    with pytest.raises(ValueError, match="not found"):
        load_manifest(tmp_path / "nope.toml")
    p = tmp_path / "study.toml"
    p.write_text("[study\nname=")
    with pytest.raises(ValueError, match="invalid TOML"):
        load_manifest(p)
