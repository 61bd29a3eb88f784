"""The shoe distance sensors of the gait stage (:mod:`stridelab.pipeline.stages.gait`): their readings on the IMU grid
(:func:`read_ranges`) and the Duong & Suh filter with the configured or guessed sensor geometry
(:func:`range_trajectory`)."""
from __future__ import annotations

import dataclasses
import re

import numpy as np

from stridelab.pipeline.stages._context import StageContext

_RANGE_NAME = re.compile(r"range-([A-Za-z0-9]+)-")


def read_ranges(ctx: StageContext, rec: dict, placement: str, t_ns: np.ndarray) -> np.ndarray | None:
    """(N, 2) m on the IMU grid (columns A, B; NaN where no reading falls on that sample; +inf kept: beyond the
    maximum, REP-117), or None when the foot has no distance sensor. A reading goes to the nearest IMU sample
    within half a sample period."""
    keys = sorted(k for k in rec["sensors"].get(placement, {}) if k.startswith("range:"))
    if not keys or len(t_ns) < 2:
        return None
    from stridelab.estimators.sync import nearest_sample
    out = np.full((len(t_ns), 2), np.nan)
    for j, key in enumerate(keys[:2]):
        m = _RANGE_NAME.search(key)
        col = {"A": 0, "B": 1}.get(m.group(1).upper(), j) if m else j
        t = ctx.read_table(rec["sensors"][placement][key]["series_path"], ["t_ns", "range_m"])
        i, ok = nearest_sample(t_ns, t.column("t_ns").to_numpy())
        out[i[ok], col] = t.column("range_m").to_numpy()[ok]
    return out


def range_trajectory(gyr, acc, ranges, fs: float, placement: str, dp):
    """The Duong & Suh filter of one foot segment with the configured or guessed geometry; (result, source).
    ``dp``: the stage's :class:`stridelab.pipeline.stages.gait.DistanceSensorParams`."""
    from stridelab.estimators.trajectory import RangeGeometry, detect_zupt, duong_suh_trajectory, geometry_from_stance
    fp, g = dp.filter, (dp.geometry or {}).get(placement)
    if g is not None:
        return duong_suh_trajectory(gyr, acc, ranges, sampling_rate_hz=fs, params=fp,
                                    geometry=RangeGeometry(**{k: tuple(v) for k, v in g.items()})), "configured"
    geo = geometry_from_stance(acc, detect_zupt(gyr, acc, sampling_rate_hz=fs, params=fp.zupt))
    fp = dataclasses.replace(fp, init_calib_var=float(dp.unknown_geometry_calib_var))
    if geo is None:
        return duong_suh_trajectory(gyr, acc, ranges, sampling_rate_hz=fs, params=fp), "unknown"
    return duong_suh_trajectory(gyr, acc, ranges, sampling_rate_hz=fs, geometry=geo, params=fp), "guessed"
