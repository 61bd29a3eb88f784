"""Chest daily activity (thesis ch. 7): filter, Eq. 54-57, transitions, steps, timeline, days, bad input."""
from __future__ import annotations

import dataclasses
import datetime as dt
import json
from zoneinfo import ZoneInfo

import numpy as np
import pytest

from stridelab.estimators.activity import (PRESETS, ActivityParams, chest_height_change_m, classify_day,
                                 cumulative_svm_sign, daily_summaries, ga_filter_sos, inclination_deg, vertical_acc_g)
from stridelab.estimators.activity._types import LEVEL
from tests.conftest import shared_data

G = 9.80665
FS = 100.0


def _posture(lean_deg, n):
    th = np.deg2rad(lean_deg)
    return np.tile([-G * np.sin(th), G * np.cos(th), 0.0], (n, 1))


def _walk(n_s, f_step=1.8, lean_deg=4.0, amp=3.0):
    t = np.arange(int(n_s * FS)) / FS
    a = _posture(lean_deg, t.size)
    a[:, 1] += amp * np.sin(2 * np.pi * f_step * t)
    a[:, 0] += 0.6 * amp * np.sin(2 * np.pi * f_step * t + 0.8)
    a[:, 2] += 0.3 * amp * np.sin(np.pi * f_step * t)
    return a


def _noise(a, seed=0):
    return a + np.random.default_rng(seed).normal(0, 0.03, a.shape)


def _min_jerk(n):
    s = np.linspace(0, 1, n)
    return 10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5


def _sit_stand(direction, dur_s=2.0, drop_m=0.40, lean_end=10.0, lean_start=5.0):
    """Synthetic StSi (direction=-1) or SiSt (+1): minimum-jerk chest height change inside a lean bump."""
    n = int(dur_s * FS)
    dt_ = 1 / FS
    z = direction * drop_m * _min_jerk(n)
    az = np.gradient(np.gradient(z, dt_), dt_)
    s = np.linspace(0, 1, n)
    lean = lean_start + (lean_end - lean_start) * _min_jerk(n) + 30.0 * np.sin(np.pi * s) ** 2
    th = np.deg2rad(lean)
    f = G + az                                     # vertical specific force (world)
    return np.column_stack([-f * np.sin(th), f * np.cos(th), np.zeros(n)])


def test_ga_filter_matches_thesis_design():
    from scipy import signal
    sos = ga_filter_sos(100.0)
    b, a = signal.sos2tf(sos)
    np.testing.assert_allclose(b / a[0], [6.299566e-04, 1.2212896e-03, 6.299566e-04], rtol=1e-6)
    np.testing.assert_allclose(a / a[0], [1, -1.9299359487, 0.9324200096], atol=1e-9)
    w, h = signal.sosfreqz(sos, worN=[1.0, 2.0], fs=100.0)
    np.testing.assert_allclose(20 * np.log10(np.abs(h)), [-5.1, -15.8], atol=0.1)


def test_inclination_and_vertical_acc():
    for lean in (0.0, 30.0, -30.0, 60.0):
        ga = _posture(lean, 1)[0] / G
        assert inclination_deg(ga[1]) == pytest.approx(abs(lean), abs=1e-6)
        assert vertical_acc_g(ga[0:1], ga[1:2])[0] * G == pytest.approx(G, abs=0.01)
    assert inclination_deg(np.array([1.2, -1.3])).tolist() == [0.0, 180.0]      # clipped, never NaN


def test_cumulative_svm_sign_and_dy():
    t = np.linspace(0, 1, 200)
    lobe = np.sin(2 * np.pi * t)
    assert cumulative_svm_sign(-lobe) == -1 and cumulative_svm_sign(lobe) == 1
    a = _sit_stand(-1)
    dy, _ = chest_height_change_m(a[:, 1] / G * np.cos(0) , FS)  # raw vertical (small lean error)
    assert dy < 0


def _day(blocks, seed=0):
    return _noise(np.vstack(blocks), seed)


