"""Approximate normative sagittal-plane joint angle bands for adult level walking (mean ± SD, degrees).

Knot values read off the typical curves of healthy adults at self-selected speed in Winter, *Biomechanics
and Motor Control of Human Movement* (4th ed., 2009) and Perry & Burnfield, *Gait Analysis* (2010):
hip flexion +, knee flexion +, ankle dorsiflexion +. They are an orientation aid for the dashboard and
reports, **not** a validated reference: a lab should replace them with its own normative data
(same shape: cycle % -> mean, SD).
"""
from __future__ import annotations

import numpy as np

# cycle %: 0 = initial contact, ~60 = toe-off, 100 = next initial contact
_KNOTS = {
    "hip": ([0, 10, 30, 50, 60, 75, 87, 100], [30, 25, 5, -10, -2, 20, 32, 30], 6.0),
    "knee": ([0, 15, 40, 60, 72, 85, 100], [5, 18, 5, 38, 62, 30, 5], 6.0),
    "ankle": ([0, 7, 30, 48, 62, 75, 100], [0, -6, 8, 12, -18, 0, 0], 5.0),
}


def normative_band(joint: str, n: int = 101):
    """(cycle_pct (n,), mean_deg (n,), sd_deg (n,)) for ``hip``, ``knee`` or ``ankle``; None otherwise.

    Only the sagittal plane (flexion/extension, dorsi/plantar flexion) has a band.
    """
    key = next((k for k in _KNOTS if k in joint.lower()), None)
    if key is None:
        return None
    x, y, sd = _KNOTS[key]
    pct = np.linspace(0.0, 100.0, n)
    # periodic smoothing of the piecewise-linear knots: circular moving average over 9 % of the cycle
    lin = np.interp(pct, x, y)
    k = 9
    ext = np.concatenate([lin[-k:-1], lin, lin[1:k]])
    smooth = np.convolve(ext, np.ones(k) / k, mode="same")[k - 1: k - 1 + n]
    return pct, smooth, np.full(n, sd)


def is_sagittal(plane: str | None) -> bool:
    p = (plane or "").lower()
    return p == "" or any(s in p for s in ("sag", "flex", "x", "dorsi"))


#: Orientation bands for the clinical measures (docs/clinical_measures.md, with the references). Each entry:
#: (low, high, what the band means, source); None = open end. Not validated cut-offs for this device.
CLINICAL_BANDS = {
    "gait_speed_m_s": [(None, 0.4, "household walker after stroke", "Perry et al. 1995"),
                       (0.4, 0.8, "limited community walker after stroke", "Perry et al. 1995"),
                       (0.8, None, "community walker after stroke", "Perry et al. 1995")],
    "gait_speed_healthy_m_s": [(1.13, 1.34, "healthy adults 60-79 y, comfortable speed",
                                "Bohannon & Williams Andrews 2011")],
    "swing_time_s_symmetry": [(1.0, 1.06, "healthy range of the swing-time symmetry ratio", "Patterson et al. 2010")],
    "stance_time_s_symmetry": [(1.0, 1.05, "healthy range of the stance-time symmetry ratio", "Patterson et al. 2010")],
    "step_length_m_symmetry": [(1.0, 1.08, "healthy range of the step-length symmetry ratio", "Patterson et al. 2010")],
    "double_support_pct": [(None, 20.0, "about 20 % of the stride in healthy walking", "Perry & Burnfield 2010")],
    "stride_time_cv_pct": [(1.0, 3.0, "healthy adults", "Hausdorff 2005")],
    "steps_per_day": [(None, 5000, "sedentary", "Tudor-Locke & Bassett 2004"),
                      (5000, 7500, "low active", "Tudor-Locke & Bassett 2004"),
                      (7500, 10000, "somewhat active", "Tudor-Locke & Bassett 2004"),
                      (10000, None, "active", "Tudor-Locke & Bassett 2004")],
}


def band_label(key: str, value: float | None) -> str:
    """The band ``value`` falls in ('' when none or no value), e.g. 'limited community walker after stroke'."""
    if value is None or value != value:
        return ""
    for lo, hi, what, _src in CLINICAL_BANDS.get(key, []):
        if (lo is None or value >= lo) and (hi is None or value < hi):
            return what
    return ""


