"""Reader for the gaitmap example walk (``../shared/data/gaitmap_example``, MIT, Küderle et al. 2022).

Files (data README): ``imu_sample.csv`` (two header rows ``sensor`` / ``axis``; columns ``acc_x..gyr_z`` for
``left_sensor`` and ``right_sensor``; acc m/s², gyr **deg/s**, already rotated into gaitmap's foot sensor frame:
x toward the toes, z up at rest, y to the left), 204.8 Hz; ``mocap_sample.csv`` (Qualisys, mm, 100 Hz, markers
``{L,R}_{TOE,FCC,FM5}``, FCC = heel), started together with the IMUs (sample 0 of both = same instant);
``stride_events_sample.csv`` (per stride, in IMU samples: ``start``/``end`` = mid-stance ``min_vel`` borders, ``ic``,
``tc``, ``pre_ic``).

The reader converts to StrideLab units (gyr rad/s, marker positions m) and nothing else; the frames stay as stored
(the gait estimators are mounting-agnostic).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["GaitmapFoot", "GaitmapExample", "load_gaitmap_example"]

IMU_RATE_HZ = 204.8
MOCAP_RATE_HZ = 100.0


@dataclass(frozen=True)
class GaitmapFoot:
    """One foot of the gaitmap example.

    gyr, acc: (N, 3) rad/s and m/s² (specific force), gaitmap foot sensor frame.
    markers: name -> (M, 3) m, Qualisys lab frame (z up), at ``mocap_rate_hz``; names ``TOE``, ``FCC`` (heel), ``FM5``.
    strides: (S, 6) int, columns start, end, ic, tc, min_vel, pre_ic in IMU samples (reference, from mocap).
    """
    side: str
    gyr: np.ndarray
    acc: np.ndarray
    markers: dict
    strides: np.ndarray


@dataclass(frozen=True)
class GaitmapExample:
    """Both feet; ``sampling_rate_hz`` of the IMUs and ``mocap_rate_hz`` of the markers."""
    left: GaitmapFoot
    right: GaitmapFoot
    sampling_rate_hz: float = IMU_RATE_HZ
    mocap_rate_hz: float = MOCAP_RATE_HZ


def _read_two_header_csv(path: Path):
    import pandas as pd
    df = pd.read_csv(path, header=[0, 1], index_col=0)
    return df


def load_gaitmap_example(directory: Path | str) -> GaitmapExample:
    """Load the example walk from ``directory``; raises ``ValueError`` naming a missing or malformed file."""
    import pandas as pd
    d = Path(directory)
    need = ("imu_sample.csv", "mocap_sample.csv", "stride_events_sample.csv")
    missing = [n for n in need if not (d / n).is_file()]
    if missing:
        raise ValueError(f"gaitmap example folder {d} lacks {', '.join(missing)} (expected the gaitmap example data)")
    imu = _read_two_header_csv(d / "imu_sample.csv")
    mocap = pd.read_csv(d / "mocap_sample.csv", header=[0, 1], index_col=0)
    ev = pd.read_csv(d / "stride_events_sample.csv")
    feet = {}
    for side, sensor, prefix in (("left", "left_sensor", "L"), ("right", "right_sensor", "R")):
        try:
            acc = np.column_stack([imu[(sensor, f"acc_{a}")].to_numpy(float) for a in "xyz"])
            gyr = np.deg2rad(np.column_stack([imu[(sensor, f"gyr_{a}")].to_numpy(float) for a in "xyz"]))
            markers = {m: np.column_stack([mocap[(f"{prefix}_{m}", a)].to_numpy(float) for a in "xyz"]) / 1000.0
                       for m in ("TOE", "FCC", "FM5")}
        except KeyError as e:
            raise ValueError(f"gaitmap example: column {e} not found in {d}") from e
        sel = ev[ev["foot"] == side]
        strides = sel[["start", "end", "ic", "tc", "min_vel", "pre_ic"]].to_numpy(float)
        strides = np.rint(strides).astype(np.int64)
        feet[side] = GaitmapFoot(side=side, gyr=gyr, acc=acc, markers=markers, strides=strides)
    return GaitmapExample(left=feet["left"], right=feet["right"])
