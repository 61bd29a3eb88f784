"""Decoupled complementary filter, evaluation metric, family meta-tests and the BROAD accuracy check."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from stridelab.estimators.orientation import (DEFAULT_OFFLINE, DEFAULT_ONLINE, ESTIMATORS, DCFFilter, DCFOfflineParams, MadgwickParams, MahonyParams,
                                    DCFParams, YunCFParams, dcf, dcf_offline)
from stridelab.estimators.orientation.evaluation import orientation_error_deg, orientation_rmse_deg
from stridelab.estimators.quaternion import quat_conj, quat_from_axis_angle, quat_from_rotvec, quat_mul, quat_rotate

G = 9.81
B_ENU = 48.0 * np.array([0.0, np.cos(np.radians(63.0)), -np.sin(np.radians(63.0))])
PROJECT_ROOT = Path(__file__).resolve().parents[3]
BROAD = PROJECT_ROOT.parent / "shared" / "data" / "broad"
PARAMS_CLASSES = [DCFParams, DCFOfflineParams, YunCFParams, MadgwickParams, MahonyParams]


def _moving(n=3000, fs=100.0, seed=1):
    """Smooth random rotation with gravity + field, sensor-frame measurements, and the true quaternions."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    w = np.column_stack([np.sin(2 * np.pi * f * t + p) * a for f, p, a in
                         zip(rng.uniform(0.1, 0.5, 3), rng.uniform(0, 6, 3), (1.0, 0.8, 1.5))])
    w[: int(2 * fs)] = 0.0
    q = np.empty((n, 4))
    q[0] = quat_from_axis_angle([1.0, 0.5, 0.0], 0.4)
    for i in range(1, n):
        rv = w[i] / fs
        q[i] = quat_mul(q[i - 1], quat_from_rotvec(rv))
    acc = quat_rotate(quat_conj(q), np.array([0, 0, G]))
    mag = quat_rotate(quat_conj(q), B_ENU)
    return w, acc, mag, q


@pytest.mark.parametrize("name", sorted(ESTIMATORS))
def test_zero_input_keeps_initial_attitude(name):
    q0 = quat_from_axis_angle([0.2, 1.0, 0.3], 0.6)
    n = 400
    acc = np.tile(quat_rotate(quat_conj(q0), [0, 0, G]), (n, 1))
    mag = np.tile(quat_rotate(quat_conj(q0), B_ENU), (n, 1))
    res = ESTIMATORS[name](np.zeros((n, 3)), acc, mag, sampling_rate_hz=100.0)
    e = orientation_error_deg(res.quat, np.tile(q0, (n, 1)))[0]
    assert e[50:].max() < 0.5
    assert np.allclose(res.quat[-1], res.quat[200], atol=1e-3)


@pytest.mark.parametrize("name", sorted(ESTIMATORS))
def test_estimators_track_noise_free_rotation(name):
    gyr, acc, mag, q = _moving()
    res = ESTIMATORS[name](gyr, acc, mag, sampling_rate_hz=100.0)
    assert res.quat.shape == q.shape
    assert orientation_rmse_deg(res.quat, q).total_rmse_deg < (5.0 if name == "yun_cf" else 1.0)


def test_dcf_chunked_equals_whole_and_state_roundtrip():
    gyr, acc, mag, _ = _moving(seed=3)
    gyr = gyr + 0.01
    whole = dcf(gyr, acc, mag, sampling_rate_hz=100.0)
    f = DCFFilter(DCFParams(), sampling_rate_hz=100.0)
    a = f.update_batch(gyr[:700], acc[:700], mag[:700])
    g = DCFFilter(DCFParams(), sampling_rate_hz=100.0)
    g.state = f.state
    b = g.update_batch(gyr[700:], acc[700:], mag[700:])
    np.testing.assert_allclose(np.vstack([a.quat, b.quat]), whole.quat, rtol=0, atol=1e-12)


