"""Particle-swarm gain tuning (Nazarahari 2021 ch. 4, spec/thesis_orientation.md §4.8, §8 A13, §9.4 P3).

The whole swarm is scored in one call: :func:`swarm_errors` runs every (particle, trial) pair in one
numba ``prange`` loop over the very kernel the public filters use (so a tuned score equals what
``madgwick(...)`` / ``mahony(...)`` give for the decoded params), and returns the (particles, trials)
RMSE matrix (total error ``2·acos|w|`` of ``q_est ⊗ q_ref*``, RMS over the trial's mask — the BROAD metric).
The cost of a particle is the mean over the training trials (A13).

PSO: standard inertia-weight swarm with the thesis settings (population 50, 50 iterations, inertia 0.73
damped by 0.99 per iteration, c1 = c2 = 1.5), velocity clamped to ``v_max_frac`` of the range, positions
clipped to the bounds. Positive gains are searched in log10, thresholds linearly (A13).

Switching spaces (thesis Table 5): FOG = one gain (+ ζ or k_i); VST1 = two gain levels, S_A, S_M (+ ζ / k_i);
VST2 = three levels with nested thresholds. Thresholds are sorted per particle (the optimiser may pick
either ordering of the gain levels, as in the thesis).

Use :func:`tune_pso` for one optimisation on chosen trials and :func:`pso_leave_trials_out` for the honest
held-out error (trial k in fold k mod n_folds, same split as :mod:`.tuning`).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
from numba import njit, prange

from stridelab.estimators.orientation._fullstate_kernel import ekf_series
from stridelab.estimators.orientation._madgwick_mahony import (MadgwickParams, MahonyParams, _series,
                                                     initial_state)

__all__ = ["PSOResult", "pso_minimize", "SwitchingSpace", "SwarmData", "swarm_errors", "TuneResult", "tune_pso",
           "pso_leave_trials_out", "EKF_SPACE", "EKFSwarmData", "ekf_bounds", "ekf_decode", "ekf_encode",
           "ekf_swarm_errors", "tune_ekf_pso"]


# ------------------------------------------------------------------------------------------ generic PSO

@dataclass(frozen=True)
class PSOResult:
    """x: best position (D,); cost: its cost; history: best cost after each iteration; n_evaluations."""
    x: np.ndarray
    cost: float
    history: np.ndarray
    n_evaluations: int


def pso_minimize(cost: Callable[[np.ndarray], np.ndarray], lower, upper, *, n_particles: int = 50,
                 n_iter: int = 50, inertia: float = 0.73, damping: float = 0.99, c1: float = 1.5, c2: float = 1.5,
                 v_max_frac: float = 0.2, seed: int = 0, init: np.ndarray | None = None) -> PSOResult:
    """Minimise ``cost(X (P, D)) -> (P,)`` over the box [lower, upper] (thesis §4.8 settings by default).

    ``init`` (k, D) seeds the first k particles (earlier optima, thesis "rounds"); the rest are uniform.
    """
    lo = np.asarray(lower, dtype=float)
    hi = np.asarray(upper, dtype=float)
    if lo.shape != hi.shape or lo.ndim != 1 or np.any(hi <= lo):
        raise ValueError(f"lower/upper must be (D,) with upper > lower; got {lo} and {hi}")
    if n_particles < 2 or n_iter < 1:
        raise ValueError(f"need n_particles ≥ 2 and n_iter ≥ 1, got {n_particles}, {n_iter}")
    rng = np.random.default_rng(seed)
    d = lo.size
    x = lo + rng.random((n_particles, d)) * (hi - lo)
    if init is not None:
        init = np.atleast_2d(np.asarray(init, dtype=float))[:n_particles]
        x[:len(init)] = np.clip(init, lo, hi)
    vmax = v_max_frac * (hi - lo)
    v = (rng.random((n_particles, d)) * 2 - 1) * vmax
    f = np.asarray(cost(x), dtype=float)
    f = np.where(np.isfinite(f), f, np.inf)
    pbest, pcost = x.copy(), f.copy()
    g = int(np.argmin(pcost))
    gbest, gcost = pbest[g].copy(), float(pcost[g])
    hist = [gcost]
    w = inertia
    for _ in range(n_iter - 1):
        r1 = rng.random((n_particles, d))
        r2 = rng.random((n_particles, d))
        v = np.clip(w * v + c1 * r1 * (pbest - x) + c2 * r2 * (gbest - x), -vmax, vmax)
        x = np.clip(x + v, lo, hi)
        f = np.asarray(cost(x), dtype=float)
        f = np.where(np.isfinite(f), f, np.inf)
        better = f < pcost
        pbest[better], pcost[better] = x[better], f[better]
        g = int(np.argmin(pcost))
        if pcost[g] < gcost:
            gbest, gcost = pbest[g].copy(), float(pcost[g])
        hist.append(gcost)
        w *= damping
    return PSOResult(gbest, gcost, np.array(hist), n_particles * n_iter)


# ------------------------------------------------------------------------------------------ swarm scoring

@dataclass(frozen=True)
class SwarmData:
    """Trials concatenated for the swarm kernel (build with :meth:`from_trials`)."""
    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray
    quat_ref: np.ndarray
    mask: np.ndarray
    offsets: np.ndarray
    states0: np.ndarray
    dts: np.ndarray
    names: tuple[str, ...]

    @classmethod
    def from_trials(cls, trials: Sequence, *, static_bias: bool = True, init_s: float = 0.5) -> "SwarmData":
        """trials need ``gyr, acc, mag, quat_ref, movement, sampling_rate_hz`` (e.g. BROAD trials)."""
        if not trials:
            raise ValueError("need at least one trial")
        lens = [len(t.gyr) for t in trials]
        st = np.stack([initial_state(np.asarray(t.gyr, float), np.asarray(t.acc, float), np.asarray(t.mag, float),
                                     t.sampling_rate_hz, init_s, static_bias) for t in trials])
        cat = lambda k: np.ascontiguousarray(np.concatenate([np.asarray(getattr(t, k), float) for t in trials]))
        return cls(cat("gyr"), cat("acc"), cat("mag"), cat("quat_ref"),
                   np.ascontiguousarray(np.concatenate([np.asarray(t.movement, bool) for t in trials])),
                   np.concatenate([[0], np.cumsum(lens)]).astype(np.int64), st,
                   np.array([1.0 / t.sampling_rate_hz for t in trials]),
                   tuple(getattr(t, "name", str(i)) for i, t in enumerate(trials)))


@njit(cache=True)
def _masked_rmse_deg(q, qref, mask, a):
    """Total orientation RMSE (deg) of the estimate ``q`` (n, 4) against ``qref[a:a + n]`` over the samples
    where ``mask`` is set and the reference is finite (the BROAD metric of ``evaluation``); NaN if none."""
    ss = 0.0
    cnt = 0
    for i in range(q.shape[0]):
        if mask[a + i]:
            r0, r1, r2, r3 = qref[a + i, 0], qref[a + i, 1], qref[a + i, 2], qref[a + i, 3]
            if r0 == r0 and r1 == r1 and r2 == r2 and r3 == r3:
                w = abs(q[i, 0] * r0 + q[i, 1] * r1 + q[i, 2] * r2 + q[i, 3] * r3)
                w = w / np.sqrt(r0 * r0 + r1 * r1 + r2 * r2 + r3 * r3)
                e = 2.0 * np.arccos(min(w, 1.0))
                ss += e * e
                cnt += 1
    return np.degrees(np.sqrt(ss / cnt)) if cnt > 0 else np.nan


@njit(parallel=True, cache=True)
def _swarm_kernel(gyr, acc, mag, qref, mask, offsets, states0, dts, tsel, gains, thr, thr_m, ki, zeta, mahony,
                  out):
    n_p = gains.shape[0]
    n_t = tsel.shape[0]
    for job in prange(n_p * n_t):
        p = job // n_t
        j = job % n_t
        t = tsel[j]
        a, b = offsets[t], offsets[t + 1]
        n = b - a
        s = states0[t].copy()
        q = np.empty((n, 4))
        g = np.empty(n)
        _series(gyr[a:b], acc[a:b], mag[a:b], True, dts[t], gains[p], thr[p], thr_m[p], ki[p], zeta[p], mahony,
                s, q, g)
        out[p, j] = _masked_rmse_deg(q, qref, mask, a)


@dataclass(frozen=True)
class SwitchingSpace:
    """Search space of Madgwick (``filter="madgwick"``: β levels, ζ) or Mahony (k_p levels, k_i) gains with
    ``n_levels`` switching levels (1 = FOG, 2 = VST1, 3 = VST2) on Δ_A and Δ_M (``mag_switch``).

    Bounds: log10 β ∈ [−4, 0] rad/s, log10 k_p ∈ [−3, 1.3] 1/s, thresholds S_A ∈ [0.002, 0.5] g,
    S_M ∈ [0.002, 0.5] (fraction of the field norm), log10 ζ ∈ [−6, −1] rad/s, log10 k_i ∈ [−6, −1] 1/s².
    """
    filter: str = "madgwick"
    n_levels: int = 2
    mag_switch: bool = True
    bias_gain: bool = True

    def __post_init__(self):
        if self.filter not in ("madgwick", "mahony") or self.n_levels < 1:
            raise ValueError(f"filter must be 'madgwick' or 'mahony' and n_levels ≥ 1; got {self.filter}, "
                             f"{self.n_levels}")

    @property
    def names(self) -> tuple[str, ...]:
        g = "log10_beta" if self.filter == "madgwick" else "log10_kp"
        out = [f"{g}{k + 1}" for k in range(self.n_levels)]
        out += [f"s_acc{k + 1}" for k in range(self.n_levels - 1)]
        if self.mag_switch:
            out += [f"s_mag{k + 1}" for k in range(self.n_levels - 1)]
        if self.bias_gain:
            out.append("log10_zeta" if self.filter == "madgwick" else "log10_ki")
        return tuple(out)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        glo, ghi = (-4.0, 0.0) if self.filter == "madgwick" else (-3.0, 1.3)
        lo, hi = [glo] * self.n_levels, [ghi] * self.n_levels
        nt = (self.n_levels - 1) * (2 if self.mag_switch else 1)
        lo += [0.002] * nt
        hi += [0.5] * nt
        if self.bias_gain:
            lo.append(-6.0)
            hi.append(-1.0)
        return np.array(lo), np.array(hi)

    def decode(self, X: np.ndarray):
        """(P, D) positions -> (gains (P, L), s_acc (P, L−1), s_mag (P, L−1 or 0), ki (P,), zeta (P,))."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        L = self.n_levels
        gains = 10.0 ** X[:, :L]
        c = L
        thr = np.sort(X[:, c:c + L - 1], axis=1)
        thr += np.arange(L - 1) * 1e-9                       # strictly increasing
        c += L - 1
        if self.mag_switch and L > 1:
            thr_m = np.sort(X[:, c:c + L - 1], axis=1) + np.arange(L - 1) * 1e-9
            c += L - 1
        else:
            thr_m = np.zeros((X.shape[0], 0))
        bias = 10.0 ** X[:, c] if self.bias_gain else np.zeros(X.shape[0])
        zero = np.zeros(X.shape[0])
        ki, zeta = (zero, bias) if self.filter == "madgwick" else (bias, zero)
        return (np.ascontiguousarray(gains), np.ascontiguousarray(thr), np.ascontiguousarray(thr_m),
                np.ascontiguousarray(ki), np.ascontiguousarray(zeta))

    def to_params(self, x: np.ndarray, *, static_bias: bool = True, init_s: float = 0.5):
        """Decoded :class:`MadgwickParams` / :class:`MahonyParams` of one position (rounded to 4 significant
        digits, the shipped precision)."""
        gains, thr, thr_m, ki, zeta = self.decode(x)
        r = lambda v: tuple(float(f"{u:.4g}") for u in v)
        if self.filter == "madgwick":
            return MadgwickParams(beta_levels_rad_s=r(gains[0]), s_acc_g=r(thr[0]), s_mag=r(thr_m[0]),
                                  zeta_rad_s=r(zeta)[0], static_bias=static_bias, init_s=init_s)
        return MahonyParams(kp_levels_per_s=r(gains[0]), ki_per_s2=r(ki)[0], s_acc_g=r(thr[0]), s_mag=r(thr_m[0]),
                            static_bias=static_bias, init_s=init_s)


