"""Only what is consumed is computed: a free-living day gets no chest orientation unless its study asks
(``[compute.orientation] free_living = true``), and the ledger says why each stage ran."""
from __future__ import annotations

from dataclasses import replace

import pytest

from pipeline import config, runner
from pipeline.formats.mcap_write import write_recording
from pipeline.stages import registry
from tests.pipeline._lab import df
from warehouse.catalog import first
from warehouse.read import connect_snapshot


@pytest.fixture
def free_living_file(tmp_path):
    from studies.manifest import DEFAULT_MANIFEST, load_manifest
    from studies.simulator import simulate_chest_day, study_participants
    m = replace(load_manifest(DEFAULT_MANIFEST), name="optin").with_free_living_hours(0.05)
    rec, _ = simulate_chest_day(m, study_participants(m, 1)[0], 0)
    return write_recording(rec, tmp_path / f"{rec.name}.mcap")


@pytest.fixture
def studies_dir(tmp_path, monkeypatch):
    d = tmp_path / "studies"
    (d / "optin").mkdir(parents=True)
    monkeypatch.setenv("STRIDELAB_STUDIES", str(d))
    config.study_manifest.cache_clear()
    yield d
    config.study_manifest.cache_clear()


def _ledger(root):
    return {(s, r) for s, r in df(root, "SELECT stage, reason FROM stage_runs WHERE status = 'ok'")
            .itertuples(index=False)}


def test_free_living_orientation_only_when_the_study_asks(tmp_path, free_living_file, studies_dir):
    root = tmp_path / "wh"
    s = runner.run(root, None, files=[free_living_file])
    assert not s.failed, s.failed
    assert first(connect_snapshot(root).execute("SELECT count(*) FROM orientation"))[0] == 0
    assert _ledger(root) == {("activity", "output of free_living sessions; first run")}
    assert len(df(root, "SELECT * FROM activity_bouts")) > 0

    (studies_dir / "optin" / "study.toml").write_text("[compute.orientation]\nfree_living = true\n")
    config.study_manifest.cache_clear()
    s = runner.run(root, None)
    assert not s.failed and s.stage_runs == 1 and s.skipped_fresh == 1     # activity stays fresh
    ori = df(root, "SELECT placement, n_samples FROM orientation")
    assert list(ori.placement) == ["chest"] and ori.n_samples[0] == 0.05 * 3600 * 100
    assert ("orientation", "requested by study optin ([compute.orientation] free_living = true); first run") \
        in _ledger(root)


def test_lab_orientation_is_needed_by_the_later_stages():
    stages = registry()
    ori = {s.name: s for s in stages}["orientation"]
    assert runner.why_wanted(ori, "lab", "demo", stages) == "needed by calibration, joint_angles"
    assert runner.why_wanted(ori, "free_living", "demo", stages) is None


def test_a_bad_compute_table_is_refused_with_the_study_named(studies_dir):
    (studies_dir / "optin" / "study.toml").write_text("[compute.orientation]\nfree_livng = true\n")
    with pytest.raises(ValueError, match=r"study optin: \[compute.orientation\].*free_livng"):
        config.requested("optin", "orientation", "free_living")

