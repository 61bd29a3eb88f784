"""Daily digital mobility outcomes from walking bouts (Mobilise-D).

Outcomes and their aggregation follow the Mobilise-D digital mobility outcome definitions (Polhemus et al. 2021,
"Walking on common ground", Digit Biomark, doi:10.1159/000516271; Kirk et al. 2024, "Mobilise-D insights to
estimate real-world walking speed in multiple conditions with a wearable device", Sci Rep 14:1754,
doi:10.1038/s41598-024-51766-5): walking time, number of bouts by duration class (10-30, 30-60, 60-120, > 120 s),
median and 95th centile of bout walking speed, stride length and cadence over bouts longer than 10 s; and the
95th centile of stride velocity (SV95C, qualified by the EMA for Duchenne muscular dystrophy, Servais et al. 2023,
Nat Med 29:2454, doi:10.1038/s41591-023-02459-5). Centiles by linear interpolation (NumPy's default).
"""
from __future__ import annotations

import numpy as np

from stridelab.estimators.trunk_gait._types import DURATION_CLASSES_S, DailyOutcomes

MIN_BOUT_S = 10.0


def _q(x: np.ndarray, q: float) -> float:
    x = x[np.isfinite(x)]
    return float(np.percentile(x, q)) if len(x) else float("nan")


def daily_outcomes(bout_start_s, bout_duration_s, bout_cadence_spm, bout_stride_length_m, bout_speed_m_s,
                   stride_speed_m_s=None, *, stride_bout=None) -> DailyOutcomes:
    """Outcomes of one day from per-bout arrays (B,) and optional per-stride speeds (S,).

    ``stride_bout`` (S,) int: index into the bout arrays of each stride; when given, SV95C uses the strides of
    bouts longer than 10 s only, otherwise all given strides. NaN bout values are ignored in the centiles.
    """
    start = np.asarray(bout_start_s, float).ravel()
    dur = np.asarray(bout_duration_s, float).ravel()
    cols = [np.asarray(c, float).ravel() for c in (bout_cadence_spm, bout_stride_length_m, bout_speed_m_s)]
    if any(len(c) != len(dur) for c in [start, *cols]):
        raise ValueError("bout arrays must have the same length: start, duration, cadence, stride length, speed "
                         f"have {[len(start), len(dur), *map(len, cols)]}")
    if np.any(dur < 0):
        raise ValueError("bout_duration_s has negative values; pass end - start in seconds")
    cad, sl, sp = cols
    long = dur > MIN_BOUT_S
    classes = tuple(int(np.sum((dur >= lo) & (dur < hi))) for lo, hi in DURATION_CLASSES_S)
    if stride_speed_m_s is None:
        sv = np.empty(0)
    else:
        sv = np.asarray(stride_speed_m_s, float).ravel()
        if stride_bout is not None:
            sb = np.asarray(stride_bout, np.int64).ravel()
            if len(sb) != len(sv):
                raise ValueError(f"stride_bout has {len(sb)} entries, stride_speed_m_s {len(sv)}")
            if len(sb) and (sb.min() < 0 or sb.max() >= len(dur)):
                raise ValueError("stride_bout indexes outside the bout arrays")
            sv = sv[long[sb]] if len(sb) else sv
    return DailyOutcomes(
        walking_time_s=float(dur.sum()), n_bouts=int(len(dur)), n_bouts_by_class=classes,
        n_bouts_over_10s=int(long.sum()),
        speed_median_m_s=_q(sp[long], 50), speed_p95_m_s=_q(sp[long], 95),
        stride_length_median_m=_q(sl[long], 50), stride_length_p95_m=_q(sl[long], 95),
        cadence_median_spm=_q(cad[long], 50), cadence_p95_spm=_q(cad[long], 95),
        stride_velocity_p95_m_s=_q(sv, 95))