def swarm_errors(space: SwitchingSpace, X: np.ndarray, data: SwarmData, trials: Sequence[int] | None = None
                 ) -> np.ndarray:
    """(P, T) total RMSE (degrees) of every particle on every selected trial, in one parallel numba call."""
    gains, thr, thr_m, ki, zeta = space.decode(X)
    tsel = np.arange(len(data.names)) if trials is None else np.asarray(trials, dtype=np.int64)
    out = np.empty((gains.shape[0], len(tsel)))
    _swarm_kernel(data.gyr, data.acc, data.mag, data.quat_ref, data.mask, data.offsets, data.states0, data.dts,
                  tsel, gains, thr, thr_m, ki, zeta, space.filter == "mahony", out)
    return out


# ------------------------------------------------------------------------------------------ tuning + CV

@dataclass(frozen=True)
class TuneResult:
    """params: decoded best params; train_cost_deg: mean total RMSE on the training trials; x: position;
    seconds: wall time; n_evaluations: particle evaluations (each on every training trial)."""
    params: object
    x: np.ndarray
    train_cost_deg: float
    history: np.ndarray
    seconds: float
    n_evaluations: int


def tune_pso(space: SwitchingSpace, data: SwarmData, train: Sequence[int] | None = None, *, n_particles: int = 50,
             n_iter: int = 50, seed: int = 0, init=None, static_bias: bool = True) -> TuneResult:
    """One PSO run on the ``train`` trials (default: all)."""
    tr = np.arange(len(data.names)) if train is None else np.asarray(train, dtype=np.int64)
    lo, hi = space.bounds()
    t0 = time.perf_counter()
    res = pso_minimize(lambda X: swarm_errors(space, X, data, tr).mean(axis=1), lo, hi, n_particles=n_particles,
                       n_iter=n_iter, seed=seed, init=init)
    return TuneResult(space.to_params(res.x, static_bias=static_bias), res.x, res.cost, res.history,
                      time.perf_counter() - t0, res.n_evaluations)


