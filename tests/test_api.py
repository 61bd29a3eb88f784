"""The Python API (``stridelab.open``, ``stridelab.read_recording``) on a warehouse and MCAP files made the real way."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import stridelab

pytestmark = pytest.mark.slow      # a simulated study run through every stage (small_home), or a fresh process
ROOT = Path(__file__).resolve().parents[1]


def test_importing_the_package_has_no_side_effects():
    """No environment variable, no warning filter set by our code (third-party modules such as SciPy install their
    own at import: each call is attributed to the file that made it), nothing heavy imported by ``stridelab``."""
    code = """
import os, sys, warnings
ours = os.getcwd()
calls = []
for name in ("filterwarnings", "simplefilter"):
    real = getattr(warnings, name)
    def spy(*a, _real=real, **k):
        calls.append(sys._getframe(1).f_code.co_filename)
        return _real(*a, **k)
    setattr(warnings, name, spy)
before = dict(os.environ)
import stridelab
light = [m for m in ("duckdb", "pandas", "streamlit", "numba") if m in sys.modules]
import stridelab.estimators, stridelab.estimators.orientation, stridelab.estimators.gait, stridelab.estimators.activity, stridelab.estimators.trajectory
print(sorted(set(os.environ) ^ set(before)), [c for c in calls if c.startswith(ours) and "site-packages" not in c], light)
"""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=ROOT, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[] [] []"


def test_open_accepts_the_home_or_the_warehouse_and_reads_the_newest_snapshot(small_home):
    a, b = stridelab.open(small_home), stridelab.open(small_home / "warehouse")
    assert a.root == b.root == small_home / "warehouse"
    assert a.snapshot == b.snapshot and a.snapshot.parent.name == "snapshots"
    with a:
        p = a.participants()
        assert list(p["participant_id"]) == ["P001"]
        s = a.sessions(participant="P001")
        assert set(s["kind"]) == {"lab", "free_living"}
        assert len(a.sessions(participant="nobody")) == 0


def test_tables_come_back_as_dataframes_filtered_by_participant_and_session(small_home):
    with stridelab.open(small_home) as wh:
        st = wh.strides(participant="P001")
        assert len(st) > 20 and {"side", "stride_length_m", "speed_m_s", "ic_ns"} <= set(st.columns)
        assert set(st["participant_id"]) == {"P001"}
        one = st["session_id"].iloc[0]
        assert set(wh.strides(session=one)["session_id"]) == {one}
        # the same rows as a plain SQL query on the snapshot
        n = wh.sql("SELECT count(*) AS n FROM strides")["n"].iloc[0]
        assert n == len(st)
        assert len(wh.daily_activity(participant="P001")) > 0
        acc = wh.accuracy(stage="gait_events")
        assert len(acc) and set(acc["stage"]) == {"gait_events"}
        assert wh.table("sessions").shape[0] == 4
        assert wh.arrow("sessions").num_rows == 4


def test_a_table_the_warehouse_lacks_raises_a_clear_error(small_home):
    with stridelab.open(small_home) as wh:
        with pytest.raises(stridelab.TableMissing, match="no table 'x; DROP'"):
            wh.table("x; DROP")
        with pytest.raises(stridelab.TableMissing, match="no table 'no_such_table'.*tables: .*strides"):
            wh.table("no_such_table")
        if wh.has_table("walking_bouts"):       # the walking-at-home stage ran: its bouts come back filtered
            wb = wh.walking_bouts(participant="P001")
            assert set(wb["participant_id"]) <= {"P001"} and {"cadence_spm", "placement"} <= set(wb.columns)
        else:
            with pytest.raises(stridelab.TableMissing, match="walking_bouts.*walking-at-home stage"):
                wh.walking_bouts()


def test_open_refuses_what_is_not_a_warehouse(tmp_path):
    with pytest.raises(FileNotFoundError, match="not a StrideLab warehouse"):
        stridelab.open(tmp_path)
    with pytest.raises(FileNotFoundError, match="no such folder"):
        stridelab.open(tmp_path / "nope")


def test_series_of_the_warehouse_equal_the_recording_read_from_its_mcap(small_home):
    """The IMU samples the warehouse stored equal what read_recording reads from the inbox file (units: m/s², rad/s)."""
    walk = sorted((small_home / "inbox").rglob("*walk-1*.mcap"))[0]
    rec = stridelab.read_recording(walk)
    assert rec.metadata["participant"] == "P001" and rec.metadata["trial"] == "walk-1"
    foot = rec.imu["foot_left"]
    assert foot.acc.shape == foot.gyr.shape == (len(foot.t_ns), 3)
    assert 8.0 < np.median(np.linalg.norm(foot.acc, axis=1)) < 11.5          # m/s², not g
    assert foot.mag is not None and 10 < np.median(np.linalg.norm(foot.mag, axis=1)) < 100   # µT, not tesla
    assert any(e["type"] == "IC" for e in rec.events)
    assert "foot_left" in rec.reference_poses
    with stridelab.open(small_home) as wh:
        stored = wh.imu(rec.metadata["session"], "foot_left", trial="walk-1")
    np.testing.assert_array_equal(stored.t_ns, foot.t_ns)
    np.testing.assert_allclose(stored.acc, foot.acc, rtol=0, atol=1e-6)
    np.testing.assert_allclose(stored.gyr, foot.gyr, rtol=0, atol=1e-6)


def test_read_recording_refuses_a_corrupt_file_in_one_line(small_home, tmp_path):
    walk = sorted((small_home / "inbox").rglob("*walk-1*.mcap"))[0]
    bad = tmp_path / "cut.mcap"
    bad.write_bytes(walk.read_bytes()[:5000])
    with pytest.raises(ValueError) as e:
        stridelab.read_recording(bad)
    assert "\n" not in str(e.value)
    with pytest.raises(FileNotFoundError):
        stridelab.read_recording(tmp_path / "none.mcap")