def test_stand_sit_stand_transitions_and_timeline():
    p = ActivityParams(thigh_length_m=0.45)
    acc = _day([_posture(5, 3000), _walk(20), _posture(5, 3000), _sit_stand(-1), _posture(10, 6000),
                _sit_stand(+1, lean_start=10, lean_end=10), _posture(10, 3000), _walk(20), _posture(5, 2000)])
    r = classify_day(acc, sampling_rate_hz=FS, params=p)
    kinds = [("SiLy", "LySi", "StSi", "SiSt")[k] for k in r.transitions.kind]
    assert kinds == ["StSi", "SiSt"]
    n_sec = int(np.ceil(acc.shape[0] / FS))
    assert r.second_class.shape == (n_sec,)                     # every second has a class
    names = r.class_names()
    sit0 = int((3000 + 2000 + 3000 + 200) / FS)
    assert (names[sit0 + 5: sit0 + 55] == "sitting").all()
    assert (names[-15:] == "standing").all()
    assert (names[35:45] == "level_walking").all()


def test_bow_rejected_no_height_change():
    n = 300
    s = np.linspace(0, 1, n)
    th = np.deg2rad(5 + 55 * np.sin(np.pi * s) ** 2)
    bow = np.column_stack([-G * np.sin(th), G * np.cos(th), np.zeros(n)])
    acc = _day([_posture(5, 3000), bow, _posture(5, 3000)])
    r = classify_day(acc, sampling_rate_hz=FS)
    assert len(r.transitions) == 0


def test_lying_transitions():
    n = 400
    lean = 10 + 80 * _min_jerk(n)
    th = np.deg2rad(lean)
    down = np.column_stack([-G * np.sin(th), G * np.cos(th), np.zeros(n)])
    up = down[::-1]
    acc = _day([_posture(10, 3000), down, _posture(90, 6000), up, _posture(10, 3000)])
    r = classify_day(acc, sampling_rate_hz=FS, params=PRESETS["thesis"])
    assert [("SiLy", "LySi", "StSi", "SiSt")[k] for k in r.transitions.kind] == ["SiLy", "LySi"]
    assert (r.class_names()[40:90] == "lying").all()


@pytest.mark.parametrize("f_step", [1.5, 1.8, 2.1])
def test_step_count_within_3_percent(f_step):
    acc = _day([_posture(5, 1000), _walk(60, f_step), _posture(5, 1000)])
    r = classify_day(acc, sampling_rate_hz=FS)
    ref = 60 * f_step
    assert abs(len(r.step_times_s) - ref) <= 0.03 * ref
    assert (r.step_modality == LEVEL).all()


def test_bout_rules_two_peaks_no_bout():
    a = _posture(5, 1000)
    for k in (300, 350):                     # two isolated bumps 0.5 s apart -> no walking
        a[k:k + 10, 1] += 5.0
    r = classify_day(_noise(a), sampling_rate_hz=FS)
    assert len(r.bouts) == 0


def test_stairs_by_slower_cadence_and_lean():
    acc = _day([_posture(5, 500), _walk(60, 1.9, 4), _walk(20, 1.45, 14), _walk(60, 1.9, 4), _walk(20, 1.45, 0),
                _walk(30, 1.9, 4), _posture(5, 500)])
    r = classify_day(acc, sampling_rate_hz=FS)
    names = r.class_names()
    assert (names[70:80] == "stairs_up").mean() > 0.8
    assert (names[150:160] == "stairs_down").mean() > 0.8
    assert (names[20:60] == "level_walking").all()