def pso_leave_trials_out(space: SwitchingSpace, data: SwarmData, *, n_folds: int = 3,
                         folds: Sequence[Sequence[int]] | None = None, **kw) -> dict:
    """Cross-validation of :func:`tune_pso`: ``folds`` (lists of trial indices held out together, e.g. one per
    BROAD group for leave-one-group-out), default trial k in fold k mod n_folds. Returns a dict with the
    held-out error per trial (``heldout_deg``, trial order), ``cv_heldout_mean_deg``, per-fold params."""
    n = len(data.names)
    if folds is None:
        if n < n_folds:
            raise ValueError(f"need at least n_folds={n_folds} trials, got {n}")
        folds = [np.arange(k, n, n_folds) for k in range(n_folds)]
    held = np.full(n, np.nan)
    out = []
    for f in folds:
        test = np.asarray(f, dtype=np.int64)
        train = np.setdiff1d(np.arange(n), test)
        r = tune_pso(space, data, train, **kw)
        x = np.asarray(r.x)[None]
        held[test] = swarm_errors(space, x, data, test)[0]
        out.append({"test_trials": [data.names[i] for i in test], "train_cost_deg": r.train_cost_deg,
                    "x": [float(v) for v in r.x], "params": _asdict(r.params), "seconds": r.seconds})
    return {"heldout_deg": held, "cv_heldout_mean_deg": float(np.nanmean(held)), "folds": out}


