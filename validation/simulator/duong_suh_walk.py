"""Synthetic straight walk with two shoe distance sensors: the closed-loop test of spec B11 (Duong & Suh).

World z up, floor z = 0, walking along world +x. IMU body x points down, body y forward (B11), so
R(body→world) = [[0, 1, 0], [0, 0, −1], [−1, 0, 0]] when the foot is flat. Timing: ``stand_s`` standing, ``n_strides``
strides of ``stance_s`` stance and ``swing_s`` swing (τ), ``end_s`` standing. Swing (s = (t − t_toe-off)/τ):

    v_x = (2L/τ) sin²(πs)  ⇒  x = x_0 + L (s − sin(2πs)/(2π)) ;   z = h_0 + clearance · sin⁴(πs)        (SIM1)
    optional pitch θ(s) = pitch_deg · sin(2πs) about the lateral world axis (0 in B11)                  (SIM2)

IMU: acc = R'(a + g e3) + b_a + n_a, gyr = ω_body + b_g + n_g (derivatives by central differences of the analytic
path, h = 1e-4 s). Distance sensor i: p_i = r + R r_i, beam R n_i, range = −p_i,z / (e3'R n_i), σ = range_noise_m,
every ``range_divider``-th IMU sample, NaN above 0.20 m (VL6180 range) or when the beam is not downward.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._rotations import quat_from_matrix

__all__ = ["DsWalk", "simulate_ds_walk", "SHOE_GEOMETRY_EQ24"]

GRAVITY = 9.81
#: the simulated shoe: lever arms r_A, r_B (m) from the IMU to the two distance sensors and their unit beam
#: directions n_A, n_B, in IMU body coordinates (x toward the floor), rows (r_A, r_B, n_A, n_B). Values: the
#: calibration Duong & Suh 2015 report for their own shoe after a walking trial, eq. (24) (spec B11 takes it as
#: the truth of the closed-loop test), transcribed here from the paper.
SHOE_GEOMETRY_EQ24 = np.array([[-0.0124, 0.0806, 0.0], [-0.0033, -0.0611, -0.0006],
                               [1.0, 0.0001, 0.0], [1.0, 0.0002, -0.0001]])

R_FLAT = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]])


@dataclass(frozen=True)
class DsWalk:
    """gyr, acc (N, 3); ranges (N, 2) (NaN = no reading); pos (N, 3) and rot (N, 3, 3) truth; quat0 (4,) true
    initial attitude; geometry: the true sensor mounting, (4, 3) rows r_A, r_B, n_A, n_B (a filter takes it as
    ``RangeGeometry.from_array``); sampling_rate_hz; stance (N,) bool truth."""
    gyr: np.ndarray
    acc: np.ndarray
    ranges: np.ndarray
    pos: np.ndarray
    rot: np.ndarray
    quat0: np.ndarray
    geometry: np.ndarray
    sampling_rate_hz: float
    stance: np.ndarray


def _path(t, *, stand_s, n_strides, stance_s, swing_s, L, h0, clearance, pitch_rad):
    t = np.asarray(t, float)
    x = np.zeros_like(t)
    z = np.full_like(t, h0)
    th = np.zeros_like(t)
    period = stance_s + swing_s
    for k in range(n_strides):
        to = stand_s + k * period + stance_s             # toe-off
        s = np.clip((t - to) / swing_s, 0.0, 1.0)
        x += L * (s - np.sin(2 * np.pi * s) / (2 * np.pi))
        inside = (t > to) & (t < to + swing_s)
        z += np.where(inside, clearance * np.sin(np.pi * s) ** 4, 0.0)
        th += np.where(inside, pitch_rad * np.sin(2 * np.pi * s), 0.0)
    return np.stack([x, np.zeros_like(t), z], 1), th


def _rot(th):
    """Flat-foot attitude rotated by θ about world y (positive: toes … up for walking along +x)."""
    c, s = np.cos(th), np.sin(th)
    Ry = np.zeros((len(th), 3, 3))
    Ry[:, 0, 0], Ry[:, 0, 2], Ry[:, 1, 1], Ry[:, 2, 0], Ry[:, 2, 2] = c, s, 1.0, -s, c
    return Ry @ R_FLAT


def simulate_ds_walk(seed: int = 0, *, sampling_rate_hz: float = 100.0, stand_s: float = 2.0, n_strides: int = 8,
                     stance_s: float = 0.6, swing_s: float = 0.4, end_s: float = 1.0, stride_length_m: float = 1.2,
                     stance_height_m: float = 0.04, clearance_m: float = 0.12, pitch_deg: float = 0.0,
                     geometry=SHOE_GEOMETRY_EQ24, acc_noise: float = 0.05, gyr_noise: float = 0.01,
                     acc_bias=(0.05, -0.04, 0.03), gyr_bias=(0.004, -0.003, 0.005), range_noise_m: float = 0.003,
                     range_divider: int = 3, max_range_m: float = 0.20) -> DsWalk:
    """The B11 configuration by default (10 seeds in the acceptance test)."""
    rng = np.random.default_rng(seed)
    fs = float(sampling_rate_hz)
    dur = stand_s + n_strides * (stance_s + swing_s) + end_s
    n = int(round(dur * fs))
    t = np.arange(n) / fs
    kw = dict(stand_s=stand_s, n_strides=n_strides, stance_s=stance_s, swing_s=swing_s, L=stride_length_m,
              h0=stance_height_m, clearance=clearance_m, pitch_rad=np.radians(pitch_deg))
    h = 1e-4
    p, th = _path(t, **kw)
    pm, thm = _path(t - h, **kw)
    pp, thp = _path(t + h, **kw)
    a_w = (pp - 2 * p + pm) / h ** 2
    R = _rot(th)
    dth = (thp - thm) / (2 * h)
    w_world = np.stack([np.zeros(n), dth, np.zeros(n)], 1)
    f_w = a_w + np.array([0.0, 0.0, GRAVITY])
    acc = np.einsum("nji,nj->ni", R, f_w) + np.asarray(acc_bias) + rng.normal(0, acc_noise, (n, 3))
    gyr = np.einsum("nji,nj->ni", R, w_world) + np.asarray(gyr_bias) + rng.normal(0, gyr_noise, (n, 3))
    g = np.array(geometry, float).reshape(4, 3)
    ranges = np.full((n, 2), np.nan)
    idx = np.arange(0, n, range_divider)
    for s in range(2):
        pnt = p[idx] + R[idx] @ g[s]
        beam = R[idx] @ (g[2 + s] / np.linalg.norm(g[2 + s]))
        with np.errstate(divide="ignore", invalid="ignore"):
            d = np.where(beam[:, 2] < -0.1, -pnt[:, 2] / beam[:, 2], np.nan)
        d = d + rng.normal(0, range_noise_m, len(idx))
        ranges[idx, s] = np.where((d > max_range_m) | (d <= 0), np.nan, d)
    period = stance_s + swing_s
    stance = np.ones(n, bool)
    for k in range(n_strides):
        to = stand_s + k * period + stance_s
        stance &= ~((t > to) & (t < to + swing_s))
    return DsWalk(gyr, acc, ranges, p, R, quat_from_matrix(R[0]), g, fs, stance)
