"""Madgwick / Mahony online classes and switching, particle-swarm tuning (spec §4.3-4.4, §4.8, 9.1 T6, 9.2 T10)."""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from stridelab.estimators.orientation import (MadgwickFilter, MadgwickParams, MahonyFilter, MahonyParams, madgwick, mahony)
from stridelab.estimators.orientation.evaluation import orientation_error_deg, orientation_rmse_deg
from stridelab.estimators.orientation.pso import SwarmData, SwitchingSpace, pso_minimize, swarm_errors, tune_pso
from tests.estimators.orientation.test_fullstate import simulate

G = 9.81
ROOT = Path(__file__).resolve().parents[3]
BROAD = ROOT.parent / "shared" / "data" / "broad"
TUNED = ROOT / "estimators" / "orientation" / "tuned_gains.json"

VST1 = MadgwickParams(beta_levels_rad_s=(0.05, 0.002), s_acc_g=(0.03,), s_mag=(0.05,), zeta_rad_s=0.002,
                      static_bias=True)
MVST2 = MahonyParams(kp_levels_per_s=(2.0, 0.5, 0.01), ki_per_s2=0.01, s_acc_g=(0.02, 0.1), s_mag=(0.05, 0.2),
                     static_bias=True)


@pytest.mark.parametrize("cls,params", [(MadgwickFilter, VST1), (MahonyFilter, MVST2),
                                        (MadgwickFilter, MadgwickParams()),
                                        (MahonyFilter, MahonyParams())])