def _asdict(p):
    import dataclasses
    return dataclasses.asdict(p)


# ------------------------------------------------------------------------------------------ full-state EKF

#: decision variables of the robust EKF (thesis Table 10 minus P0, which the thesis also keeps fixed):
#: (name, lower, upper, log10?)
EKF_SPACE = (("sigma_gyr1", -4.0, 0.0, True), ("sigma_gyr2", -4.0, 0.0, True), ("s_gyr", 0.05, 5.0, False),
             ("sigma_acc1", -3.0, 1.0, True), ("sigma_acc2", -3.0, 1.0, True), ("s_acc", 0.005, 0.5, False),
             ("sigma_mag1", -2.0, 1.5, True), ("sigma_mag2", -2.0, 1.5, True), ("s_mag", 0.005, 0.5, False),
             ("tau_ext_acc", -2.5, 0.5, True), ("tau_mag_dist", -1.0, 2.0, True), ("sigma_ext_acc", -3.0, 1.0, True),
             ("sigma_bias", -7.0, -2.0, True), ("sigma_mag_dist", -4.0, 0.0, True), ("gamma", 0.7, 3.0, True))


def ekf_bounds() -> tuple[np.ndarray, np.ndarray]:
    return np.array([b[1] for b in EKF_SPACE]), np.array([b[2] for b in EKF_SPACE])


