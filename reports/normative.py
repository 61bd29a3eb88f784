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
