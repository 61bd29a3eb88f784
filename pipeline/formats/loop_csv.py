"""Reader for x-io / NGIMU-style CSVs (the foot-IMU loop walks): ``Time (s), Gyroscope X..Z (deg/s),
Accelerometer X..Z (g)`` and, when present, ``Magnetometer X..Z (uT)`` (NGIMU ``sensors.csv``; µT kept).

About 400 Hz with timestamp jitter and occasional repeated timestamps. The reader sorts by time, merges rows
with the same timestamp (mean), and resamples linearly onto a uniform grid at the median sample rate (rounded
to 1 Hz); units become rad/s and m/s² (1 g = 9.80665 m/s²). Mounting is unknown and left as recorded.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["LoopRecording", "load_loop_csv", "COLUMNS"]

COLUMNS = ("Time (s)", "Gyroscope X (deg/s)", "Gyroscope Y (deg/s)", "Gyroscope Z (deg/s)",
           "Accelerometer X (g)", "Accelerometer Y (g)", "Accelerometer Z (g)")
MAG_COLUMNS = ("Magnetometer X (uT)", "Magnetometer Y (uT)", "Magnetometer Z (uT)")
G0 = 9.80665


@dataclass(frozen=True)
class LoopRecording:
    """gyr (N, 3) rad/s, acc (N, 3) m/s² on a uniform grid; ``n_duplicates`` merged repeated timestamps;
    ``mag`` (N, 3) µT when the file has magnetometer columns, else None."""
    gyr: np.ndarray
    acc: np.ndarray
    sampling_rate_hz: float
    n_duplicates: int
    mag: np.ndarray | None = None


def load_loop_csv(path: Path | str) -> LoopRecording:
    """Read and resample one CSV; raises ``ValueError`` naming the file and the problem."""
    import pandas as pd
    path = Path(path)
    try:
        df = pd.read_csv(path)
    except (OSError, pd.errors.ParserError, UnicodeDecodeError) as e:
        raise ValueError(f"{path}: not a readable CSV ({e})") from e
    df.columns = [c.strip() for c in df.columns]
    missing = [c for c in COLUMNS if c not in df.columns]
    if missing:
        raise ValueError(f"{path}: missing column(s) {', '.join(missing)}; expected {', '.join(COLUMNS)}")
    cols = list(COLUMNS) + (list(MAG_COLUMNS) if all(c in df.columns for c in MAG_COLUMNS) else [])
    df = df[cols].apply(pd.to_numeric, errors="coerce").dropna()
    if len(df) < 10:
        raise ValueError(f"{path}: fewer than 10 valid rows")
    n_raw = len(df)
    df = df.groupby(COLUMNS[0], sort=True).mean().reset_index()
    t = df[COLUMNS[0]].to_numpy(float)
    dt = np.diff(t)
    fs = float(np.round(1.0 / np.median(dt)))
    if not fs > 0:
        raise ValueError(f"{path}: cannot determine the sampling rate from the time column")
    grid = t[0] + np.arange(int(np.floor((t[-1] - t[0]) * fs + 1e-6)) + 1) / fs      # 1e-6: float round-off
    x = df[cols[1:]].to_numpy(float)
    y = np.column_stack([np.interp(grid, t, x[:, i]) for i in range(x.shape[1])])
    return LoopRecording(gyr=np.deg2rad(y[:, :3]), acc=y[:, 3:6] * G0, sampling_rate_hz=fs,
                         n_duplicates=n_raw - len(df), mag=y[:, 6:9] if y.shape[1] == 9 else None)
