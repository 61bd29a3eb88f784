"""Live session -> inbox -> `stridelab run` -> the live outputs stored beside the nightly's, with their agreement.

A replayed lab walk of the hemiparetic demo participant goes through `stridelab live` (recorder on, written by
the real recorder into the inbox), then the real nightly run ingests it and runs every stage; the warehouse must
hold the live outputs (``live_outputs``) and the agreement tables of the ``live_agreement`` stage.
"""
from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from stridelab.cli import main
from stridelab.warehouse.read import connect_snapshot


@pytest.mark.slow
def test_live_session_enters_the_nightly_and_its_agreement_is_stored(tmp_path, lab_files, monkeypatch):
    cal, walk = lab_files
    inbox = tmp_path / "inbox"
    r = CliRunner().invoke(main, ["live", "--replay", str(walk), "--calibration", str(cal), "--speed", "max",
                                  "--inbox", str(inbox), "--name", "live1", "--no-serve", "--json"])
    assert r.exit_code == 0, r.output
    live_summary = json.loads(r.stdout.strip().splitlines()[-1])
    r = CliRunner().invoke(main, ["run", "--inbox", str(inbox), "--warehouse", str(tmp_path / "wh"), "--jobs", "1",
                                  "--json"])
    assert r.exit_code == 0, r.output
    con = connect_snapshot(tmp_path / "wh")
    try:
        kinds = dict(con.execute("SELECT kind, n_rows FROM live_outputs").fetchall())
        assert kinds["angles"] == live_summary["frames"] == 3000 and kinds["events"] > 20, kinds
        skipped, meta = con.execute("SELECT skipped_topics, metadata FROM recordings").fetchone()
        assert json.loads(meta).get("live_source") == "replay", meta      # kept, not dropped as an undeclared field
        assert "/live/" not in (skipped or ""), skipped          # stored, so not listed as skipped
        runs = dict(con.execute("SELECT stage, status FROM stage_runs").fetchall())
        assert runs["live_agreement"] == "ok", runs
        s = con.execute("SELECT comparison, quantity, key, metric, value FROM live_agreement").fetchall()
        by = {(c, q, k, m): v for c, q, k, m, v in s}
        joints = sorted({k for c, q, k, m in by if q == "joint_angle"})
        assert joints == ["ankle_left", "ankle_right", "hip_left", "hip_right", "knee_left", "knee_right"], joints
        # online filter run by the nightly over the whole recording: the live outputs are causal, so equal up
        # to rounding (the magnetometer makes a µT -> T -> µT round trip through the recording)
        for k in joints:
            assert by[("online_filter", "joint_angle", k, "max_abs_diff_deg")] < 1e-6, k
        for side in ("left", "right"):
            for typ in ("IC", "TC"):
                key = f"{side}_{typ}"
                n = by[("online_filter", "event", key, "n_live")]
                assert n >= 8
                assert by[("online_filter", "event", key, "matched")] == n == by[("online_filter", "event", key,
                                                                                   "n_other")]
                assert by[("online_filter", "event", key, "max_abs_diff_ms")] == 0.0
                # the nightly's gait stage (smoothed foot kinematics, toe-off refinement): a measured difference
                assert by[("offline_smoothed", "event", key, "matched")] >= 0.9 * n
        # offline smoothed angles: a measured, non-zero difference of a few degrees in flexion
        for k in ("hip_left", "knee_left", "knee_right"):
            v = by[("offline_smoothed", "joint_angle", k, "rmse_deg_sagittal")]
            assert 0.0 < v < 5.0, (k, v)
        strides = con.execute("SELECT count(*), max(max_abs_diff_online_deg), min(max_abs_diff_offline_deg) "
                              "FROM live_agreement_strides WHERE plane = 'sagittal'").fetchone()
        assert strides[0] >= 2 * 3 * 10 and strides[1] < 1e-6 and strides[2] > 0, strides
        ev = con.execute("SELECT count(*), count(online_ns), count(offline_ns), max(abs(online_diff_ms)) "
                         "FROM live_agreement_events").fetchone()
        assert ev[0] == kinds["events"] and ev[1] == ev[0] and ev[2] >= 0.9 * ev[0] and ev[3] == 0.0, ev
    finally:
        con.close()
    # ... and shown on the dashboard's runs page (Streamlit AppTest on the published snapshot)
    import streamlit as st
    from streamlit.testing.v1 import AppTest
    from tests.dashboard.conftest import APP
    monkeypatch.setenv("STRIDELAB_WAREHOUSE", str(tmp_path / "wh"))
    st.cache_data.clear()
    st.cache_resource.clear()
    at = AppTest.from_file(str(APP), default_timeout=60)
    at.run()
    at.switch_page("views/runs.py")
    at.run()
    assert not at.exception, [e.value for e in at.exception]
    assert "Live sessions beside the nightly" in [h.value for h in at.subheader]
    joints = [set(d.value["joint"]) for d in at.dataframe if "joint" in d.value.columns]
    assert {"knee_left", "knee_right"} <= set().union(*joints), joints
