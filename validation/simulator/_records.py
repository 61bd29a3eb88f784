"""What the simulator emits: one recording as plain arrays, field for field the recording layout the format
writers read (``stridelab.pipeline.formats.mcap_write``; DESIGN.md "Recording format"). Defined here so the simulator
depends on no estimator code; ``tests/validation/test_simulator_independence.py`` checks the fields agree with
the layout of the numerical layer. Units: time int64 ns (UTC, sensor clock), acc m/s², gyr rad/s, mag µT, m,
quaternions ``[w, x, y, z]`` segment/sensor frame -> ENU.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class ImuData:
    """``t_ns`` (N,) int64; ``acc`` (N, 3) m/s²; ``gyr`` (N, 3) rad/s or None; ``mag`` (N, 3) µT or None."""
    t_ns: np.ndarray
    acc: np.ndarray
    gyr: np.ndarray | None
    mag: np.ndarray | None = None


@dataclass
class PoseData:
    """Reference segment pose: ``t_ns`` (N,), ``pos`` (N, 3) m ENU, ``quat`` (N, 4) segment -> ENU."""
    t_ns: np.ndarray
    pos: np.ndarray
    quat: np.ndarray


@dataclass
class RangeData:
    """A shoe distance sensor: ``t_ns`` (N,), ``range_m`` (N,), limits in m."""
    t_ns: np.ndarray
    range_m: np.ndarray
    min_range_m: float = 0.0
    max_range_m: float = 0.2


@dataclass
class Recording:
    """One simulated recording: ``metadata`` (the ``session`` record), ``imu`` placement -> ImuData,
    ``reference_poses`` placement -> PoseData, ``ranges`` "<placement>/<A|B>" -> RangeData, ``events`` annotation
    dicts (``t_ns``, ``type``, ``side``/``placement``, ``label``/``end_ns``), ``name`` (the file stem)."""
    metadata: dict[str, str]
    imu: dict[str, ImuData] = field(default_factory=dict)
    reference_poses: dict[str, PoseData] = field(default_factory=dict)
    ranges: dict[str, RangeData] = field(default_factory=dict)
    events: list[dict] = field(default_factory=list)
    name: str = "recording"
