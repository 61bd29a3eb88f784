"""The window-feature kernels (estimators/activity/_window_kernels.py) give exactly what the NumPy expressions they
replace in ``windows.window_features`` give, bit for bit, on random data and on a real chest recording."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from stridelab.estimators.activity import _window_kernels as WK
from stridelab.estimators.activity import windows as W
from stridelab.estimators.activity._signals import autocalibrate
from tests.conftest import shared_data

G = 9.80665


def _same(a, b):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape
    assert np.array_equal(a.view(np.uint64), b.view(np.uint64)), f"max |diff| {np.max(np.abs(a - b))}"


def _reference_calibrated(acc: np.ndarray, fs: float):
    """``calibrated_g`` as it was written in NumPy."""
    a = np.asarray(acc, dtype=np.float64) / G
    cal = autocalibrate(a, fs)
    if cal.status == "none":
        return a, cal.status
    return (a - cal.offset_g) * cal.gain, cal.status


def _reference_moments(a: np.ndarray, d: np.ndarray, w: int, fs: float):
    """The window means and mean squares as ``window_features`` computed them in NumPy."""
    A, D = W._windows(a, w), W._windows(d, w)
    mean = A.mean(axis=1)
    u = W._unit(mean)
    vert = np.einsum("wnk,wk->wn", D, u)
    horiz = D - vert[:, :, None] * u[:, None, :]
    nrm = np.linalg.norm(A, axis=2)
    return (mean, vert, (D ** 2).sum(axis=2).mean(axis=1), (horiz ** 2).sum(axis=2).mean(axis=1),
            (vert ** 2).mean(axis=1), ((np.diff(nrm, axis=1) * fs) ** 2).mean(axis=1))


def _reference_bands(v: np.ndarray, fs: float, nfft: int, detrend: str):
    """The periodogram and its band powers and peak as ``window_features`` computed them in NumPy."""
    from scipy import fft as sfft
    X = sfft.rfft(signal.detrend(v, axis=1, type=detrend), n=nfft, axis=1)
    P = X.real ** 2 + X.imag ** 2
    P *= 1.0 / (fs * v.shape[1])
    P[:, 1:(nfft + 1) // 2] *= 2.0
    f = sfft.rfftfreq(nfft, 1.0 / fs)
    bands = [P[:, (f >= lo) & (f < hi)].sum(axis=1) for lo, hi in BANDS]
    sel = (f >= 0.5) & (f <= 3.5)
    return np.column_stack(bands), f[sel][np.argmax(P[:, sel], axis=1)]


BANDS = [(0.5, 1.4), W.GAIT_BAND_HZ, (2.4, 6.0), (0.3, 6.0), (0.1, 0.5)]


def _check_bands(v: np.ndarray, fs: float):
    nfft = max(v.shape[1], int(2 ** np.ceil(np.log2(fs / 0.05))))
    for detrend in ("constant", "linear"):
        want_p, want_peak = _reference_bands(v, fs, nfft, detrend)
        got_p, got_peak = W._band_spectrum(v, fs, nfft, detrend, BANDS, peak=(0.5, 3.5))
        _same(got_p, want_p)
        _same(got_peak, want_peak)


def _check_moments(a: np.ndarray, fs: float, w: int):
    d = signal.sosfiltfilt(signal.butter(2, [0.3, min(20.0, 0.45 * fs)], "bandpass", fs=fs, output="sos"), a, axis=0)
    mean, vert, *ms = _reference_moments(a, d, w, fs)
    _same(WK.window_mean(np.ascontiguousarray(a), w), mean)
    for got, want in zip(WK.window_mean_squares(a, d, vert, W._unit(mean), w, fs), ms):
        _same(got, want)
    _check_bands(vert, fs)


@pytest.mark.parametrize("n", list(range(0, 40)) + [127, 128, 129, 130, 255, 256, 257, 259, 260, 1000, 4099, 100_003])
def test_pairwise_sum_is_numpys(n):
    x = np.random.default_rng(n).normal(size=n + 5) * 10.0 ** np.random.default_rng(n).uniform(-3, 3, n + 5)
    stack, vals = WK.pairwise_scratch()
    if n <= WK.NUMPY_BUFSIZE:
        _same(np.array([0.0 + WK.pairwise_sum(x, 3, n, stack, vals)]), np.array([np.add.reduce(x[3:3 + n])]))
    if n:
        _same(np.array([WK.contiguous_mean(x, 3, n, stack, vals)]), np.array([x[3:3 + n].mean()]))


@pytest.mark.parametrize("w", [1, 7, 26, 260, 1000])
def test_window_moments_on_random_data(w):
    rng = np.random.default_rng(w)
    a = rng.normal(0, 0.3, (w * 37 + 5, 3)) + np.array([0.1, 0.95, -0.2])
    acc = a * G
    got, m, s = WK.scaled_window_mean_std(acc, G, w)
    _same(got, acc / G)
    blk = (acc / G)[: (len(a) // w) * w].reshape(-1, w, 3)
    _same(m, blk.mean(axis=1))
    _same(s, blk.std(axis=1))
    off, gain = np.array([0.01, -0.02, 0.005]), np.array([1.01, 0.99, 1.002])
    c, cm = WK.affine_window_mean(got, off, gain, w)
    _same(c, (got - off) * gain)
    _same(cm, W._windows((got - off) * gain, w).mean(axis=1))
    if w >= 8:
        _check_moments(got, 26.0, w)


def _postures(n_per: int, rng, fs: float, lying: bool) -> np.ndarray:
    """Still periods in several orientations (all six axis directions with ``lying``) and some motion, in m/s²,
    through a slightly wrong gain and offset (so that the sphere fit has something to correct)."""
    dirs = [(0, 1, 0), (0.3, 0.95, 0.05)] + ([(1, 0, 0), (-1, 0, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)] if lying else [])
    parts = []
    for dv in dirs:
        g = np.asarray(dv, float) / np.linalg.norm(dv)
        parts.append(g + rng.normal(0, 0.003, (n_per, 3)))
        t = np.arange(n_per) / fs
        parts.append(g + 0.3 * np.sin(2 * np.pi * 1.8 * t)[:, None] * np.array([0.2, 1.0, 0.1]))
    x = np.vstack(parts)
    return (x * np.array([1.02, 0.98, 1.01]) + np.array([0.02, -0.01, 0.03])) * G


@pytest.mark.parametrize("lying,expect", [(True, "sphere_fit"), (False, "gain_only")])
def test_calibrated_g_as_numpy(lying, expect):
    fs = 26.0
    acc = _postures(int(fs * 600), np.random.default_rng(3), fs, lying)
    a, status = W.calibrated_g(acc, fs)
    ref, ref_status = _reference_calibrated(acc, fs)
    assert status == ref_status == expect
    _same(a, ref)
    w = int(round(10 * fs))
    _, _, mean = W._calibrated_g(acc, fs, w)
    _same(mean, W._windows(ref, w).mean(axis=1))


def test_calibrated_g_without_still_windows_and_short():
    fs = 26.0
    rng = np.random.default_rng(5)
    moving = rng.normal(0, 0.5, (int(fs * 300), 3)) * G
    for acc in (moving, moving[:100]):
        a, status = W.calibrated_g(acc, fs)
        ref, ref_status = _reference_calibrated(acc, fs)
        assert status == ref_status == "none"
        _same(a, ref)


@pytest.mark.realdata
def test_identical_on_a_real_chest_recording():
    """UCI chest participant 1 at the model's rate: calibration and every kernel moment as NumPy's."""
    from stridelab.estimators.activity.window_model import RATE_HZ, WINDOW_S, resample_to_model_rate
    from stridelab.pipeline.formats.uci_chest import load_uci_participant
    p = load_uci_participant(shared_data("uci_chest") / "1.csv")
    acc = resample_to_model_rate(p.acc, p.sampling_rate_hz)
    a, status = W.calibrated_g(acc, RATE_HZ)
    ref, _ = _reference_calibrated(acc, RATE_HZ)
    _same(a, ref)
    _check_moments(a, RATE_HZ, int(round(WINDOW_S * RATE_HZ)))
