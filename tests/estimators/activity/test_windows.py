"""Window features of the learned chest-activity classifier (stridelab.estimators.activity.windows) and its LOSO bench."""
from __future__ import annotations

import numpy as np
import pytest

from stridelab.estimators.activity.windows import (FEATURE_NAMES, add_context, gait_windows, lean_deg, posture_clusters,
                                         window_features)
from tests.conftest import shared_data

G = 9.80665
FS = 52.0


def _still(lean_deg_, n_s, seed):
    th = np.deg2rad(lean_deg_)
    n = int(n_s * FS)
    a = np.tile([-G * np.sin(th), G * np.cos(th), 0.0], (n, 1))
    return a + np.random.default_rng(seed).normal(0, 0.02, a.shape)


def _walk(n_s, f_step=1.8, seed=0):
    t = np.arange(int(n_s * FS)) / FS
    a = _still(2.0, n_s, seed)
    a[:, 1] += 2.5 * np.sin(2 * np.pi * f_step * t)
    a[:, 0] += 1.2 * np.sin(2 * np.pi * f_step * t + 0.8)
    a[:, 2] += 0.6 * np.sin(np.pi * f_step * t)
    return a


def _day():
    # sitting 20° for 200 s, standing 3° 100 s, walking 1.8 Hz 150 s, standing 100 s (+ a partial window)
    return np.vstack([_still(20.0, 200, 1), _still(3.0, 100, 2), _walk(150), _still(3.0, 105, 3)])


