"""Only what is consumed is computed: a free-living day gets no chest orientation unless its study asks
(``[compute.orientation] free_living = true``), and the ledger says why each stage ran."""
from __future__ import annotations

from dataclasses import replace

import pytest

from stridelab.pipeline import config, runner
from stridelab.pipeline.formats.mcap_write import write_recording
from stridelab.pipeline.stages import registry
from tests.pipeline._lab import df
from stridelab.warehouse.catalog import first
from stridelab.warehouse.read import connect_snapshot


@pytest.fixture
def free_living_file(tmp_path):
    from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
    from stridelab.validation.simulator import simulate_chest_day, study_participants
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
    assert _ledger(root) == {("activity", "output of free_living sessions; first run"),
                             ("trunk_gait", "output of free_living sessions; first run")}
    assert len(df(root, "SELECT * FROM activity_bouts")) > 0

    (studies_dir / "optin" / "study.toml").write_text("[compute.orientation]\nfree_living = true\n")
    config.study_manifest.cache_clear()
    s = runner.run(root, None)
    assert not s.failed and s.stage_runs == 1 and s.skipped_fresh == 2     # activity, trunk_gait stay fresh
    ori = df(root, "SELECT placement, n_samples FROM orientation ORDER BY placement")
    assert list(ori.placement) == ["chest", "lower_back"]          # the demo day carries both trunk sensors
    assert (ori.n_samples == 0.05 * 3600 * 100).all()
    assert ("orientation", "requested by study optin ([compute.orientation] free_living = true); first run") \
        in _ledger(root)


def test_lab_orientation_is_needed_by_the_later_stages():
    stages = registry()
    ori = {s.name: s for s in stages}["orientation"]
    assert runner.why_wanted(ori, "lab", "demo", stages) == "needed by calibration, joint_angles, live_agreement"
    assert runner.why_wanted(ori, "free_living", "demo", stages) is None


def test_a_bad_compute_table_is_refused_with_the_study_named(studies_dir):
    (studies_dir / "optin" / "study.toml").write_text("[compute.orientation]\nfree_livng = true\n")
    with pytest.raises(ValueError, match=r"study optin: \[compute.orientation\].*free_livng"):
        config.requested("optin", "orientation", "free_living")


def test_a_long_recording_is_classified_day_by_day(tmp_path, monkeypatch):
    """Above ``DAY_PIECES_ABOVE_S`` the activity stage holds one local day of samples at a time; the
    per-second timeline still covers every second once and a bout crossing midnight stays one bout."""
    from stridelab.pipeline.stages import activity
    from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
    from stridelab.validation.simulator import simulate_chest_day, study_participants
    m = load_manifest(DEFAULT_MANIFEST)
    m = replace(m, free_living=replace(m.free_living, hours=0.4, start_local="23:48"))
    rec, _ = simulate_chest_day(m, study_participants(m, 1)[0], 0)
    f = write_recording(rec, tmp_path / f"{rec.name}.mcap")
    monkeypatch.setattr(activity, "DAY_PIECES_ABOVE_S", 600.0)
    root = tmp_path / "wh"
    assert not runner.run(root, None, files=[f]).failed
    daily = df(root, "SELECT date, max(recorded_s) AS rec, sum(seconds) AS sec FROM activity_daily GROUP BY 1 ORDER BY 1")
    assert len(daily) == 2 and list(daily.rec) == list(daily.sec) and daily.rec.sum() == 0.4 * 3600
    assert daily.rec[0] == 12 * 60                                          # 23:48 to local midnight
    b = df(root, "SELECT start_ns, end_ns, class FROM activity_bouts ORDER BY start_ns")
    assert (b.end_ns.iloc[:-1].values == b.start_ns.iloc[1:].values).all()  # contiguous, no overlap
    assert (b["class"].iloc[:-1].values != b["class"].iloc[1:].values).all()  # runs merged across midnight
    assert (b.end_ns - b.start_ns).sum() == 0.4 * 3600 * 1e9


def test_read_column_range_is_a_slice_of_the_whole_column(tmp_path):
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq
    from stridelab.warehouse.read import read_column_range
    x = np.random.default_rng(0).normal(size=(2500, 2))
    pq.write_table(pa.table({"t_ns": np.arange(2500), "a": x[:, 0], "b": x[:, 1]}), tmp_path / "s.parquet",
                   row_group_size=700)
    for a, b in ((0, 2500), (650, 1410), (700, 1400), (2499, 2500), (10, 10)):
        np.testing.assert_array_equal(read_column_range(tmp_path, "s.parquet", ("a", "b"), a, b), x[a:b])
        np.testing.assert_array_equal(read_column_range(tmp_path, "s.parquet", ("t_ns",), a, b, dtype=np.int64),
                                      np.arange(a, b))
