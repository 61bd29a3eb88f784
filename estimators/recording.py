"""The in-memory representation of one recording, shared by the simulator and all format readers.

Pure data (NumPy arrays + a metadata dict), no I/O. Format readers in ``pipeline/formats`` and the
simulator in ``studies/`` produce it; the MCAP writer and ingest consume it. Units follow DESIGN.md:
time int64 ns (UTC, sensor clock), acc m/s², gyr rad/s, mag µT, distances m, quaternions
``[w, x, y, z]`` rotating the sensor (or segment) frame into ENU.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

PLACEMENTS = ("pelvis", "thigh_left", "thigh_right", "shank_left", "shank_right",
              "foot_left", "foot_right", "chest", "lower_back")
#: single-sensor trunk placements the trunk-gait stage reads (docs/walking_at_home.md: body frames)
TRUNK_PLACEMENTS = ("lower_back", "chest")

#: keys of the MCAP ``session`` metadata record (DESIGN.md "Recording format")
SESSION_KEYS_REQUIRED = ("study", "participant", "session", "kind")
SESSION_KEYS_OPTIONAL = ("protocol", "trial", "timezone")
SESSION_KINDS = ("lab", "free_living", "calibration")
#: optional numeric body measures of the participant (decimal strings, SI units; ingest checks the range, the
#: trunk-gait stage reads them): height, leg length (greater trochanter to floor), height of a lower-back sensor
#: above the floor, walking aid (0/1)
SESSION_BODY_FIELDS = ("height_m", "leg_length_m", "sensor_height_m", "walking_aid")
SESSION_BODY_RANGES = {"height_m": (0.5, 2.5), "leg_length_m": (0.3, 1.5), "sensor_height_m": (0.3, 1.6),
                       "walking_aid": (0, 1)}
#: study-design marks of a session: ``repeat_baseline = 1`` = one of several baseline sessions before an
#: intervention (the between-session error of a change is taken from them: stridelab.estimators.gait.clinical.change_mdc95)
SESSION_DESIGN_FIELDS = ("repeat_baseline",)


@dataclass
class ImuData:
    """One IMU: ``t_ns`` (N,) int64 sensor time; ``acc`` (N, 3) m/s²; ``gyr`` (N, 3) rad/s, or None for an
    accelerometer-only device; ``mag`` (N, 3) µT on the same time grid, or None when the sensor has no
    magnetometer."""
    t_ns: np.ndarray
    acc: np.ndarray
    gyr: np.ndarray | None
    mag: np.ndarray | None = None


@dataclass
class PoseData:
    """Reference segment pose from optical capture: ``t_ns`` (N,), ``pos`` (N, 3) m in ENU,
    ``quat`` (N, 4) [w x y z] segment frame -> ENU."""
    t_ns: np.ndarray
    pos: np.ndarray
    quat: np.ndarray


@dataclass
class RangeData:
    """A shoe distance sensor (Duong & Suh): ``t_ns`` (N,), ``range_m`` (N,), limits in m."""
    t_ns: np.ndarray
    range_m: np.ndarray
    min_range_m: float = 0.0
    max_range_m: float = 0.2


@dataclass
class Recording:
    """One recording (one MCAP file).

    ``metadata`` is the ``session`` record (study, participant, session, kind, protocol, trial,
    timezone). ``imu`` maps placement -> ImuData; ``reference_poses`` placement -> PoseData;
    ``ranges`` "<placement>/<A|B>" -> RangeData; ``events`` is a list of annotation dicts with at
    least ``t_ns`` (int) and ``type`` (e.g. ``"IC"``, ``"TC"``, ``"activity"``), plus ``side`` or
    ``placement`` for gait events and ``label`` / ``end_ns`` for activity labels.
    """
    metadata: dict[str, str]
    imu: dict[str, ImuData] = field(default_factory=dict)
    reference_poses: dict[str, PoseData] = field(default_factory=dict)
    ranges: dict[str, RangeData] = field(default_factory=dict)
    events: list[dict] = field(default_factory=list)
    name: str = "recording"