def test_dcf_removes_gyro_bias_at_rest():
    n, fs = 6000, 100.0
    gyr = np.tile([0.0, 0.0, np.radians(1.0)], (n, 1))        # 1°/s bias about the vertical, 60 s at rest
    acc = np.tile([0.0, 0.0, G], (n, 1))
    res = dcf(gyr, acc, None, sampling_rate_hz=fs)               # 6D: nothing else can stop the heading drift
    e = orientation_error_deg(res.quat[-1:], res.quat[int(5 * fs):int(5 * fs) + 1])[0][0]
    assert e < 0.2                                                # plain integration would drift 55°


def test_dcf_rejects_a_magnetic_disturbance():
    gyr, acc, mag, q = _moving(n=6000, seed=5)
    mag_d = mag.copy()
    mag_d[2500:3500] *= 1.3                                      # field +30 % for 10 s (spec T8)
    clean = dcf(gyr, acc, mag, sampling_rate_hz=100.0)
    dist = dcf(gyr, acc, mag_d, sampling_rate_hz=100.0)
    assert (dist.gain[2600:3400] == 0).mean() > 0.8
    h = orientation_error_deg(dist.quat, q)[1]
    assert h[2500:3600].max() < orientation_error_deg(clean.quat, q)[1].max() + 1.0
    off = dcf_offline(gyr, acc, mag_d, sampling_rate_hz=100.0)
    assert orientation_error_deg(off.quat, q)[1][2500:3600].max() < 1.5


def test_dcf_gaps_short_recordings_and_6d():
    gyr, acc, mag, _ = _moving(seed=7)
    gyr[500:520] = np.nan
    acc[900:950] = np.nan
    mag[1200:1300] = np.nan
    for f in (dcf, dcf_offline):
        res = f(gyr, acc, mag, sampling_rate_hz=100.0)
        assert np.isfinite(res.quat).all()
        assert not f(gyr, acc, None, sampling_rate_hz=100.0).mag_used
        with pytest.raises(ValueError, match="shorter than one second"):
            f(gyr[:50], acc[:50], None, sampling_rate_hz=100.0)


def test_error_split_heading_and_inclination():
    n = 10
    ref = np.tile(quat_from_axis_angle([0.3, 0.1, 1.0], 0.8), (n, 1))
    yaw = quat_mul(quat_from_axis_angle([0, 0, 1.0], np.radians(7.0)), ref)       # earth-frame heading error
    tot, head, inc = orientation_error_deg(yaw, ref)
    np.testing.assert_allclose([tot[0], head[0], inc[0]], [7.0, 7.0, 0.0], atol=1e-5)
    tilt = quat_mul(quat_from_axis_angle([1.0, 0, 0], np.radians(4.0)), ref)
    tot, head, inc = orientation_error_deg(tilt, ref)
    np.testing.assert_allclose([tot[0], head[0], inc[0]], [4.0, 0.0, 4.0], atol=1e-5)
    r = orientation_rmse_deg(yaw, ref, np.r_[np.ones(5, bool), np.zeros(5, bool)])
    assert r.n_scored == 5 and r.total_rmse_deg == pytest.approx(7.0)
    with pytest.raises(ValueError, match="no sample"):
        orientation_rmse_deg(yaw, ref, np.zeros(n, bool))


@pytest.mark.parametrize("params_cls", PARAMS_CLASSES)
def test_params_documented_hashable_and_json_roundtrip(params_cls):
    p = params_cls()
    doc = params_cls.__doc__ or ""
    assert all(f.name in doc for f in dataclasses.fields(p))
    hash(p)
    d = {k: tuple(v) if isinstance(v, list) else v for k, v in json.loads(json.dumps(dataclasses.asdict(p))).items()}
    if params_cls is DCFOfflineParams:
        d["online"] = DCFParams(**d["online"])
    assert params_cls(**d) == p


def test_registry_defaults_exist():
    assert DEFAULT_ONLINE in ESTIMATORS and DEFAULT_OFFLINE in ESTIMATORS