def test_upside_down_and_rotated_sensor():
    base = [_posture(5, 2000), _walk(30), _posture(5, 2000), _sit_stand(-1), _posture(12, 3000)]
    acc = _day(base)
    r0 = classify_day(acc, sampling_rate_hz=FS, params=ActivityParams(thigh_length_m=0.45))
    Rx = np.diag([1.0, -1.0, -1.0])                           # upside down on the sternum
    c, s = np.cos(0.6), np.sin(0.6)
    Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])       # plus tilted 34°
    for R in (Rx, Rz @ Rx):
        r = classify_day(acc @ R.T, sampling_rate_hz=FS, params=ActivityParams(thigh_length_m=0.45))
        assert (r.second_class == r0.second_class).mean() > 0.97
        assert abs(len(r.step_times_s) - len(r0.step_times_s)) <= 2


def test_clipped_accelerometer_warns_and_still_counts_steps():
    acc = _day([_posture(5, 1000), _walk(60, 1.8, amp=8.0), _posture(5, 1000)])
    acc = np.clip(acc, -14.0, 14.0)
    r = classify_day(acc, sampling_rate_hz=FS)
    assert any("clipped" in w for w in r.warnings)
    assert abs(len(r.step_times_s) - 108) <= 0.03 * 108


def test_no_walking_day_is_typed_and_warned():
    r = classify_day(_day([_posture(10, 20000), _posture(90, 20000)]), sampling_rate_hz=FS)
    assert len(r.bouts) == 0 and r.step_times_s.size == 0
    assert any("no walking" in w for w in r.warnings)
    ds = daily_summaries(r)
    assert ds[0].steps == {"level_walking": 0, "stairs_up": 0, "stairs_down": 0} and ds[0].bout_s_max == 0.0


def test_nonwear_after_standing():
    acc = _day([_walk(20), _posture(5, 6000), np.tile([0.0, 0.0, G], (int(1500 * FS), 1)), _posture(5, 3000),
                _walk(20)])
    r = classify_day(acc, sampling_rate_hz=FS, params=ActivityParams(nonwear_min_s=1200.0))
    nw = r.class_names() == "non_wear"
    assert 1450 <= nw.sum() <= 1620          # the perfectly still minute of standing before may join it
    assert nw[100 + 60: 100 + 1450].all()


@pytest.mark.parametrize("date,hours", [("2026-03-29", 23), ("2026-10-25", 25)])
def test_dst_day_lengths(date, hours):
    tz = ZoneInfo("Europe/Zurich")
    d = dt.date.fromisoformat(date)
    t0 = int(dt.datetime(d.year, d.month, d.day, tzinfo=tz).timestamp()) * 10 ** 9
    n = hours * 3600 * 10                                  # 10 Hz, whole day lying still (cheap)
    acc = np.tile([G, 0.0, 0.0], (n, 1)) + np.random.default_rng(1).normal(0, 0.03, (n, 3))
    r = classify_day(acc, sampling_rate_hz=10.0, t0_ns=t0, timezone="Europe/Zurich")
    ds = daily_summaries(r)
    assert len(ds) == 1 and ds[0].date == date
    assert ds[0].day_length_s == hours * 3600 == ds[0].recorded_s
    assert sum(ds[0].seconds.values()) == hours * 3600


def test_midnight_crossing_splits_days():
    tz = ZoneInfo("America/New_York")
    t0 = int(dt.datetime(2026, 5, 4, 22, 0, tzinfo=tz).timestamp()) * 10 ** 9
    acc = _day([_posture(5, 3000), _walk(30), _posture(5, 4 * 3600 * 100 - 6000)])
    r = classify_day(acc, sampling_rate_hz=FS, t0_ns=t0, timezone="America/New_York")
    ds = daily_summaries(r)
    assert [d.date for d in ds] == ["2026-05-04", "2026-05-05"]
    assert [d.recorded_s for d in ds] == [7200, r.second_class.size - 7200]
    assert ds[0].steps["level_walking"] > 40 and ds[1].steps["level_walking"] == 0


def test_input_checks():
    with pytest.raises(ValueError, match="shape"):
        classify_day(np.zeros((10, 2)), sampling_rate_hz=FS)
    with pytest.raises(ValueError, match="looks like g"):
        classify_day(_posture(0, 1000) / G, sampling_rate_hz=FS)
    with pytest.raises(ValueError, match="sampling_rate_hz"):
        classify_day(_posture(0, 1000), sampling_rate_hz=0.0)


