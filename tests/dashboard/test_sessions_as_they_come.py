"""Sessions as they come (issue 14, point 3): one foot only, feet + lower back without a calibration trial, chest
only, a hand-held sensor, no magnetometer, accelerometer only, 52-400 Hz. The nightly run (every stage, reports)
records ``skipped`` with the reason where a stage lacks its placements, fails nowhere, writes no QC rows for
sensors the session never had, and the report and dashboard pages render."""
from __future__ import annotations

import numpy as np
import pytest

from stridelab.estimators.recording import ImuData, Recording
from stridelab.pipeline import runner
from stridelab.pipeline.formats.mcap_write import write_recording
from tests.pipeline._lab import df

pytestmark = pytest.mark.slow        # six sessions through every stage, reports and five pages: ~2.5 min on 2 cores

T0 = 1_714_554_000_000_000_000


def _imu(n, fs, rng, mag=False, gyro=True):
    t = T0 + np.rint(np.arange(n) * 1e9 / fs).astype(np.int64)
    acc = np.tile([0.0, 0.0, 9.81], (n, 1)) + rng.normal(0, 0.3, (n, 3))
    gyr = rng.normal(0, 0.2, (n, 3)) if gyro else None
    return ImuData(t, acc, gyr, rng.normal(0, 1, (n, 3)) + [20, 0, -40] if mag else None)


SESSIONS = {   # participant: (kind, {placement: (rate, mag, gyro)}, extra session fields)
    "onefoot": ("lab", {"foot_right": (400.0, False, True)}, {}),
    "feetback": ("lab", {"foot_left": (100.0, False, True), "foot_right": (100.0, False, True),
                         "pelvis": (100.0, False, True)}, {}),
    "chestlab": ("lab", {"chest": (128.0, True, True)}, {}),
    "hand": ("lab", {"hand": (285.7, True, True)}, {}),
    "chestday": ("free_living", {"chest": (52.0, False, False)}, {"accelerometer_only": "chest"}),
    "wrist": ("free_living", {"wrist": (100.0, False, False)}, {"accelerometer_only": "wrist"}),
}


@pytest.fixture(scope="module")
def wh(tmp_path_factory):
    d = tmp_path_factory.mktemp("as_they_come")
    rng = np.random.default_rng(14)
    files = []
    for pid, (kind, sensors, extra) in SESSIONS.items():
        secs = 600 if kind == "free_living" else 20
        imu = {pl: _imu(int(secs * fs), fs, rng, mag, gyro) for pl, (fs, mag, gyro) in sensors.items()}
        meta = {"study": "imported", "participant": pid, "session": f"{pid}-s1", "kind": kind,
                "trial": "day" if kind == "free_living" else "walk", "timezone": "UTC", **extra}
        files.append(write_recording(Recording(meta, imu=imu, name=pid), d / f"{pid}.mcap"))
    from stridelab.cli import _report_builder
    s = runner.run(d / "wh", None, files=files, reports_dir=d / "reports", build_report=_report_builder(d / "wh"))
    assert not s.failed and not s.quarantined, (s.failed, s.quarantined)
    return d


def _runs(wh):
    r = df(wh / "wh", "SELECT split_part(session_id, '-', 1) AS pid, stage, status, note FROM stage_runs")
    return {(p, st): (status, note) for p, st, status, note in r.itertuples(index=False)}


@pytest.mark.parametrize("pid, stage, needle", [
    ("onefoot", "calibration", "calibration skipped: no pelvis/thigh/shank sensors (session has foot_right)"),
    ("onefoot", "joint_angles", "joint angles skipped: no pelvis/thigh/shank sensors"),
    ("feetback", "joint_angles", "no joint has sensors on both its segments (session has foot_left, foot_right, pelvis)"),
    ("chestlab", "gait", "gait skipped: no foot_left/foot_right IMU (session has chest)"),
    ("chestlab", "calibration", "calibration skipped"),
    ("hand", "gait", "gait skipped: no foot_left/foot_right IMU (session has hand)"),
    ("hand", "joint_angles", "joint angles skipped"),
    ("wrist", "activity", "activity skipped: no chest IMU (session has wrist)"),
])
def test_stage_without_its_placements_is_skipped_with_the_reason(wh, pid, stage, needle):
    status, note = _runs(wh)[(pid, stage)]
    assert status == "skipped" and needle in note, (status, note)


def test_what_can_run_runs(wh):
    runs = _runs(wh)
    for key in (("onefoot", "gait"), ("feetback", "gait"), ("onefoot", "orientation"), ("hand", "orientation"),
                ("chestlab", "orientation"), ("chestday", "activity"), ("feetback", "calibration")):
        assert runs[key][0] == "ok", (key, runs[key])
    assert "no foot_left IMU" in runs[("onefoot", "gait")][1]             # one foot: partial, said so
    cal = df(wh / "wh", "SELECT placement, status FROM calibration")      # no QC rows for absent thighs / shanks
    assert set(cal["placement"]) == {"foot_left", "foot_right", "pelvis"} and (cal["status"] == "fail").all()
    summ = df(wh / "wh", "SELECT session_id FROM gait_summary")
    assert not any(s.startswith(("chestlab", "hand")) for s in summ["session_id"])
    ori = df(wh / "wh", "SELECT split_part(session_id, '-', 1) AS pid, placement, sampling_rate_hz, mag_used "
                        "FROM orientation ORDER BY ALL")
    rates = {(p, pl): (round(fs, 1), m) for p, pl, fs, m in ori.itertuples(index=False)}
    assert rates[("onefoot", "foot_right")] == (400.0, False) and rates[("chestlab", "chest")] == (128.0, True)


def test_skipped_runs_are_final_until_something_changes(wh):
    s = runner.run(wh / "wh", None, files=sorted(wh.glob("*.mcap")))
    assert s.stage_runs == 0 and not s.failed


def test_reports_and_pages_render(wh, app_env):
    assert sorted(p.name for p in (wh / "reports").glob("*.html")) == sorted(
        f"imported_{p}.html" for p in SESSIONS)
    from tests.dashboard.test_pages import open_page
    app_env(wh / "wh")
    at = open_page("overview")
    cov = next(d.value for d in at.dataframe if "sessions_skipped" in d.value)
    assert cov.set_index("stage").loc["gait", "sessions_skipped"] == 2
    for pid in SESSIONS:
        at = open_page("participant", {"study": "imported", "participant": pid})
        assert pid in " ".join(h.value for h in at.header)
    open_page("runs")
    open_page("activity")
    open_page("accuracy")