@pytest.fixture(scope="module")
def broad_trials():
    if not BROAD.is_dir():
        pytest.skip(f"BROAD data not found at {BROAD}; see DESIGN.md 'Real data'")
    from stridelab.pipeline.formats.broad import load_broad
    return load_broad(BROAD)


@pytest.mark.realdata
def test_broad_reader_finds_every_trial(broad_trials):
    assert len(broad_trials) == len(list(BROAD.glob("*.hdf5")))
    t = broad_trials[0]
    assert t.gyr.shape == t.acc.shape == t.mag.shape and t.quat_ref.shape == (len(t.gyr), 4)
    assert 280 < t.sampling_rate_hz < 290 and t.movement.any() and t.groups


@pytest.mark.realdata
@pytest.mark.slow
def test_default_online_beats_vqf_on_broad(broad_trials):
    def mean_err(name):
        return np.mean([orientation_rmse_deg(ESTIMATORS[name](t.gyr, t.acc, t.mag, sampling_rate_hz=t.sampling_rate_hz)
                                             .quat, t.quat_ref, t.movement).total_rmse_deg for t in broad_trials])
    ours, ref = mean_err(DEFAULT_ONLINE), mean_err("vqf")
    assert ours <= ref, f"default online {DEFAULT_ONLINE} {ours:.3f}° vs vqf {ref:.3f}°"


def test_shipped_tuned_gains_are_the_defaults():
    d = json.loads((PROJECT_ROOT / "estimators" / "orientation" / "tuned_gains.json").read_text())
    assert dataclasses.asdict(DCFParams()) == d["dcf"]["params"]
    assert dataclasses.asdict(DCFOfflineParams()) == d["dcf_offline"]["params"]


def test_leave_trials_out_picks_on_training_folds_only():
    from stridelab.estimators.orientation.tuning import leave_trials_out
    err = np.array([[1.0, 1.0, 1.0, 1.0, 1.0, 1.0], [0.5, 2.0, 2.0, 0.5, 2.0, 2.0]])
    cv = leave_trials_out(err, ["a", "b"], n_folds=3)
    assert cv.folds == ((0, 3), (1, 4), (2, 5)) and cv.chosen_per_fold == (0, 0, 0) and cv.cv_error_deg == 1.0