# ---- speed-matched bands (Schwartz et al. 2008; reports/_schwartz2008.py) ------------------------------------
STANDARD_GRAVITY = 9.80665
#: leg length assumed when none is given (m): about the adult mean; the page says when it was assumed
DEFAULT_LEG_LENGTH_M = 0.90


def speed_category_centres() -> dict[str, float]:
    """Dimensionless speed each Schwartz category stands for: the middle of its published range; the open-ended
    very slow and very fast categories are given a range as wide as their neighbour's (0.136), i.e. 0.159 and
    0.704 (our assumption: the paper gives only the inner boundary)."""
    from stridelab.reports._schwartz2008 import RANGES
    width = RANGES["slow"][1] - RANGES["slow"][0]
    out = {}
    for cat, (lo, hi) in RANGES.items():
        lo = hi - width if lo is None else lo
        hi = lo + width if hi is None else hi
        out[cat] = round((lo + hi) / 2.0, 4)
    return out


def dimensionless_speed(speed_m_s: float, leg_length_m: float = DEFAULT_LEG_LENGTH_M) -> float:
    """v̂ = v / sqrt(g L) (Hof 1996; the speed normalisation of Schwartz et al. 2008)."""
    if not leg_length_m > 0:
        raise ValueError(f"leg length must be > 0 m, got {leg_length_m}")
    return float(speed_m_s) / (STANDARD_GRAVITY * float(leg_length_m)) ** 0.5


def speed_matched_band(joint: str, speed_m_s: float, leg_length_m: float = DEFAULT_LEG_LENGTH_M, n: int = 101):
    """(cycle_pct (n,), mean_deg (n,), sd_deg (n,), info) of ``hip``, ``knee`` or ``ankle`` at a walking speed.

    The Schwartz et al. 2008 curves exist at five discrete speeds only: mean and SD are interpolated linearly
    in dimensionless speed between the two categories whose centres (:func:`speed_category_centres`) enclose
    it, and held at the nearest category beyond the outermost centres (``info["clamped"]``). ``info``: v̂, the
    two categories and the weight of the upper one. None for another joint.
    """
    import numpy as np

    from stridelab.reports._schwartz2008 import CATEGORIES, DATA
    key = next((k for k in DATA if k in joint.lower()), None)
    if key is None:
        return None
    v = dimensionless_speed(speed_m_s, leg_length_m)
    centres = speed_category_centres()
    c = np.array([centres[k] for k in CATEGORIES])
    clamped = v < c[0] or v > c[-1]
    vv = float(np.clip(v, c[0], c[-1]))
    i = int(np.clip(np.searchsorted(c, vv, side="right") - 1, 0, len(c) - 2))
    w = (vv - c[i]) / (c[i + 1] - c[i])
    lo, hi = DATA[key][CATEGORIES[i]], DATA[key][CATEGORIES[i + 1]]
    mean51 = (1 - w) * np.asarray(lo[0]) + w * np.asarray(hi[0])
    sd51 = (1 - w) * np.asarray(lo[1]) + w * np.asarray(hi[1])
    pct = np.linspace(0.0, 100.0, n)
    grid = np.arange(0.0, 101.0, 2.0)
    info = {"v_hat": round(v, 4), "lower": CATEGORIES[i], "upper": CATEGORIES[i + 1], "weight_upper": round(float(w), 4),
            "clamped": bool(clamped), "leg_length_m": float(leg_length_m), "speed_m_s": float(speed_m_s)}
    return pct, np.interp(pct, grid, mean51), np.interp(pct, grid, sd51), info


def speed_band_table(joints=("hip", "knee")) -> dict:
    """Every category's curve of ``joints`` and the category centres: what the live page interpolates itself as the
    participant's speed changes (the same linear rule as :func:`speed_matched_band`)."""
    from stridelab.reports._schwartz2008 import CATEGORIES, DATA
    return {"categories": list(CATEGORIES), "centres": speed_category_centres(),
            "pct": [float(p) for p in range(0, 101, 2)],
            "curves": {j: {cat: {"mean": list(DATA[j][cat][0]), "sd": list(DATA[j][cat][1])} for cat in CATEGORIES}
                       for j in joints},
            "source": "Schwartz, Rozumalski & Trost 2008 (J Biomech 41:1639), typically developing children, "
                      "five speeds; interpolated in dimensionless speed"}
