"""Small foot-walk simulator after Yun et al. 2012 Table I / eqs. 14–17 (spec A7.2, A7.3), in ENU.

Gait cycle 1 s: pre-swing 0.1 s (pitch rate −7.5 rad/s, toes down), swing 0.4 s (+3.5 rad/s), initial contact 0.1 s
(−6.5 rad/s), foot flat 0.4 s; 2 s standing before, 1 s after. Walking toward magnetic north (ENU +y); body frame
x to the toes, y to the left, z up when flat; pitch θ > 0 = toes up, q = q_z(90°) ⊗ q_y(−θ).
Swing translation, "edge-corrected" (Y7): v_fwd(u) = c (g(u) − g(τ/2)), g(u) = exp(−u²/2σ²), u ∈ [−τ/2, τ/2],
σ = 0.05 s, ∫v = L (1.2 m); height p_z = H (g(u) − g(τ/2)) with H = 0.25 m; zero velocity at the swing edges.
Sensors: f_b = Rᵀ(a + g e_z), ω_b = [0, −θ̇, 0], m_b = Rᵀ B, B = |B|(0, cos β, −sin β); noise per axis
``measurement = true + μ + σ randn`` (eq. 18, Table II σ scaled by ``noise_scale``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import erf

from ._rotations import quat_from_axis_angle, quat_mul, quat_to_matrix

__all__ = ["SimWalk", "simulate_yun_walk"]

TABLE_II_SIGMA = {"acc": 0.033, "gyr": 0.0076, "mag": 0.82e-3}
TABLE_II_BIAS = {"acc": 0.049, "gyr": 7.25e-6, "mag": 1.2e-3}


@dataclass(frozen=True)
class SimWalk:
    """Simulated foot walk: gyr (N,3) rad/s, acc (N,3) m/s², mag (N,3) gauss; truth pos (N,3) m, quat (N,4)
    sensor→ENU, stance (N,) bool (foot flat); ic_idx, tc_idx (S,) truth contact samples; distance_m walked."""
    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray
    pos: np.ndarray
    quat: np.ndarray
    stance: np.ndarray
    ic_idx: np.ndarray
    tc_idx: np.ndarray
    sampling_rate_hz: float
    distance_m: float


def simulate_yun_walk(n_strides: int = 100, *, sampling_rate_hz: float = 50.0, noise_scale: float = 1.0,
                      biases: bool = False, seed: int = 0, stride_m: float = 1.2, height_m: float = 0.25,
                      heading_rate_deg_per_stride: float = 0.0, g: float = 9.81,
                      field_gauss: float = 0.48, dip_deg: float = 61.0) -> SimWalk:
    """Simulate ``n_strides`` gait cycles (module docstring); ``heading_rate_deg_per_stride`` turns the walker
    during each foot-flat (a loop when 360/n per stride)."""
    fs = float(sampling_rate_hz)
    n_cyc = int(round(fs))
    if abs(n_cyc - fs) > 1e-9 or n_cyc % 10:
        raise ValueError(f"sampling_rate_hz must be a multiple of 10 Hz (phase borders on samples), got {fs}")
    T = 1.0 / fs
    sig, tau = 0.05, 0.4
    gedge = np.exp(-tau ** 2 / (8 * sig ** 2))
    c = stride_m / (sig * np.sqrt(2 * np.pi) * erf(tau / (2 * np.sqrt(2) * sig)) - tau * gedge)
    t_total = 2.0 + n_strides * 1.0 + 1.0
    n = int(round(t_total * fs))
    t = np.arange(n) * T
    theta = np.zeros(n)
    dtheta = np.zeros(n)
    yaw = np.zeros(n)
    pos = np.zeros((n, 3))
    accw = np.zeros((n, 3))
    stance = np.ones(n, bool)
    p0 = np.zeros(3)
    heading = np.pi / 2
    ic, tc = [], []
    for i in range(n):
        i_rel = i - int(round(2.0 * fs))                  # integer sample arithmetic: phase borders fall on samples
        tt = i_rel / fs
        if i_rel < 0 or i_rel >= n_strides * n_cyc:
            k_cycle = n_strides if i_rel >= 0 else -1
            cyc = None
        else:
            k_cycle, cyc = i_rel // n_cyc, (i_rel % n_cyc) / fs
        yaw_i = np.pi / 2 + np.radians(heading_rate_deg_per_stride) * max(0, min(k_cycle + (1 if cyc is None and
                                                                                               tt >= 0 else 0),
                                                                               n_strides))
        if cyc is not None:
            base = np.radians(heading_rate_deg_per_stride) * k_cycle + np.pi / 2
            fwd = np.array([np.cos(base), np.sin(base), 0.0])
            start = np.array([0, 0, 0.0])
            # cumulative displacement before this stride (each stride along its own heading)
            for kk in range(k_cycle):
                b = np.radians(heading_rate_deg_per_stride) * kk + np.pi / 2
                start = start + stride_m * np.array([np.cos(b), np.sin(b), 0.0])
            if cyc < 0.1 - 1e-9:                                            # pre-swing
                theta[i], dtheta[i], stance[i] = -7.5 * cyc, -7.5, False
                pos[i] = start
                yaw_i = base
            elif cyc < 0.5 - 1e-9:                                          # swing
                u = cyc - 0.3
                theta[i], dtheta[i], stance[i] = -0.75 + 3.5 * (cyc - 0.1), 3.5, False
                gu = np.exp(-u * u / (2 * sig * sig))
                px = c * (sig * np.sqrt(np.pi / 2) * (erf(u / (np.sqrt(2) * sig)) + erf(tau / (2 * np.sqrt(2) * sig)))
                          - gedge * (u + tau / 2))
                pz = height_m * (gu - gedge)
                pos[i] = start + fwd * px + np.array([0, 0, pz])
                accw[i] = fwd * (c * (-u / sig ** 2) * gu) + np.array([0, 0, height_m * (u * u / sig ** 4 - 1 / sig ** 2)
                                                                      * gu])
                yaw_i = base
            elif cyc < 0.6 - 1e-9:                                          # initial contact
                theta[i], dtheta[i], stance[i] = 0.65 - 6.5 * (cyc - 0.5), -6.5, False
                pos[i] = start + fwd * stride_m
                yaw_i = base
            else:                                                    # foot flat (turns happen here)
                pos[i] = start + fwd * stride_m
                frac = (cyc - 0.6) / 0.4
                yaw_i = base + np.radians(heading_rate_deg_per_stride) * frac
        else:
            if tt >= n_strides:
                pos[i] = sum((stride_m * np.array([np.cos(np.radians(heading_rate_deg_per_stride) * kk + np.pi / 2),
                                                   np.sin(np.radians(heading_rate_deg_per_stride) * kk + np.pi / 2),
                                                   0.0]) for kk in range(n_strides)), np.zeros(3))
                yaw_i = np.pi / 2 + np.radians(heading_rate_deg_per_stride) * n_strides
            else:
                yaw_i = np.pi / 2
        yaw[i] = yaw_i
    # events: TC = start of swing (end of pre-swing), IC = end of swing
    for k in range(n_strides):
        tc.append(int(round((2.0 + k + 0.1) * fs)))
        ic.append(int(round((2.0 + k + 0.5) * fs)))
    dyaw = np.gradient(yaw, T)
    q = quat_mul(quat_from_axis_angle(np.array([0, 0, 1.0]), yaw),
                 quat_from_axis_angle(np.array([0, 1.0, 0]), -theta))
    R = quat_to_matrix(q)
    f_b = np.einsum("nji,nj->ni", R, accw + np.array([0, 0, g]))
    # body rate: pitch about body y (−θ̇) plus yaw rate about world z expressed in body
    w_b = np.zeros((n, 3))
    w_b[:, 1] = -dtheta
    w_b += np.einsum("nji,nj->ni", R, np.column_stack([np.zeros(n), np.zeros(n), dyaw]))
    B = field_gauss * np.array([0.0, np.cos(np.radians(dip_deg)), -np.sin(np.radians(dip_deg))])
    m_b = np.einsum("nji,j->ni", R, B)
    rng = np.random.default_rng(seed)
    out = {}
    for name, x in (("acc", f_b), ("gyr", w_b), ("mag", m_b)):
        x = x + noise_scale * TABLE_II_SIGMA[name] * rng.standard_normal(x.shape)
        if biases:
            x = x + TABLE_II_BIAS[name]
        out[name] = x
    return SimWalk(out["gyr"], out["acc"], out["mag"], pos, q, stance, np.array(ic), np.array(tc), fs,
                   n_strides * stride_m)