def ekf_decode(x: np.ndarray):
    """One position -> :class:`RobustEKFParams` (4 significant digits)."""
    from stridelab.estimators.orientation._fullstate import RobustEKFParams
    v = [float(f"{(10.0 ** u if b[3] else u):.4g}") for u, b in zip(np.asarray(x, float), EKF_SPACE)]
    return RobustEKFParams(sigma_gyr_rad_s=(v[0], v[1]), s_gyr_rad_s=(v[2],), sigma_acc_g=(v[3], v[4]),
                           s_acc_g=(v[5],), sigma_mag=(v[6], v[7]), s_mag=(v[8],), tau_ext_acc_s=v[9],
                           tau_mag_dist_s=v[10], sigma_ext_acc_g=v[11], sigma_bias_rad_s=v[12], sigma_mag_dist=v[13],
                           gamma=v[14])


@dataclass(frozen=True)
class EKFSwarmData:
    """Trials prepared for :func:`ekf_swarm_errors`: acc / mag normalised by each trial's initial-window norms,
    initial kernel states (q from FQA, static bias, P0 = p0·I) and earth-field references per trial."""
    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray
    quat_ref: np.ndarray
    mask: np.ndarray
    offsets: np.ndarray
    states0: np.ndarray
    mrefs: np.ndarray
    dts: np.ndarray
    names: tuple[str, ...]

    @classmethod
    def from_trials(cls, trials: Sequence, *, p0: float = 1e-3) -> "EKFSwarmData":
        from stridelab.estimators.orientation._fullstate import STATE_LEN as KS, RobustEKFFilter, RobustEKFParams
        st, mr, accs, mags = [], [], [], []
        for t in trials:
            f = RobustEKFFilter(RobustEKFParams(p0=p0), sampling_rate_hz=t.sampling_rate_hz)
            f._initialise(np.asarray(t.gyr, float), np.asarray(t.acc, float), np.asarray(t.mag, float))
            s = f.state
            st.append(s[:KS])
            mr.append(s[KS + 3:KS + 6])
            accs.append(np.asarray(t.acc, float) / s[KS + 1])
            mags.append(np.asarray(t.mag, float) / s[KS + 2])
        lens = [len(t.gyr) for t in trials]
        cat = lambda k: np.ascontiguousarray(np.concatenate([np.asarray(getattr(t, k), float) for t in trials]))
        return cls(cat("gyr"), np.ascontiguousarray(np.concatenate(accs)), np.ascontiguousarray(np.concatenate(mags)),
                   cat("quat_ref"),
                   np.ascontiguousarray(np.concatenate([np.asarray(t.movement, bool) for t in trials])),
                   np.concatenate([[0], np.cumsum(lens)]).astype(np.int64), np.stack(st), np.stack(mr),
                   np.array([1.0 / t.sampling_rate_hz for t in trials]),
                   tuple(getattr(t, "name", str(i)) for i, t in enumerate(trials)))


