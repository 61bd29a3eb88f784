"""Synthetic study simulator: determinism, physical consistency, gait asymmetry, chest-day labels."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from stridelab.estimators.quaternion import quat_angle_deg, quat_conj, quat_exp_step_1, quat_mul, quat_rotate
from stridelab.studies.manifest import DEFAULT_MANIFEST, SensorModelSpec, load_manifest
from stridelab.validation.simulator import simulate_chest_day, simulate_lab_session, simulate_study, study_participants

pytestmark = pytest.mark.slow

G = 9.81


@pytest.fixture(scope="module")
def manifest():
    m = load_manifest(DEFAULT_MANIFEST)
    m = replace(m, lab=replace(m.lab, walking_trials=1, walking_trial_s=20.0))
    return replace(m, free_living=replace(m.free_living, hours=0.1, start_local="07:30"))


@pytest.fixture(scope="module")
def ideal_sessions(manifest):
    """Noise-free lab sessions of a healthy (P001) and the hemiparetic participant (P003)."""
    out = {}
    for i in (0, 2):
        p = manifest.participants[i]
        out[p.id] = list(simulate_lab_session(manifest, p, i, sensor_model=SensorModelSpec.ideal()))
    return out


def _trials(ideal_sessions, pid="P001"):
    return {rec.metadata["trial"]: (rec, tr) for rec, tr in ideal_sessions[pid]}


def test_metadata_names_and_events(manifest):
    recs = list(simulate_study(manifest, participants=1))
    # a programme of two visits, each a lab session then a free-living day
    assert [r.name for r in recs] == ["P001_lab1_calibration", "P001_lab1_walk-1", "P001_free1_day-1",
                                      "P001_lab2_calibration", "P001_lab2_walk-1", "P001_free2_day-2"]
    kinds = [r.metadata["kind"] for r in recs]
    assert kinds == ["lab", "lab", "free_living"] * 2      # the calibration trial belongs to the lab session
    assert [r.metadata["session"] for r in recs[::3]] == ["P001-lab-1", "P001-lab-2"]
    day_ns = 86_400 * 10**9
    # follow-up 6 weeks after baseline, same local time (the summer-time change between them: 1 h less)
    assert round((int(recs[3].imu["foot_left"].t_ns[0]) - int(recs[0].imu["foot_left"].t_ns[0])) / day_ns) == \
        manifest.visit_interval_days
    for r in recs:
        for k in ("study", "participant", "session", "kind", "protocol", "trial", "timezone"):
            assert isinstance(r.metadata[k], str) and r.metadata[k]
        for imu in r.imu.values():
            assert imu.t_ns.dtype == np.int64 and np.all(np.diff(imu.t_ns) > 0)
    cal = recs[0]
    labels = [(e["label"], e.get("side")) for e in cal.events if e["type"] == "calibration_window"]
    assert labels == [("quiet_standing", None), ("hip_flexion_extension", "right"),
                      ("hip_flexion_extension", "left"), ("straight_walking", None)]
    walk_win = next(e for e in cal.events if e.get("label") == "straight_walking")
    assert walk_win["steps"] == manifest.lab.straight_steps
    assert set(recs[1].imu) == {"pelvis", "thigh_left", "thigh_right", "shank_left", "shank_right",
                                "foot_left", "foot_right", "chest"} | ({"lower_back"} if manifest.lab.lower_back else set())
    assert set(recs[1].ranges) == {"foot_left/A", "foot_left/B", "foot_right/A", "foot_right/B"}
    assert recs[2].imu["chest"].mag is None
    assert ("lower_back" in recs[2].imu) == manifest.free_living.lower_back


def test_deterministic(manifest):
    a = list(simulate_study(manifest, participants=1, seed=5))
    b = list(simulate_study(manifest, participants=1, seed=5))
    c = next(iter(simulate_study(manifest, participants=1, seed=6)))
    for ra, rb in zip(a, b):
        assert ra.name == rb.name and ra.events == rb.events
        for k in ra.imu:
            np.testing.assert_array_equal(ra.imu[k].acc, rb.imu[k].acc)
            np.testing.assert_array_equal(ra.imu[k].gyr, rb.imu[k].gyr)
            np.testing.assert_array_equal(ra.imu[k].t_ns, rb.imu[k].t_ns)
    assert not np.array_equal(a[0].imu["foot_left"].acc, c.imu["foot_left"].acc)


def test_stance_foot_still_and_flat(ideal_sessions):
    rec, tr = _trials(ideal_sessions)["walk-1"]
    fs = 100.0
    n_flat = 0
    for side in ("left", "right"):
        pos = tr.segment_pos[f"foot_{side}"]
        q = tr.segment_quat[f"foot_{side}"]
        ic, tc = tr.events[side]["IC"], tr.events[side]["TC"]
        T = tr.gait.stride_s
        for t_ic in ic:
            # foot flat: from IC + loading to heel-off (before the next TC)
            nxt = tc[tc > t_ic]
            if not nxt.size:
                continue
            a = int(np.ceil((t_ic + tr.gait.load_frac * T) * fs)) + 1
            b = int(np.floor((nxt[0] - tr.gait.preswing_frac * T) * fs)) - 1
            seg = slice(a, b)
            assert b - a > 10
            np.testing.assert_allclose(pos[seg], np.repeat(pos[a:a + 1], b - a, 0), atol=1e-9)
            up = quat_rotate(q[seg], np.array([0.0, 1.0, 0.0]))
            np.testing.assert_allclose(up[:, 2], 1.0, atol=1e-9)           # foot y axis vertical: flat
            np.testing.assert_allclose(tr.gyr_true[f"foot_{side}"][seg], 0.0, atol=1e-6)
            n_flat += 1
    assert n_flat > 10


def test_segment_lengths_constant_and_feet_above_floor(ideal_sessions):
    for trial, (rec, tr) in _trials(ideal_sessions, "P003").items():
        geo = tr.geometry
        for side in ("left", "right"):
            H, K, A = (tr.segment_pos[f"{s}_{side}"] for s in ("thigh", "shank", "foot"))
            np.testing.assert_allclose(np.linalg.norm(H - K, axis=1), geo.thigh_m, atol=1e-9)
            np.testing.assert_allclose(np.linalg.norm(K - A, axis=1), geo.shank_m, atol=1e-9)
            for pt in tr.foot_points[side].values():
                assert pt[:, 2].min() > -1e-6, (trial, side)


def test_rest_reads_gravity_and_zero_rate(ideal_sessions):
    rec, tr = _trials(ideal_sessions)["calibration"]
    for p, imu in rec.imu.items():
        acc_enu = quat_rotate(tr.sensor_quat[p][:300], imu.acc[:300])
        np.testing.assert_allclose(acc_enu, np.tile([0.0, 0.0, G], (300, 1)), atol=1e-6)
        np.testing.assert_allclose(imu.gyr[:300], 0.0, atol=1e-9)
        # error-free but with a mounting misalignment: the sensor frame is not the segment frame
        assert quat_angle_deg(tr.mounting_quat[p]) >= 4.9


@pytest.mark.parametrize("placement", ["foot_right", "shank_left", "thigh_right", "pelvis", "chest"])
def test_gyro_integrates_to_reference(ideal_sessions, placement):
    rec, tr = _trials(ideal_sessions)["walk-1"]
    gyr = rec.imu[placement].gyr
    q = quat_mul(tr.segment_quat[placement][0], tr.mounting_quat[placement])
    for k in range(gyr.shape[0] - 1):
        w = 0.5 * (gyr[k] + gyr[k + 1])
        q = quat_exp_step_1(q, w[0], w[1], w[2], 0.01)
    ref = quat_mul(tr.segment_quat[placement][-1], tr.mounting_quat[placement])
    assert quat_angle_deg(quat_mul(quat_conj(ref), q)) < 0.5


def test_accelerometer_double_integrates_to_position(ideal_sessions):
    rec, tr = _trials(ideal_sessions)["walk-1"]
    dt = 0.01
    for p in ("foot_left", "shank_right", "pelvis"):
        a_enu = quat_rotate(tr.sensor_quat[p], rec.imu[p].acc) - np.array([0.0, 0.0, G])
        pos = tr.sensor_pos[p]
        i0, n = 800, 100                                   # 1 s window while walking
        v0 = (pos[i0 + 1] - pos[i0 - 1]) / (2 * dt)
        # trapezoid on velocity and position
        v = v0 + np.concatenate([[np.zeros(3)], np.cumsum(0.5 * (a_enu[i0 + 1:i0 + n] + a_enu[i0:i0 + n - 1]) * dt, 0)])
        x = pos[i0] + np.concatenate([[np.zeros(3)], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt, 0)])
        err = np.abs(x - pos[i0:i0 + n]).max()
        assert err < 0.01, (p, err)


def test_ic_events_match_strides_and_sequence(ideal_sessions):
    rec, tr = _trials(ideal_sessions)["walk-1"]
    for side in ("left", "right"):
        ic, tc = tr.events[side]["IC"], tr.events[side]["TC"]
        assert len(ic) == len(tc) > 5                     # every stride: one TC then one IC
        assert np.all(tc < ic) and np.all(ic[:-1] < tc[1:])
        rec_ic = [e for e in rec.events if e["type"] == "IC" and e["side"] == side]
        assert len(rec_ic) == len(ic) and all(e["placement"] == f"foot_{side}" for e in rec_ic)
        # displacement of the foot between footprints: one stride per IC
        strides = np.diff(tr.segment_pos[f"foot_{side}"][[0, -1]][:, :2], axis=0)
        assert np.isfinite(strides).all()


def _temporal(tr, side):
    ic, tc = tr.events[side]["IC"], tr.events[side]["TC"]
    T = np.median(np.diff(ic))
    stance = np.median([tc[tc > a][0] - a for a in ic[:-1] if np.any(tc > a)]) / T
    other = "left" if side == "right" else "right"
    oic = tr.events[other]["IC"]
    step = np.median([a - oic[oic < a][-1] for a in ic if np.any(oic < a)])
    return stance, step


def test_hemiparetic_asymmetric_healthy_symmetric(ideal_sessions):
    _, tr = _trials(ideal_sessions, "P003")["walk-1"]
    st_l, step_l = _temporal(tr, "left")      # P003: paretic left
    st_r, step_r = _temporal(tr, "right")
    assert st_r - st_l > 0.05                  # longer non-paretic stance
    assert step_l - step_r > 0.05              # longer paretic step time (s)
    kl = tr.joint_angles_deg["knee_left"][:, 0].max()
    kr = tr.joint_angles_deg["knee_right"][:, 0].max()
    assert kr - kl > 5.0                       # reduced paretic knee flexion
    _, tr = _trials(ideal_sessions, "P001")["walk-1"]
    assert abs(_temporal(tr, "left")[0] - _temporal(tr, "right")[0]) < 0.01
    knee = tr.joint_angles_deg["knee_right"][:, 0]
    assert 50.0 < knee.max() < 80.0 and knee.min() > -5.0


def test_range_sensors(ideal_sessions):
    rec, tr = _trials(ideal_sessions)["walk-1"]
    r = rec.ranges["foot_left/A"]
    assert np.median(np.diff(r.t_ns)) == 30_000_000
    ok = r.range_m[np.isfinite(r.range_m)]
    assert ok.size > 0.5 * r.range_m.size and ok.min() >= 0.0 and ok.max() <= 0.2
    assert ok.max() > 0.08                                # foot lifted in swing
    np.testing.assert_allclose(np.median(ok), 0.03, atol=1e-9)   # flat foot: sensor 3 cm above the floor
    # out of range (beyond 0.2 m or beam not towards the floor) reads NaN: lift the whole foot 0.3 m
    from stridelab.validation.simulator._lab import range_geometry
    assert set(range_geometry(tr.geometry)) == set(rec.ranges)


def test_chest_day_labels_cover_duration(manifest):
    rec, truth = simulate_chest_day(manifest, manifest.participants[0], 0, keep_true=True)
    imu = rec.imu["chest"]
    assert imu.t_ns.size == int(round(manifest.free_living.hours * 3600 * 100))
    ev = [e for e in rec.events if e["type"] == "activity"]
    assert ev[0]["t_ns"] <= imu.t_ns[0] and ev[-1]["end_ns"] >= imu.t_ns[-1]
    for a, b in zip(ev[:-1], ev[1:]):
        assert a["end_ns"] == b["t_ns"]                      # no gaps, no overlaps
    allowed = {"lying", "sitting", "standing", "level_walking", "stairs_up", "stairs_down", "transition", "non_wear"}
    assert {e["label"] for e in ev} <= allowed
    # physical consistency: static periods read |acc| = g and zero rate
    static = np.linalg.norm(truth.gyr_true, axis=1) == 0
    assert static.mean() > 0.3
    np.testing.assert_allclose(np.linalg.norm(truth.acc_true[static], axis=1), G, atol=1e-9)


def test_chest_day_full_day_is_scripted(manifest):
    m = replace(manifest, free_living=replace(manifest.free_living, hours=24.0, start_local="00:00"))
    from stridelab.validation.simulator._chest_day import build_day_script
    bouts = build_day_script(np.random.default_rng(1), m.participants[2], 24 * 3600)
    labels = {b.label for b in bouts if b.t0 < 24 * 3600}
    assert {"lying", "sitting", "standing", "level_walking", "stairs_up", "stairs_down", "transition",
            "non_wear"} <= labels
    assert all(b1.t1 == pytest.approx(b2.t0) for b1, b2 in zip(bouts[:-1], bouts[1:]))


def test_more_participants_derived_deterministically(manifest):
    ps = study_participants(manifest, 7)
    assert [p.id for p in ps] == ["P001", "P002", "P003", "P004", "P005", "P006", "P007"]
    assert ps == study_participants(manifest, 7)
    assert ps[6].hemiparetic


def test_programme_follow_up_values(manifest):
    """Visit k of a programme simulates the participant moved towards the follow_up_* values (P003 improves)."""
    from stridelab.validation.simulator._gait_patterns import gait_params
    p3 = manifest.participants[2]
    assert p3.hemiparetic and p3.follow_up_speed_m_s > p3.speed_m_s and p3.follow_up_severity < p3.severity
    base, follow = p3.at_visit(1, manifest.visits), p3.at_visit(manifest.visits, manifest.visits)
    assert base == p3 and follow.speed_m_s == p3.follow_up_speed_m_s and follow.severity == p3.follow_up_severity
    assert gait_params(follow).speed_m_s > gait_params(base).speed_m_s
    healthy = manifest.participants[0]
    assert healthy.at_visit(2, 2) == healthy                # no follow_up_* values: the same participant