@pytest.mark.realdata
def test_bench_orientation_json_format():
    if not BROAD.is_dir():
        pytest.skip(f"BROAD data not found at {BROAD}; see DESIGN.md 'Real data'")
    from click.testing import CliRunner
    from stridelab.validation.bench.orientation import command
    one = sorted(BROAD.glob("*.hdf5"))[0]
    r = CliRunner().invoke(command, ["--broad", str(one), "--estimator", "dcf", "--estimator", "vqf", "--json"])
    assert r.exit_code != 0 and "at least two groups" in r.output          # one trial: no fold to hold out
    r = CliRunner().invoke(command, ["--broad", str(one), "--estimator", "dcf", "--estimator", "vqf", "--json",
                                     "--no-cv"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert set(d) == {"trials", "summary", "default", "default_offline", "in_sample_note", "shipped_defaults",
                      "cross_validated", "in_sample", "attached_magnet_synthetic"}
    assert d["shipped_defaults"]["online_rmse_deg"] == d["summary"]["dcf"]["mean_total_rmse_deg"]
    assert d["shipped_defaults"]["vqf_rmse_deg"] == d["summary"]["vqf"]["mean_total_rmse_deg"]
    assert d["cross_validated"]["recorded"] is True                    # --no-cv: the figures of tuned_gains.json
    assert set(d["attached_magnet_synthetic"]) == {"dcf", "vqf"}
    assert set(d["attached_magnet_synthetic"]["dcf"]["by_offset_ut"]) == {"4", "10", "25", "40"}
    assert {t["estimator"] for t in d["trials"]} == {"dcf", "vqf"}
    assert set(d["trials"][0]) == {"trial", "group", "estimator", "total_rmse_deg", "heading_rmse_deg",
                                   "inclination_rmse_deg"}
    assert set(d["summary"]["dcf"]) == {"mean_total_rmse_deg", "us_per_sample", "in_sample", "by_group"}
    assert d["summary"]["dcf"]["in_sample"] and not d["summary"]["vqf"]["in_sample"]


@pytest.mark.realdata
@pytest.mark.slow
def test_bench_cross_validation_holds_each_group_out():
    """Leave-one-group-out on three real BROAD trials (one per group, first 60 s): every trial's held-out error
    is the error of the candidate chosen on the *other* trials, for ours and for the tuned baselines."""
    if not BROAD.is_dir():
        pytest.skip(f"BROAD data not found at {BROAD}; see DESIGN.md 'Real data'")
    from stridelab.validation.bench.orientation import candidate_grids, run_cross_validation
    from stridelab.pipeline.formats.broad import load_broad
    from stridelab.estimators.orientation.tuning import trial_groups
    names = ("05_undisturbed_slow_rotation_with_breaks_B", "18_undisturbed_fast_translation_with_breaks_B",
             "24_disturbed_tapping_A")
    trials = []
    for n in names:
        t = load_broad(BROAD / f"{n}.hdf5")[0]
        k = int(60 * t.sampling_rate_hz)            # movement (scored) starts after 32-45 s of rest
        trials.append(dataclasses.replace(t, gyr=t.gyr[:k], acc=t.acc[:k], mag=t.mag[:k], quat_ref=t.quat_ref[:k],
                                          movement=t.movement[:k], pos_ref=None))
    labels = trial_groups(trials)
    assert labels == ("rotation", "translation", "disturbed")
    cv = run_cross_validation(trials, labels, pso=(4, 2))
    assert cv["folds"] == {g: [n] for g, n in zip(labels, names)}
    for name, m in cv["methods"].items():
        assert set(m["heldout_by_group_deg"]) == set(labels)
        if m.get("tuning") != "grid":
            continue
        by = np.array([[c[g] for g in labels] for c in m["candidate_by_group_deg"]])   # (candidates, trials)
        for j, g in enumerate(labels):
            best = int(np.argmin(np.delete(by, j, axis=1).mean(axis=1)))
            assert m["chosen_per_fold"][g] == m["candidates"][best], name
            assert m["heldout_per_trial_deg"][names[j]] == pytest.approx(by[best, j], abs=1e-12)
    assert set(candidate_grids()) <= set(cv["methods"]) and {"madgwick_pso", "mahony_pso"} <= set(cv["methods"])


def test_leave_groups_out_chooses_without_the_held_out_group():
    from stridelab.estimators.orientation.tuning import leave_groups_out, trial_groups
    err = np.array([[1.0, 1.0, 3.0, 3.0], [2.0, 2.0, 0.5, 0.5], [0.9, 5.0, 5.0, 0.9]])
    cv = leave_groups_out(err, ["a", "b", "c"], ["g1", "g1", "g2", "g2"])
    assert cv.folds == ((0, 1), (2, 3)) and cv.chosen_per_fold == (1, 0)
    np.testing.assert_allclose(cv.heldout_per_trial, [2.0, 2.0, 3.0, 3.0])
    assert cv.cv_error_deg == 2.5
    with pytest.raises(ValueError, match="two groups"):
        leave_groups_out(err, ["a", "b", "c"], ["g", "g", "g", "g"])

    class T:
        name, groups = "x", ("undisturbed", "combined")
    with pytest.raises(ValueError, match="none of the groups"):
        trial_groups([T()])


def test_rest_bias_kalman_is_not_pulled_by_the_onset_of_a_slow_movement():
    """20 s at rest with a 0.5°/s bias, then a slow yaw whose rate ramps up by 1.5°/s²: for ~2 s the causal
    rest detector still says 'rest' (the gyro stays within 2°/s of its 0.5-s low-pass). Setting the bias to the
    low-passed gyro then takes in the movement (≈ 4°/s, the detector's limit); the Kalman update (VQF's rest-bias
    estimation, steady-state time constant ≈ 9 s) moves by a fraction of the onset (measured 0.43°/s)."""
    fs, n0, n1 = 100.0, 2000, 600
    t = np.arange(n1) / fs
    rate = np.r_[np.zeros(n0), np.radians(1.5) * t]
    gyr = np.column_stack([np.zeros(n0 + n1), np.zeros(n0 + n1), rate + np.radians(0.5)])
    acc = np.tile([0.0, 0.0, G], (n0 + n1, 1))
    bias = {}
    for mode in ("lowpass", "kalman"):
        f = DCFFilter(DCFParams(rest_bias=mode), sampling_rate_hz=fs)
        f.update_batch(gyr, acc, None)
        bias[mode] = np.degrees(f.state[20])
    assert abs(bias["lowpass"] - 0.5) > 3.0
    assert abs(bias["kalman"] - 0.5) < 0.5


def _heading_rmse_deg(q_est, q_true, sl):
    e = orientation_rmse_deg(q_est[sl], q_true[sl], np.ones(len(q_true[sl]), bool))
    return e.heading_rmse_deg


def test_attached_magnet_longer_than_the_rejection_limit_is_not_adopted():
    """Issue 43, online orientation: a magnet that moves with the sensor (hard iron, a constant sensor-frame offset, as
    BROAD trials 32/34: 58 / 14 µT) for longer than ``mag_reject_max_s`` (60 s). Before, the filter rejected the
    disturbed field for 60 s and then adopted it as the new reference: the heading followed the disturbed field (tens
    of degrees off). Now the online hard-iron fit removes the offset and the settling time keeps the disturbance's
    edges out; the old configuration (no hard-iron fit, no settling) still fails here, so the test can fail."""
    fs = 100.0
    w, acc, mag, q = _moving(n=int(150 * fs), fs=fs, seed=5)
    b = 25.0 * np.array([0.6, -0.48, 0.64])                     # 25 µT, fixed sensor-frame direction
    on, off = int(20 * fs), int(110 * fs)                        # on for 90 s while moving
    mag = mag.copy()
    mag[on:off] += b
    sl = slice(on, off)
    new = dcf(w, acc, mag, sampling_rate_hz=fs)
    old = dcf(w, acc, mag, sampling_rate_hz=fs, params=DCFParams(hard_iron=False, mag_settle_s=0.0))
    e_new, e_old = _heading_rmse_deg(new.quat, q, sl), _heading_rmse_deg(old.quat, q, sl)
    assert e_old > 8.0, f"the failure mode is not reproduced: old heading RMSE {e_old:.1f}°"
    assert e_new < 2.0, f"heading RMSE with the magnet on {e_new:.1f}° (old configuration {e_old:.1f}°)"


def test_hard_iron_fit_leaves_a_clean_field_alone():
    """Without a magnet the hard-iron correction stays off (offset below ``hard_iron_min_ut``): the result equals the
    filter without the fit, sample for sample."""
    w, acc, mag, q = _moving(n=6000, fs=100.0, seed=2)
    a = dcf(w, acc, mag, sampling_rate_hz=100.0).quat
    b = dcf(w, acc, mag, sampling_rate_hz=100.0, params=DCFParams(hard_iron=False)).quat
    np.testing.assert_array_equal(a, b)


def test_hard_iron_fit_ignores_a_field_that_does_not_move_with_the_sensor():
    """A disturbance fixed in the room (the field rotates with the earth frame, not the sensor: no sphere in the sensor
    frame) fails the norm model: the fit's residual stays above its threshold and the correction is never applied, so
    the result equals the filter without the fit."""
    w, acc, mag, q = _moving(n=9000, fs=100.0, seed=3)
    dist = quat_rotate(quat_conj(q), np.array([15.0, -10.0, 5.0]))   # earth-fixed extra field, from 20 s to 60 s
    mag = mag.copy()
    mag[2000:6000] += dist[2000:6000]
    a = dcf(w, acc, mag, sampling_rate_hz=100.0).quat
    b = dcf(w, acc, mag, sampling_rate_hz=100.0, params=DCFParams(hard_iron=False)).quat
    np.testing.assert_array_equal(a, b)