@njit(parallel=True, cache=True)
def _ekf_swarm_kernel(gyr, acc, mag, qref, mask, offsets, states0, mrefs, dts, tsel, V, out):
    n_p = V.shape[0]
    n_t = tsel.shape[0]
    for job in prange(n_p * n_t):
        p = job // n_t
        j = job % n_t
        t = tsel[j]
        a, b = offsets[t], offsets[t + 1]
        n = b - a
        dt = dts[t]
        v = V[p]
        coef = np.array([np.exp(-dt / v[9]), np.exp(-dt / v[10]), v[11] * v[11] * dt, v[12] * v[12] * dt,
                         v[13] * v[13] * dt, 1.0 / (v[14] * v[14])])
        s = states0[t].copy()
        q = np.empty((n, 4))
        aux = np.empty((n, 9))
        lv = np.empty((n, 3), dtype=np.int8)
        ekf_series(gyr[a:b], acc[a:b], mag[a:b], True, dt, coef, np.array([v[0], v[1]]), np.array([v[2]]),
                   np.array([v[3], v[4]]), np.array([v[5]]), np.array([v[6], v[7]]), np.array([v[8]]), mrefs[t], s,
                   q, aux, lv)
        out[p, j] = _masked_rmse_deg(q, qref, mask, a)


def ekf_swarm_errors(X: np.ndarray, data: EKFSwarmData, trials: Sequence[int] | None = None) -> np.ndarray:
    """(P, T) total RMSE (degrees) of the robust EKF for every particle (rows of X in :data:`EKF_SPACE`)."""
    X = np.atleast_2d(np.asarray(X, dtype=float))
    V = np.empty_like(X)
    for k, b in enumerate(EKF_SPACE):
        V[:, k] = 10.0 ** X[:, k] if b[3] else X[:, k]
    # the decoded params are rounded to 4 significant digits, as shipped
    V = np.array([[float(f"{u:.4g}") for u in row] for row in V])
    tsel = np.arange(len(data.names)) if trials is None else np.asarray(trials, dtype=np.int64)
    out = np.empty((X.shape[0], len(tsel)))
    _ekf_swarm_kernel(data.gyr, data.acc, data.mag, data.quat_ref, data.mask, data.offsets, data.states0,
                      data.mrefs, data.dts, tsel, np.ascontiguousarray(V), out)
    return out


def ekf_encode(params) -> np.ndarray:
    """:class:`RobustEKFParams` (2-level switches) -> position in :data:`EKF_SPACE` (to seed a swarm)."""
    p = params
    vals = [*p.sigma_gyr_rad_s, *p.s_gyr_rad_s, *p.sigma_acc_g, *p.s_acc_g, *p.sigma_mag, *p.s_mag, p.tau_ext_acc_s,
            p.tau_mag_dist_s, p.sigma_ext_acc_g, p.sigma_bias_rad_s, p.sigma_mag_dist, p.gamma]
    if len(vals) != len(EKF_SPACE):
        raise ValueError("ekf_encode needs 2-level switches (one threshold each)")
    return np.array([np.log10(v) if b[3] else v for v, b in zip(vals, EKF_SPACE)])


def tune_ekf_pso(data: EKFSwarmData, train: Sequence[int] | None = None, *, n_particles: int = 16, n_iter: int = 10,
                 seed: int = 0, init=None) -> TuneResult:
    """PSO of the robust EKF's 15 gains on the ``train`` trials (default: all)."""
    tr = np.arange(len(data.names)) if train is None else np.asarray(train, dtype=np.int64)
    lo, hi = ekf_bounds()
    t0 = time.perf_counter()
    res = pso_minimize(lambda X: ekf_swarm_errors(X, data, tr).mean(axis=1), lo, hi, n_particles=n_particles,
                       n_iter=n_iter, seed=seed, init=init)
    return TuneResult(ekf_decode(res.x), res.x, res.cost, res.history, time.perf_counter() - t0, res.n_evaluations)
