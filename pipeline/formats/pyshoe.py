"""Reader for the PyShoe Vicon trials (``../shared/data/pyshoe_vicon``; MIT repackaging of Wagstaff et al. 2017).

One ``.mat`` file per trial (``scipy.io.loadmat``): ``imu`` (N, 6) accelerometer m/s² (specific force) then gyro
rad/s in the sensor frame of a shoe-mounted MicroStrain IMU; ``ts`` (1, N) or (N,) timestamps in s; ``gt`` (N, 3)
Vicon foot position in m at every IMU sample. The Vicon frame is a mirror image of a right-handed z-up frame, so
the reader flips its y axis (``position`` is right-handed, z up). Optional ``zv_<detector>_opt`` (1, N) are the
zero-velocity labels of PyShoe's detectors with thresholds optimised per trial against Vicon (an oracle); they are
returned as booleans for diagnostics only.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["PyShoeTrial", "load_pyshoe_trial", "load_pyshoe_dir"]


@dataclass(frozen=True)
class PyShoeTrial:
    """acc (N, 3) m/s², gyr (N, 3) rad/s (sensor frame); t (N,) s from the file; position (N, 3) m, right-handed
    z up (Vicon y flipped); ``sampling_rate_hz`` = 1 / median sample interval, rounded to 0.1 Hz."""
    name: str
    acc: np.ndarray
    gyr: np.ndarray
    t: np.ndarray
    position: np.ndarray
    sampling_rate_hz: float
    oracle_zv: dict = field(default_factory=dict)


def load_pyshoe_trial(path: Path | str) -> PyShoeTrial:
    """Read one trial; raises ``ValueError`` naming the file and what is wrong."""
    import scipy.io as sio
    path = Path(path)
    try:
        d = sio.loadmat(path)
    except (OSError, ValueError, TypeError, NotImplementedError) as e:
        raise ValueError(f"{path}: not a readable MATLAB file ({e}); expected a PyShoe Vicon trial") from e
    missing = [k for k in ("imu", "ts", "gt") if k not in d]
    if missing:
        raise ValueError(f"{path}: missing variable(s) {', '.join(missing)}; a PyShoe Vicon trial has imu, ts, gt")
    imu = np.asarray(d["imu"], float)
    ts = np.asarray(d["ts"], float).ravel()
    gt = np.asarray(d["gt"], float)
    n = imu.shape[0]
    if imu.ndim != 2 or imu.shape[1] != 6:
        raise ValueError(f"{path}: imu has shape {imu.shape}, expected (N, 6) acc m/s² then gyro rad/s")
    if gt.shape != (n, 3) or ts.shape != (n,):
        raise ValueError(f"{path}: imu has {n} rows but ts has {ts.size} and gt shape {gt.shape}; "
                         "expected one timestamp and one (x, y, z) Vicon position per IMU sample")
    if n < 10 or not (np.all(np.isfinite(imu)) and np.all(np.isfinite(ts))):
        raise ValueError(f"{path}: fewer than 10 samples or non-finite imu/ts values")
    dt = np.diff(ts)
    if not np.all(dt > 0):
        raise ValueError(f"{path}: timestamps ts are not strictly increasing")
    fs = float(np.round(1.0 / np.median(dt), 1))
    pos = gt * np.array([1.0, -1.0, 1.0])
    zv = {k[3:-4]: np.asarray(v).ravel().astype(bool) for k, v in d.items()
          if k.startswith("zv_") and k.endswith("_opt") and np.asarray(v).size == n}
    return PyShoeTrial(name=path.stem, acc=imu[:, :3].copy(), gyr=imu[:, 3:].copy(), t=ts, position=pos,
                       sampling_rate_hz=fs, oracle_zv=zv)


def load_pyshoe_dir(directory: Path | str) -> list[PyShoeTrial]:
    """All ``*.mat`` trials of a folder in name order; ``ValueError`` if there is none."""
    d = Path(directory)
    files = sorted(d.glob("*.mat"))
    if not files:
        raise ValueError(f"{d}: no .mat files; expected the PyShoe Vicon trials (see ../shared/data/README.md)")
    return [load_pyshoe_trial(f) for f in files]