def test_chunked_equals_whole_and_state_roundtrip(cls, params):
    gyr, acc, mag, _, _ = simulate(n=1500, seed=7)
    whole = (madgwick if cls is MadgwickFilter else mahony)(gyr, acc, mag, sampling_rate_hz=100.0, params=params)
    f = cls(params, sampling_rate_hz=100.0)
    a = f.update_batch(gyr[:700], acc[:700], mag[:700])
    g = cls(params, sampling_rate_hz=100.0)
    g.state = f.state
    b = g.update_batch(gyr[700:], acc[700:], mag[700:])
    np.testing.assert_allclose(np.vstack([a.quat, b.quat]), whole.quat, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(np.r_[a.gain, b.gain], whole.gain)


def test_magnetic_switch_selects_the_low_gain_level():
    gyr, acc, mag, _, _ = simulate(n=1000, seed=8, noise=False, bias_deg_s=0.0)
    acc[:] = np.linalg.norm(acc, axis=1, keepdims=True) * acc / np.linalg.norm(acc, axis=1, keepdims=True)
    mag[500:600] *= 1.3                                           # +30 % field: Δ_M = 0.3 > S_M
    res = madgwick(gyr, acc, mag, sampling_rate_hz=100.0, params=VST1)
    assert np.all(res.gain[500:600] == 0.002)
    # Δ_A alone decides elsewhere: level 0 where |‖a‖ − g| < 0.03 g and the field is undisturbed
    da = np.abs(np.linalg.norm(acc, axis=1) - G) / G
    quiet = (da < 0.03) & (np.arange(1000) < 500)
    assert np.all(res.gain[quiet] == 0.05)


def test_static_bias_removal_stops_6d_heading_drift():
    n = 6000
    gyr = np.tile([0.0, 0.0, np.radians(1.0)], (n, 1))           # 1°/s bias about up, at rest
    acc = np.tile([0.0, 0.0, G], (n, 1))
    for fn, p in ((madgwick, MadgwickParams(static_bias=True)), (mahony, MahonyParams(static_bias=True))):
        res = fn(gyr, acc, None, sampling_rate_hz=100.0, params=p)
        assert orientation_error_deg(res.quat[-1:], res.quat[:1])[0][0] < 0.05
    drift = madgwick(gyr, acc, None, sampling_rate_hz=100.0)      # default: no removal, ≈ 60° of drift
    assert orientation_error_deg(drift.quat[-1:], drift.quat[:1])[0][0] > 30


def test_pso_finds_the_minimum_of_a_shifted_quadratic():
    c = np.array([0.3, -1.2, 2.0])
    res = pso_minimize(lambda X: ((X - c) ** 2).sum(axis=1), [-5, -5, -5], [5, 5, 5], n_particles=30, n_iter=60,
                       seed=1)
    np.testing.assert_allclose(res.x, c, atol=1e-3)
    assert np.all(np.diff(res.history) <= 0)


@dataclass
class _Trial:
    name: str
    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray
    quat_ref: np.ndarray
    movement: np.ndarray
    sampling_rate_hz: float = 100.0


def _trials(k=3, n=2000):
    out = []
    for i in range(k):
        gyr, acc, mag, q, _ = simulate(n=n, seed=20 + i, bias_deg_s=0.3)
        out.append(_Trial(f"t{i}", gyr, acc, mag, q, np.arange(n) >= 300))
    return out


@pytest.mark.parametrize("filt,levels", [("madgwick", 2), ("mahony", 3), ("madgwick", 1)])
def test_swarm_scores_equal_the_public_filter(filt, levels):
    trials = _trials()
    data = SwarmData.from_trials(trials)
    space = SwitchingSpace(filt, levels)
    lo, hi = space.bounds()
    X = lo + np.random.default_rng(0).random((3, lo.size)) * (hi - lo)
    X[:, :levels] = np.round(X[:, :levels], 3)
    E = swarm_errors(space, X, data)
    fn = madgwick if filt == "madgwick" else mahony
    for p in range(3):
        params = space.to_params(X[p])
        direct = [orientation_rmse_deg(fn(t.gyr, t.acc, t.mag, sampling_rate_hz=100.0, params=params).quat,
                                       t.quat_ref, t.movement).total_rmse_deg for t in trials]
        np.testing.assert_allclose(E[p], direct, rtol=2e-3, atol=2e-3)   # params rounded to 4 significant digits


def test_tuning_beats_the_paper_gain_on_training_trials():
    trials = _trials(k=2, n=1500)
    data = SwarmData.from_trials(trials)
    r = tune_pso(SwitchingSpace("madgwick", 2), data, n_particles=12, n_iter=8, seed=0)
    paper = np.mean([orientation_rmse_deg(madgwick(t.gyr, t.acc, t.mag, sampling_rate_hz=100.0).quat, t.quat_ref,
                                          t.movement).total_rmse_deg for t in trials])
    assert r.train_cost_deg < paper
    assert r.n_evaluations == 96 and len(r.history) == 8


@pytest.mark.realdata
def test_shipped_adaptive_gains_beat_fixed_gains_on_broad():
    """Spec 9.2 T10 on real data: the shipped 3-level (VST2) gains beat the fixed gains (FOG) tuned the same way,
    on all 15 BROAD trials (re-measured here) and in leave-trials-out CV (figures recorded in tuned_gains.json).
    Not asserted because it is not true: Madgwick VST1 loses to FOG in CV (3.31° vs 3.11°, docs/orientation.md)."""
    if not BROAD.is_dir():
        pytest.skip(f"BROAD data not found at {BROAD}; see DESIGN.md 'Real data'")
    from stridelab.estimators.orientation import MADGWICK_BROAD_VST2, MAHONY_BROAD_VST2
    from stridelab.pipeline.formats.broad import load_broad
    tuned = json.loads(TUNED.read_text())
    trials = load_broad(BROAD)
    tup = lambda d: {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}
    for filt, cls, fn, shipped in (("madgwick", MadgwickParams, madgwick, MADGWICK_BROAD_VST2),
                                   ("mahony", MahonyParams, mahony, MAHONY_BROAD_VST2)):
        entry = tuned[f"{filt}_pso"]
        fog, vst = cls(**tup(entry["fog"]["params"])), cls(**tup(entry["adaptive"]["params"]))
        assert vst == shipped                                   # the code preset is what the JSON records
        err = {}
        for tag, p in (("fog", fog), ("vst", vst)):
            err[tag] = np.mean([orientation_rmse_deg(fn(t.gyr, t.acc, t.mag, sampling_rate_hz=t.sampling_rate_hz,
                                                        params=p).quat, t.quat_ref, t.movement).total_rmse_deg
                                for t in trials])
        assert err["vst"] < err["fog"], (filt, err)
        assert err["vst"] == pytest.approx(entry["adaptive"]["mean_error_all_trials_deg"], abs=0.01)
        assert entry["adaptive"]["cv_heldout_mean_total_rmse_deg"] < entry["fog"]["cv_heldout_mean_total_rmse_deg"]

def _disturbed_trial(seed, n=6000, fs=100.0):
    """Spec 9.2-like synthetic trial: smooth rotation, 1-s bursts of 1.5 g external acceleration every 8 s and
    two 10-s magnetic disturbances (+30 % norm, field rotated 25°), bias 0.5°/s, white noise."""
    rng = np.random.default_rng(seed)
    gyr, acc, mag, q, _ = simulate(n=n, fs=fs, seed=seed, bias_deg_s=0.5)
    t = np.arange(n) / fs
    for t0 in np.arange(5.0, n / fs - 2, 8.0):
        i0, i1 = int(t0 * fs), int((t0 + 1.0) * fs)
        d = rng.normal(size=3)
        burst = 1.5 * G * np.sin(np.pi * (t[i0:i1] - t0))[:, None] * d / np.linalg.norm(d)
        acc[i0:i1] += burst                               # body-frame burst (direction irrelevant here)
    for t0 in (15.0, 40.0):
        i0, i1 = int(t0 * fs), int((t0 + 10.0) * fs)
        ang = np.radians(25.0)
        rz = np.array([[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1]])
        mag[i0:i1] = 1.3 * mag[i0:i1] @ rz.T
    return _Trial(f"d{seed}", gyr, acc, mag, q, t >= 3.0)


@pytest.mark.parametrize("filt", ["madgwick", "mahony"])
def test_adaptive_beats_fixed_gains_on_held_out_synthetic_trials(filt):
    """Spec 9.2 T10: PSO on one simulated trial, tested on 3 others; VST1 beats FOG (held-out mean RMSE)."""
    train = SwarmData.from_trials([_disturbed_trial(100)])
    test = SwarmData.from_trials([_disturbed_trial(s) for s in (101, 102, 103)])
    held = {}
    for levels in (1, 2):
        space = SwitchingSpace(filt, levels)
        r = tune_pso(space, train, n_particles=20, n_iter=15, seed=0)
        held[levels] = float(swarm_errors(space, np.asarray(r.x)[None], test)[0].mean())
    assert held[2] < held[1], held


def test_ekf_swarm_scores_equal_the_public_filter():
    from stridelab.estimators.orientation import RobustEKFParams, robust_ekf
    from stridelab.estimators.orientation.pso import EKFSwarmData, ekf_decode, ekf_encode, ekf_swarm_errors
    trials = _trials(k=2, n=1500)
    data = EKFSwarmData.from_trials(trials)
    x = ekf_encode(RobustEKFParams())
    assert ekf_decode(x) == RobustEKFParams()
    X = np.stack([x, x + 0.05])
    E = ekf_swarm_errors(X, data)
    for p in range(2):
        params = ekf_decode(X[p])
        direct = [orientation_rmse_deg(robust_ekf(t.gyr, t.acc, t.mag, sampling_rate_hz=100.0, params=params).quat,
                                       t.quat_ref, t.movement).total_rmse_deg for t in trials]
        np.testing.assert_allclose(E[p], direct, rtol=0, atol=1e-9)