def test_params_documented_and_stampable():
    for preset in PRESETS.values():
        assert all(f.name in (ActivityParams.__doc__ or "") for f in dataclasses.fields(preset))
        d = dataclasses.asdict(preset)
        assert ActivityParams(**json.loads(json.dumps(d))) == preset
        hash(preset)
    with pytest.raises(ValueError):
        ActivityParams(align="sideways")


def test_autocalibration_recovers_gain_and_offset():
    from stridelab.estimators.activity import autocalibrate
    rng = np.random.default_rng(3)
    dirs = rng.normal(size=(60, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    blocks = [np.tile(d, (1000, 1)) for d in dirs]
    x = np.vstack(blocks)
    gain_true, off_true = np.array([1.05, 0.97, 1.02]), np.array([0.03, -0.02, 0.05])
    raw = x / gain_true + off_true + rng.normal(0, 0.002, x.shape)
    cal = autocalibrate(raw, 100.0)
    assert cal.status == "sphere_fit"
    np.testing.assert_allclose(cal.gain, gain_true, atol=0.005)
    np.testing.assert_allclose(cal.offset_g, off_true, atol=0.005)


@pytest.mark.realdata
def test_uci_bench_runs_on_real_data(tmp_path):
    """Three real participants (links, not copies) of the default's training set: the default is scored by
    nested LOPO outer folds among them (never by the shipped model, which has seen them)."""
    from stridelab.validation.bench.activity import run_benchmark
    d = shared_data("uci_chest")
    for q in ("1", "2", "3"):
        (tmp_path / f"{q}.csv").symlink_to(d / f"{q}.csv")
    out = run_benchmark(tmp_path, show_progress=False, speed=False, tuned_rf=False)
    assert set(out["methods"]) == {"thesis", "rules", "default", "learned_loso"}
    per = out["methods"]["default"]["per_participant"]
    assert set(per) == {"1", "2", "3"} and all(v["scored_by"] == "nested LOPO outer fold" for v in per.values())
    assert out["default"] == "default" and out["best_balanced_accuracy"] in out["methods"]
    lc = out["label_consistency"]
    assert sum(lc["windows"]) == out["methods"]["default"]["windows"]
    assert 0.0 < lc["ceiling_balanced_accuracy"] <= 1.0 and lc["contradicted"][3] <= lc["windows"][3]
    for m in out["methods"].values():
        assert {"accuracy", "balanced_accuracy", "confusion", "per_participant"} <= set(m)
        assert len(m["per_participant"]) >= 1


@pytest.mark.slow
def test_simulated_day_agreement_and_steps():
    from stridelab.studies.manifest import load_manifest
    from stridelab.validation.simulator import simulate_chest_day, study_participants
    m = load_manifest(None)
    p = study_participants(m, 1)[0]
    rec, _ = simulate_chest_day(m, p, 0)
    imu = rec.imu["chest"]
    t0 = int(imu.t_ns[0])
    r = classify_day(imu.acc, sampling_rate_hz=m.sampling_rate_hz, t0_ns=t0, timezone=m.timezone,
                     params=ActivityParams(thigh_length_m=float(rec.metadata["thigh_length_m"])))
    from stridelab.validation.bench.activity import reference_seconds
    ref, steps_ref = reference_seconds(rec.events, t0, r.second_class.size)
    scored = ref >= 0                               # "transition" seconds are not scored
    assert (r.second_class[scored] == ref[scored]).mean() >= 0.95
    assert abs(len(r.step_times_s) - steps_ref) <= 0.03 * steps_ref


def _bow(peak_deg=50.0, dur_s=3.0, lean0=5.0):
    n = int(dur_s * FS)
    s = np.linspace(0, 1, n)
    th = np.deg2rad(lean0 + (peak_deg - lean0) * np.sin(np.pi * s) ** 2)
    return np.column_stack([-G * np.sin(th), G * np.cos(th), np.zeros(n)])


def _kinds(r):
    return [("SiLy", "LySi", "StSi", "SiSt")[k] for k in r.transitions.kind]


def _sitting_share(r, a_s, b_s):
    return float((r.class_names()[int(a_s):int(b_s)] == "sitting").mean())


def test_sequence_check_recovers_missed_stand_to_sit():
    """A stand-to-sit whose ΔY fails the thigh check (0.06 m) before a clear sit-to-stand: the posture sequence
    (walking = standing, a SiSt needs sitting before it) adds it back, and prefers it to a bow before it."""
    p = ActivityParams(thigh_length_m=0.45)
    blocks = [_posture(5, 2000), _walk(20), _posture(5, 2000), _bow(), _posture(5, 2000),
              _sit_stand(-1, drop_m=0.06), _posture(10, 60000), _sit_stand(+1, lean_start=10, lean_end=5),
              _posture(5, 2000), _walk(20), _posture(5, 2000)]
    acc = _day(blocks)
    sit_a = sum(b.shape[0] for b in blocks[:6]) / FS
    sit_b = sit_a + 600
    r = classify_day(acc, sampling_rate_hz=FS, params=p)
    assert _kinds(r) == ["StSi", "SiSt"]
    assert r.transitions.t_s[0] > sit_a - 5                      # the stand-to-sit, not the bow
    assert _sitting_share(r, sit_a + 5, sit_b - 5) == 1.0
    assert any("posture-sequence" in w for w in r.warnings)
    off = classify_day(acc, sampling_rate_hz=FS, params=dataclasses.replace(p, sitstand_resolve=False))
    assert _kinds(off) == ["SiSt"] and _sitting_share(off, sit_a + 5, sit_b - 5) == 0.0


def test_sequence_check_flips_one_wrong_sign_without_flipping_the_next():
    """A stand-to-sit whose chest motion reads as a rise (+0.4 m) followed by a correct sit-to-stand: the first
    is flipped to StSi, the second stays SiSt (relabelling by the current state alone flipped the second)."""
    p = ActivityParams(thigh_length_m=0.45)
    blocks = [_posture(5, 2000), _walk(20), _posture(5, 2000), _sit_stand(+1, lean_start=5, lean_end=10),
              _posture(10, 60000), _sit_stand(+1, lean_start=10, lean_end=5), _posture(5, 2000), _walk(20),
              _posture(5, 2000)]
    acc = _day(blocks)
    sit_a = sum(b.shape[0] for b in blocks[:4]) / FS
    r = classify_day(acc, sampling_rate_hz=FS, params=p)
    assert _kinds(r) == ["StSi", "SiSt"]
    assert _sitting_share(r, sit_a + 5, sit_a + 595) == 1.0
    off = classify_day(acc, sampling_rate_hz=FS, params=dataclasses.replace(p, sitstand_resolve=False))
    assert _kinds(off) == ["SiSt", "SiSt"]


def test_sequence_check_keeps_consistent_days_and_bows():
    """Standing with bows between walks: nothing added; thesis preset does not run the check."""
    p = ActivityParams(thigh_length_m=0.45)
    acc = _day([_posture(5, 2000), _walk(20), _posture(5, 3000), _bow(45), _posture(5, 3000), _bow(55),
                _posture(5, 3000), _walk(20), _posture(5, 2000)])
    r = classify_day(acc, sampling_rate_hz=FS, params=p)
    assert len(r.transitions) == 0 and not (r.class_names() == "sitting").any()
    assert PRESETS["thesis"].sitstand_resolve is False


def test_dy_from_norm_is_lag_free():
    """ΔY (Eq. 56) from ‖a‖ recovers a 0.40 m sit-to-stand within 10 % over the θ-minima window, better than the
    projection on the lagging causal GA direction (the window and the lean are those of the synthetic SiSt)."""
    from stridelab.estimators.activity._detect import _window_dy
    from stridelab.estimators.activity._signals import gravitational_component
    a = np.vstack([_posture(10, 300), _sit_stand(+1, lean_start=10, lean_end=5), _posture(5, 300)]) / G
    ga = gravitational_component(a, FS)
    i0, i1 = 300, 500
    dy_norm = _window_dy(a, ga, None, i0 - 50, i1 + 50, FS, "norm")
    dy_raw = _window_dy(a, ga, None, i0 - 50, i1 + 50, FS, "raw")
    assert abs(dy_norm - 0.40) < 0.04
    assert abs(dy_norm - 0.40) < abs(dy_raw - 0.40)


def test_bench_reference_seconds_and_no_uci_shape():
    """Per-second reference of the simulated-day bench: whole seconds inside each labelled interval,
    transitions unscored, scripted steps summed; the UCI part can be skipped without breaking the JSON keys."""
    from stridelab.validation.bench.activity import reference_seconds, run_benchmark
    s = 1_000_000_000
    ev = [{"t_ns": 0, "end_ns": 3 * s, "label": "sitting"},
          {"t_ns": 3 * s, "end_ns": int(5.5 * s), "label": "transition"},
          {"t_ns": int(5.5 * s), "end_ns": 9 * s, "label": "level_walking", "steps": 7}]
    ref, steps = reference_seconds(ev, 0, 10)
    assert steps == 7
    assert ref.tolist() == [1, 1, 1, -1, -1, -1, 3, 3, 3, -1]
    out = run_benchmark(None, show_progress=False, speed=False, simulated=0)
    assert out["methods"] == {} and out["default"] == "default" and "simulated" not in out


def _lean_change(a_deg, b_deg, dur_s=2.0):
    n = int(dur_s * FS)
    th = np.deg2rad(a_deg + (b_deg - a_deg) * _min_jerk(n))
    return np.column_stack([-G * np.sin(th), G * np.cos(th), np.zeros(n)])


def test_sequence_check_uses_reclined_trunk_as_sitting_evidence():
    """Walking, then 10 min still with the trunk reclined 30° behind the upright walking posture (θ stays above
    20°, so no candidate excursion; no chest motion), then walking: the posture evidence makes it sitting."""
    p = ActivityParams(thigh_length_m=0.45)
    blocks = [_posture(5, 2000), _walk(20), _posture(5, 2000), _lean_change(5, -30), _posture(-30, 60000),
              _lean_change(-30, 5), _posture(5, 2000), _walk(20), _posture(5, 2000)]
    acc = _day(blocks)
    a = sum(b.shape[0] for b in blocks[:4]) / FS
    r = classify_day(acc, sampling_rate_hz=FS, params=p)
    assert _sitting_share(r, a + 5, a + 595) == 1.0
    assert _kinds(r) == ["StSi", "SiSt"]
    assert (r.class_names()[int(a) - 15:int(a) - 5] == "standing").all()
    upright_only = classify_day(acc, sampling_rate_hz=FS, params=dataclasses.replace(p, sit_lean_deg=60.0))
    assert _sitting_share(upright_only, a + 5, a + 595) == 0.0


def test_resolve_sitstand_lean_evidence_without_any_candidate():
    """No excursion candidate at all, walking before and after a 10-min reclined (30°) still period: the lean
    run's onset and end become StSi / SiSt."""
    from stridelab.estimators.activity._timeline import resolve_sitstand
    from stridelab.estimators.activity._types import Bouts, Transitions
    z = np.zeros(0)
    empty = Transitions(z, np.zeros(0, np.int8), z, z, z)
    bouts = Bouts(np.array([0.0, 720.0]), np.array([60.0, 780.0]), np.array([60, 60]), np.zeros(2, np.int8),
                  np.full(2, 100.0), np.zeros(2), np.zeros(2))
    theta = np.full(800, 3.0)
    theta[100:700] = 30.0
    no = np.zeros(800, dtype=bool)
    tr, n = resolve_sitstand(empty, empty, np.zeros(0, bool), bouts, no, no, 0.15, theta, 18.0)
    assert tr.kind.tolist() == [2, 3] and tr.t_s.tolist() == [100.0, 700.0] and n == 2
    tr0, n0 = resolve_sitstand(empty, empty, np.zeros(0, bool), bouts, no, no, 0.15, theta, 40.0)
    assert len(tr0) == 0 and n0 == 0


def test_inclination_is_an_angle_even_with_a_scale_error_left_by_autocalibration():
    """An offset on the vertical axis that auto-calibration cannot see (still orientations do not cover the
    sphere) makes the upright sensor read 0.7 g (0.77 g after the common gain): Eq. 54 (theta_mode "thesis")
    turns that into a 40° lean and rejects every walking bout as not upright; the default's direction-only θ keeps walking upright."""
    import dataclasses

    n_lie, n_walk = int(1800 * FS), int(600 * FS)
    t = np.arange(n_walk) / FS
    walk = np.column_stack([-G * np.sin(0.07) + 2.0 * np.sin(2 * np.pi * 1.9 * t),
                            G * np.cos(0.07) + 3.0 * np.sin(2 * np.pi * 1.9 * t + 0.5), np.sin(np.pi * 1.9 * t)])
    acc = np.vstack([np.tile([G, 0.0, 0.0], (n_lie, 1)), np.tile([0.0, G, 0.0], (int(300 * FS), 1)), walk,
                     np.tile([G, 0.0, 0.0], (n_lie, 1))])
    acc += np.random.default_rng(3).normal(0.0, 0.03, acc.shape)
    acc[:, 1] -= 0.3 * G                  # zero-g offset on y: lying reads 1.04 g, upright 0.7 g
    r = classify_day(acc, sampling_rate_hz=FS)
    assert r.calibration.status != "sphere_fit" and len(r.bouts) > 0
    walking = r.class_names() == "level_walking"
    assert walking.mean() > 0.1 and np.median(r.inclination_deg[walking]) < 15.0
    thesis_theta = classify_day(acc, sampling_rate_hz=FS,
                                params=dataclasses.replace(PRESETS["default"], theta_mode="thesis"))
    assert np.median(thesis_theta.inclination_deg[walking]) > 25.0 and len(thesis_theta.bouts) < len(r.bouts)


def test_overwrite_input_gives_the_same_result_and_reuses_the_array():
    """``overwrite_input=True`` (the stage's memory saving) changes where the calibrated signal lives, not the
    result; without it the caller's samples stay untouched. Also through the window model, whose posterior
    must be computed before the rules overwrite the samples."""
    from stridelab.pipeline.activity_model import classify_recording
    p = ActivityParams(thigh_length_m=0.45)
    acc = _day([_posture(5, 3000), _walk(20), _posture(5, 3000), _sit_stand(-1), _posture(10, 6000),
                _sit_stand(+1, lean_start=10, lean_end=10), _posture(10, 3000), _walk(20), _posture(5, 2000)])
    acc = np.ascontiguousarray(acc * 1.02 + 0.05)          # off-nominal gain and offset: a real calibration step
    for run in (lambda a, **k: classify_day(a, sampling_rate_hz=FS, params=p, **k),
                lambda a, **k: classify_recording(a, sampling_rate_hz=FS, params=p, **k)):
        keep = acc.copy()
        ref = run(acc)
        np.testing.assert_array_equal(acc, keep)           # the copy path leaves the input alone
        work = acc.copy()
        got = run(work, overwrite_input=True)
        assert not np.array_equal(work, keep)              # the array was reused for the calibrated signal
        for f in dataclasses.fields(ref):
            a, b = getattr(ref, f.name), getattr(got, f.name)
            if isinstance(a, np.ndarray):
                np.testing.assert_array_equal(a, b, err_msg=f.name)
            elif dataclasses.is_dataclass(a):
                assert repr(a) == repr(b), f.name
            else:
                assert a == b, f.name
