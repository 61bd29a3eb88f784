"""Adapter to the ``vqf`` library (Laidig & Seel 2023, doi:10.1016/j.inffus.2022.10.014).

VQF already uses StrideLab's conventions (ENU, [w x y z], rad/s, m/s²); this wrapper only makes the
arrays contiguous and maps the result. ``offline=True`` uses ``offlineVQF`` (forward-backward). ``params``: VQF
parameters by their library names (e.g. ``{"tauMag": 25.0}``), the library defaults otherwise.
"""
from __future__ import annotations

import numpy as np

from stridelab.estimators.orientation._types import OrientationResult


def vqf_orientation(gyr, acc, mag=None, *, sampling_rate_hz: float, offline: bool = False,
                    params: dict | None = None) -> OrientationResult:
    from vqf import VQF, offlineVQF
    gyr = np.ascontiguousarray(gyr, dtype=np.float64)
    acc = np.ascontiguousarray(acc, dtype=np.float64)
    mag_c = None if mag is None else np.ascontiguousarray(mag, dtype=np.float64)
    ts = 1.0 / sampling_rate_hz
    if offline:
        out = offlineVQF(gyr, acc, mag_c, ts, dict(params) if params else None)
        quat = out["quat9D"] if mag_c is not None else out["quat6D"]
        rest = out.get("restDetected", np.zeros(len(gyr), bool))
    else:
        out = VQF(ts, **(params or {})).updateBatch(gyr, acc, mag_c)
        quat = out["quat9D"] if mag_c is not None else out["quat6D"]
        rest = out.get("restDetected", np.zeros(len(gyr), bool))
    return OrientationResult(quat=np.asarray(quat), gain=np.zeros(len(gyr)), still=np.asarray(rest, bool),
                             mag_used=mag_c is not None, params={"offline": offline, **(params or {})})
