"""Gait-cycle normalised joint-angle curves: 0–100 % between consecutive initial contacts."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

N_POINTS = 101


@dataclass(frozen=True)
class CycleCurves:
    """Time-normalised curves of one signal over gait cycles.

    cycles: (C, 101, K) one row per cycle (0, 1, …, 100 % of the cycle); mean / sd: (101, K) over
    cycles (NaN-aware; sd with ddof=1, NaN for one cycle); rom: (C, K) range of motion (max − min)
    per cycle; rom_mean / rom_sd: (K,) over cycles; bounds: (C, 2) the ``[ic_k, ic_{k+1}]`` sample
    indices of each cycle. C = 0 (typed empty arrays) when fewer than two contacts exist.
    """
    cycles: np.ndarray
    mean: np.ndarray
    sd: np.ndarray
    rom: np.ndarray
    rom_mean: np.ndarray
    rom_sd: np.ndarray
    bounds: np.ndarray

    @property
    def n_cycles(self) -> int:
        return int(self.cycles.shape[0])


def normalise_cycles(signal: np.ndarray, ic_idx: np.ndarray, *, min_samples: int = 20,
                     max_samples: int | None = None, n_points: int = N_POINTS) -> CycleCurves:
    """Cut ``signal`` (N, K) or (N,) at consecutive initial contacts and resample each cycle to
    ``n_points`` (linear interpolation on the sample grid). Cycles shorter than ``min_samples`` or
    longer than ``max_samples`` (e.g. a pause between walking bouts) are skipped."""
    x = np.asarray(signal, float)
    if x.ndim == 1:
        x = x[:, None]
    ic = np.sort(np.asarray(ic_idx, dtype=np.int64))
    ic = ic[(ic >= 0) & (ic < x.shape[0])]
    K = x.shape[1]
    pairs = np.column_stack([ic[:-1], ic[1:]]) if ic.size >= 2 else np.empty((0, 2), np.int64)
    d = pairs[:, 1] - pairs[:, 0]
    keep = d >= min_samples
    if max_samples is not None:
        keep &= d <= max_samples
    pairs = pairs[keep]
    C = pairs.shape[0]
    if C == 0:
        e = np.full((n_points, K), np.nan)
        return CycleCurves(np.empty((0, n_points, K)), e, e.copy(), np.empty((0, K)), np.full(K, np.nan),
                           np.full(K, np.nan), pairs)
    frac = np.linspace(0.0, 1.0, n_points)
    pos = pairs[:, :1] + frac[None, :] * (pairs[:, 1:] - pairs[:, :1])      # (C, P) fractional sample index
    i0 = np.minimum(np.floor(pos).astype(np.int64), x.shape[0] - 2)
    w = (pos - i0)[..., None]
    cyc = x[i0] * (1 - w) + x[i0 + 1] * w                                     # (C, P, K)
    return _summarise(cyc, pairs)


def _summarise(cyc: np.ndarray, pairs: np.ndarray) -> CycleCurves:
    C, n_points, K = cyc.shape
    if C == 0:
        e = np.full((n_points, K), np.nan)
        return CycleCurves(np.empty((0, n_points, K)), e, e.copy(), np.empty((0, K)), np.full(K, np.nan),
                           np.full(K, np.nan), np.asarray(pairs, np.int64).reshape(0, 2))
    import warnings
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        mean = np.nanmean(cyc, axis=0)
        sd = np.nanstd(cyc, axis=0, ddof=1) if C > 1 else np.full((n_points, K), np.nan)
        rom = np.nanmax(cyc, axis=1) - np.nanmin(cyc, axis=1)
        rom_sd = np.nanstd(rom, axis=0, ddof=1) if C > 1 else np.full(K, np.nan)
        rom_mean = np.nanmean(rom, axis=0)
    return CycleCurves(cyc, mean, sd, rom, rom_mean, rom_sd, pairs)


def pool_cycles(curves) -> CycleCurves:
    """One :class:`CycleCurves` over the cycles of several (e.g. every walking trial of a session).

    ``bounds`` keeps each cycle's sample indices within its own trial. Empty input or inputs without
    cycles give the typed empty result (K and the number of points from the first input, else 3 and 101).
    """
    curves = list(curves)
    n_points = curves[0].cycles.shape[1] if curves else N_POINTS
    K = curves[0].cycles.shape[2] if curves else 3
    cyc = [c.cycles for c in curves if c.n_cycles]
    if not cyc:
        return _summarise(np.empty((0, n_points, K)), np.empty((0, 2), np.int64))
    return _summarise(np.concatenate(cyc), np.concatenate([c.bounds for c in curves if c.n_cycles]))


def session_gait_curves(angles, ic_by_side: dict, *, sampling_rate_hz: float,
                        max_cycle_s: float = 2.5) -> dict:
    """"<joint>_<side>" -> :class:`CycleCurves` for every joint of ``angles`` (a :class:`JointAngles`)
    cut at that side's initial contacts (``ic_by_side["left"|"right"]`` sample indices)."""
    out = {}
    for key, a in angles.angles_deg.items():
        side = key.rsplit("_", 1)[1]
        ic = ic_by_side.get(side)
        if ic is None:
            continue
        out[key] = normalise_cycles(a, ic, min_samples=int(0.3 * sampling_rate_hz),
                                    max_samples=int(max_cycle_s * sampling_rate_hz))
    return out
