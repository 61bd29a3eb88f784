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