def test_window_features_shape_units_and_determinism():
    acc = _day()
    wf = window_features(acc, FS)
    assert wf.window_samples == 520
    assert wf.x.shape == (acc.shape[0] // 520, len(FEATURE_NAMES)) and wf.names == FEATURE_NAMES
    assert np.all(np.isfinite(wf.x))
    np.testing.assert_array_equal(wf.x, window_features(acc, FS).x)            # deterministic
    col = {n: wf.x[:, i] for i, n in enumerate(FEATURE_NAMES)}
    walk = slice(31, 44)                                                        # windows fully inside the walk
    assert wf.gait[walk].all() and not wf.gait[:30].any()
    np.testing.assert_allclose(col["cadence_hz"][walk], 1.8, atol=0.06)          # Hz
    np.testing.assert_allclose(col["cadence_rel"][walk], 1.0, atol=0.03)
    assert np.all(col["step_regularity"][walk] > 0.8)
    # lean in degrees: sitting 20° vs walking 2° -> ≈ 18° from the walking posture; standing ≈ 1°
    np.testing.assert_allclose(np.median(col["lean_walk_deg"][2:19]), 18.0, atol=1.0)
    assert np.median(col["lean_walk_deg"][21:29]) < 2.0
    # two still-posture clusters ≈ 17° apart; sitting is closer to the leaning one, standing to the upright one
    assert 14.0 < col["cluster_sep_deg"][0] < 20.0
    assert np.all(col["posture_margin_deg"][2:19] < 0) and np.all(col["posture_margin_deg"][21:29] > 0)
    # amplitudes are log10 g: walking RMS ~ 0.3 g, still windows at the 0.02 m/s² noise (~ 3.5 mg over 3 axes)
    assert -0.8 < np.median(col["log_dyn"][walk]) < 0.0 and np.median(col["log_dyn"][21:29]) < -2.0


def test_window_features_is_rotation_invariant_in_leans():
    acc = _day()
    c, s = np.cos(0.7), np.sin(0.7)
    R = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    a, b = window_features(acc, FS), window_features(acc @ R.T, FS)
    for name in ("lean_walk_deg", "posture_margin_deg", "cadence_hz"):
        i = FEATURE_NAMES.index(name)
        np.testing.assert_allclose(a.x[:, i], b.x[:, i], atol=0.2)


def test_helpers():
    assert lean_deg(np.array([[0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]), np.array([0.0, 2.0, 0.0])) == pytest.approx([0.0, 45.0])
    g = gait_windows(np.array([0.7, 0.7, 0.2, 0.7]), np.array([-0.5, -2.0, -0.5, -0.5]), np.array([1.9, 1.9, 1.9, 3.0]))
    assert g.tolist() == [True, False, False, False]
    x = np.arange(10.0)[:, None]
    xc, names = add_context(x, ("f",), (1,))
    assert names == ("f", "f@±1") and xc.shape == (10, 2)
    assert xc[0, 1] == pytest.approx(0.5) and xc[5, 1] == pytest.approx(5.0) and xc[9, 1] == pytest.approx(8.5)
    up, other = posture_clusters(np.zeros((2, 3)) + [0, 1, 0], np.array([True, True]), np.array([0.0, 1.0, 0.0]))
    np.testing.assert_allclose(up, other)                                       # too few still windows


def test_input_checks():
    with pytest.raises(ValueError):
        window_features(np.zeros((100, 3)), FS)                                 # shorter than one window
    with pytest.raises(ValueError):
        window_features(np.full((1000, 3), np.nan), FS)
    with pytest.raises(ValueError):
        window_features(np.zeros((1000, 2)), FS)


@pytest.mark.realdata
def test_learned_loso_on_two_uci_participants():
    from stridelab.validation.bench.activity import LEARNED, learned_loso
    from stridelab.pipeline.formats.uci_chest import load_uci_participant
    d = shared_data("uci_chest")
    parts = [load_uci_participant(d / "1.csv"), load_uci_participant(d / "2.csv")]
    out = learned_loso(parts)
    assert {"accuracy", "balanced_accuracy", "confusion", "per_participant", "development", "held_out",
            "protocol", "hyper_parameters"} <= set(out)
    assert set(out["per_participant"]) == {"1", "2"} and out["hyper_parameters"] == LEARNED
    assert out["per_participant"]["1"]["trained_on"] == ["2"] and out["per_participant"]["2"]["trained_on"] == ["1"]
    assert np.array(out["confusion"]).shape == (4, 4) and 0.0 <= out["balanced_accuracy"] <= 1.0
    assert out["windows"] == sum(v["windows"] for v in out["per_participant"].values())


def test_moving_fraction_separates_still_from_walking_seconds():
    from stridelab.estimators.activity.windows import moving_fraction
    acc = np.vstack([_still(3.0, 100, 4), _walk(100), _still(3.0, 5, 5), _walk(5), _still(3.0, 90, 6)])
    mf = moving_fraction(acc, FS, 10.0, gait_level_g=0.25)
    assert mf.shape == (acc.shape[0] // 520,)
    np.testing.assert_array_equal(mf[:10], 0.0)                      # still: a few mg against 0.05 g
    assert (mf[11:19] == 1.0).all()                                  # walking moves in every second
    assert 0.3 <= mf[20] <= 0.7                                      # half still, half walking
    np.testing.assert_array_equal(mf[-8:], 0.0)


def test_label_consistency_counts_windows_the_signal_contradicts():
    """Walking labelled over a still stretch and standing labelled over walking are counted; the ceiling is the
    mean consistent fraction per class, not a fitted figure."""
    from stridelab.validation.bench.activity import label_consistency
    from stridelab.pipeline.formats.uci_chest import UciParticipant
    acc = np.vstack([_still(20.0, 200, 1), _still(3.0, 100, 2), _walk(200), _still(3.0, 100, 3)])
    lab = np.concatenate([np.full(200 * 52, 1), np.full(100 * 52, 3), np.full(200 * 52, 4), np.full(100 * 52, 3)])
    lab[300 * 52:350 * 52] = 3           # the first 50 s of walking labelled standing (5 windows)
    lab[250 * 52:300 * 52] = 4           # 50 s of standing labelled walking (5 windows)
    u = UciParticipant(participant="9", acc=acc, counts=acc, labels=lab, counts_per_g=1.0)
    out = label_consistency([u])
    assert out["windows"] == [20, 5 + 5 + 10, 5 + 15, 0]
    assert out["contradicted"] == [0, 5, 5, 0]
    assert out["ceiling_balanced_accuracy"] == pytest.approx((1.0 + 15 / 20 + 15 / 20) / 3)
    assert out["per_participant"]["9"]["contradicted"] == [0, 5, 5, 0] and "held_out" in out


def test_window_confusion_of_consecutive_slices_adds_up_to_the_whole():
    import numpy as np
    import pytest
    from stridelab.estimators.activity.evaluation import window_confusion, window_samples
    rng = np.random.default_rng(3)
    fs, n = 50.0, 400_000
    second_class = rng.integers(0, 7, size=int(n / fs) + 1)
    labels = np.repeat(rng.integers(-1, 4, size=n // 2100 + 1), 2100)[:n]     # label runs of 42 s
    code_to_class = {0: 0, 1: 1, 2: 2, 3: 3}
    whole = window_confusion(second_class, labels, fs, code_to_class)
    w = window_samples(fs)
    step = 37 * w
    parts = sum(window_confusion(second_class, labels[a:a + step], fs, code_to_class, first_sample=a)
                for a in range(0, n, step))
    assert whole.sum() > 100 and np.array_equal(parts, whole)
    with pytest.raises(ValueError, match="multiple"):
        window_confusion(second_class, labels[1:], fs, code_to_class, first_sample=1)


def _literal_window_confusion(second_class, labels, fs, code_to_class, first_sample=0):
    """The scorer's definition written window by window (as it was before the numba kernel)."""
    from stridelab.estimators.activity.evaluation import CLASS_MAP, window_samples
    n, w = labels.shape[0], window_samples(fs)
    sec = np.minimum((np.arange(first_sample, first_sample + n) / fs).astype(np.int64), second_class.shape[0] - 1)
    C = np.zeros((4, 4), dtype=np.int64)
    for i in range(0, n - w + 1, w):
        lab = labels[i:i + w]
        if (lab != lab[0]).any() or int(lab[0]) not in code_to_class:
            continue
        C[code_to_class[int(lab[0])], np.bincount(CLASS_MAP[second_class[sec[i:i + w]]], minlength=4).argmax()] += 1
    return C


def test_window_confusion_equals_its_window_by_window_definition():
    """Label runs starting and ending inside windows, unscored codes, a partial last window, seconds past the
    prediction's end, ties in the vote (constant-class runs of 5 s over 10-s windows), slices."""
    from stridelab.estimators.activity.evaluation import window_confusion, window_samples
    rng = np.random.default_rng(0)
    for t in range(200):
        fs = float(rng.choice([20.0, 26.0, 50.0, 100.0, 12.5]))
        n = int(rng.integers(0, 20000))
        n_sec = max(1, int(n / fs) + int(rng.integers(-3, 3)) + 1)
        second_class = (np.repeat(rng.integers(0, 7, n_sec // 5 + 1), 5)[:n_sec] if t % 3 == 0
                        else rng.integers(0, 7, n_sec))
        labels = np.full(n, -1, np.int64)
        for i, c in enumerate(np.sort(rng.integers(0, max(n, 1), 4))):
            labels[c:c + int(rng.integers(0, 5000))] = i
        code_to_class = {i: int(rng.integers(0, 4)) for i in range(4) if rng.random() < 0.8}
        first = int(rng.integers(0, 3)) * window_samples(fs)
        assert np.array_equal(window_confusion(second_class, labels, fs, code_to_class, first_sample=first),
                              _literal_window_confusion(second_class, labels, fs, code_to_class, first))


def test_periodogram_and_regularity_match_their_reference_definitions():
    """The band powers and peak frequency of the fast periodogram equal those of scipy.signal.periodogram (both
    detrends, even and odd nfft) and the regularity kernel equals the direct normalised autocorrelation,
    including out-of-range lags."""
    from scipy import signal as sg
    from stridelab.estimators.activity.windows import _acf_at, _band_spectrum
    rng = np.random.default_rng(3)
    v = rng.standard_normal((40, 260)) + np.linspace(0, 2, 260) + np.sin(2 * np.pi * 1.7 * np.arange(260) / 26.0)
    bands = [(0.1, 0.5), (0.5, 1.4), (1.4, 2.4), (2.4, 6.0), (0.3, 6.0), (0.0, 13.1)]
    for nfft in (512, 515):
        for det in ("constant", "linear"):
            f0, p0 = sg.periodogram(v, fs=26.0, nfft=nfft, axis=1, detrend=det)
            want = np.column_stack([p0[:, (f0 >= lo) & (f0 < hi)].sum(axis=1) for lo, hi in bands])
            sel = (f0 >= 0.5) & (f0 <= 3.5)
            got, peak = _band_spectrum(v, 26.0, nfft, det, bands, peak=(0.5, 3.5))
            np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-14 * p0.max())
            np.testing.assert_allclose(peak, f0[sel][np.argmax(p0[:, sel], axis=1)], rtol=1e-12)
    lag = rng.integers(-2, 265, size=40)
    ref = np.zeros(40)
    for i, k in enumerate(lag):
        x = v[i] - v[i].mean()
        if 0 < k < 260:
            ref[i] = (x[:-k] * x[k:]).sum() / (x * x).sum()
    np.testing.assert_allclose(_acf_at(v, lag), ref, rtol=1e-10, atol=1e-12)
