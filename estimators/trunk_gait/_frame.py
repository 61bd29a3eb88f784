"""Which sensor axis is vertical and which is anterior, from the data (placement check included).

Vertical: the mean specific-force direction while walking (Moe-Nilssen 1998, "A new method for evaluating motor
control in gait under real-life environmental conditions. Part 1", Clin Biomech 13:320,
doi:10.1016/S0268-0033(98)00089-8: tilt correction of trunk accelerometry by the mean gravity direction).
Anterior: the horizontal direction whose acceleration co-varies with the rate of change of the vertical
acceleration at the step frequency. Rationale (Zijlstra & Hof 2003, Gait Posture 18:1,
doi:10.1016/S0966-6362(02)00190-X): the trunk moves as an inverted pendulum; its forward speed peaks at double
support, when its vertical acceleration is rising to its peak, so forward acceleration ≈ +k · d(vertical acc)/dt,
whereas medio-lateral acceleration alternates sign from step to step and averages out. This fixes the anterior
axis and its sign in one step; checked on 52 Voisard L5 trials (Xsens: anterior = sensor -z) and the Mobilise-D
lab trials (McRoberts: anterior = sensor +z).
"""
from __future__ import annotations

import numpy as np

from stridelab.estimators.trunk_gait._filters import butter_filtfilt
from stridelab.estimators.trunk_gait._types import TrunkFrame

G = 9.80665
AXES = "xyz"
_BAND_HZ = (0.5, 4.0)


def check_units(acc: np.ndarray, gyr: np.ndarray | None, fs_hz: float) -> None:
    """ValueError with the fix when shapes, rate or units look wrong (P12)."""
    if acc.ndim != 2 or acc.shape[1] != 3:
        raise ValueError(f"acc must be (N, 3) m/s², got shape {acc.shape}")
    if gyr is not None and gyr.shape != acc.shape:
        raise ValueError(f"gyr must have the shape of acc {acc.shape}, got {gyr.shape}")
    if not np.isfinite(fs_hz) or fs_hz <= 0:
        raise ValueError(f"fs_hz must be > 0, got {fs_hz}")
    if len(acc) == 0:
        return
    step = max(1, len(acc) // 20000)
    g = float(np.median(np.linalg.norm(acc[::step], axis=1)))
    if 0.5 < g < 2.0:
        raise ValueError(f"acc median norm is {g:.2f}: looks like g, expected m/s² (multiply by 9.80665)")
    if gyr is not None and np.percentile(np.abs(gyr[::step]), 99) > 35.0:
        raise ValueError("gyr looks like deg/s, expected rad/s (use np.deg2rad)")


def _bandpass(x: np.ndarray, fs_hz: float) -> np.ndarray:
    hi = min(_BAND_HZ[1], 0.45 * fs_hz)
    return butter_filtfilt(2, (_BAND_HZ[0], hi), "bandpass", fs_hz, x, axis=0)


def anterior_evidence(acc: np.ndarray, fs_hz: float, up: np.ndarray) -> tuple[np.ndarray, float, float]:
    """(c (3,), sum dV², sum |H|²) of one walking segment: c = Σ H·dV/dt with H the horizontal and V the
    vertical band-passed acceleration (see module docstring). Segments are summed before normalising."""
    if len(acc) < int(2 * fs_hz):
        return np.zeros(3), 0.0, 0.0
    a = _bandpass(acc, fs_hz)
    v = a @ up
    h = a - np.outer(v, up)
    dv = np.gradient(v) * fs_hz
    return h.T @ dv, float(dv @ dv), float(np.einsum("ij,ij->", h, h))


def frame_from_axes(up: np.ndarray, anterior_hint: np.ndarray) -> np.ndarray:
    """R with rows x (anterior, horizontal part of ``anterior_hint``), y (``up``), z = x × y (right)."""
    y = up / np.linalg.norm(up)
    x = anterior_hint - (anterior_hint @ y) * y
    nx = np.linalg.norm(x)
    if nx < 1e-9:                      # hint parallel to up: take the most horizontal sensor axis
        x = np.eye(3)[int(np.argmin(np.abs(y)))]
        x = x - (x @ y) * y
        nx = np.linalg.norm(x)
    x = x / nx
    return np.vstack([x, y, np.cross(x, y)])


def build_frame(up_sum: np.ndarray, resultant: float, c: np.ndarray, dv2: float, h2: float,
                walking_found: bool, norm_g: float) -> TrunkFrame:
    """Assemble a ``TrunkFrame`` (and its warnings) from accumulated evidence."""
    warnings = []
    y = up_sum / max(np.linalg.norm(up_sum), 1e-12)
    c_h = c - (c @ y) * y
    ant_conf = float(np.linalg.norm(c_h) / np.sqrt(dv2 * h2)) if dv2 > 0 and h2 > 0 else 0.0
    if not walking_found:
        warnings.append("no walking found: the anterior axis is not determined (x is an arbitrary horizontal axis)")
        ant_conf = 0.0
    R = frame_from_axes(y, c_h if np.linalg.norm(c_h) > 0 else np.zeros(3))
    vert_conf = float(np.clip(resultant, 0.0, 1.0))
    if vert_conf < 0.9 or not (0.8 * G < norm_g < 1.2 * G):
        warnings.append(f"vertical axis not found: wrong placement? (gravity direction stability {vert_conf:.2f}, "
                        f"mean |acc| {norm_g:.2f} m/s²; a trunk sensor gives > 0.9 and about 9.8)")
    vax = int(np.argmax(np.abs(y)))
    vsign = int(np.sign(y[vax])) or 1
    if vsign < 0:
        warnings.append(f"sensor looks upside down: its {AXES[vax]} axis points down (the detected frame corrects it)")
    aax = int(np.argmax(np.abs(R[0])))
    asign = int(np.sign(R[0][aax])) or 1
    if walking_found and ant_conf < 0.1:
        warnings.append(f"anterior axis uncertain (confidence {ant_conf:.2f}): forward and backward may be swapped")
    return TrunkFrame(R=R, confidence=float(min(vert_conf, ant_conf)), vertical_axis=vax, vertical_sign=vsign,
                      anterior_axis=aax, anterior_sign=asign, walking_found=walking_found, warnings=tuple(warnings))


def frame_from_sequences(acc: np.ndarray, fs_hz: float, sequences: np.ndarray) -> TrunkFrame:
    """The frame from the samples inside ``sequences`` (G, 2) [start, end) (all samples when G = 0)."""
    walking = len(sequences) > 0
    segs = [(int(s), int(e)) for s, e in sequences] if walking else [(0, len(acc))]
    step = max(1, len(acc) // 200000) if not walking else 1
    up_sum = np.zeros(3)
    dirs = np.zeros(3)
    n = 0
    norm_sum = 0.0
    for s, e in segs:
        a = acc[s:e:step]
        up_sum += a.sum(axis=0)
        nrm = np.linalg.norm(a, axis=1)
        norm_sum += nrm.sum()
        dirs += (a / np.maximum(nrm, 1e-9)[:, None]).sum(axis=0)
        n += len(a)
    if n == 0:
        raise ValueError("acc has no samples: cannot detect the trunk frame")
    y = up_sum / max(np.linalg.norm(up_sum), 1e-12)
    c = np.zeros(3)
    dv2 = h2 = 0.0
    if walking:
        for s, e in segs:
            ci, d, h = anterior_evidence(acc[s:e], fs_hz, y)
            c += ci
            dv2 += d
            h2 += h
    return build_frame(up_sum, float(np.linalg.norm(dirs) / n), c, dv2, h2, walking, norm_sum / n)
