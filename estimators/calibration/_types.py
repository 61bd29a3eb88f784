"""Parameters and result types of the sensor-to-segment calibration family."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from types import MappingProxyType

import numpy as np

from stridelab.estimators.quaternion import quat_from_matrix

LEG_SEGMENTS = ("thigh", "shank", "foot")
SIDES = ("left", "right")
LEG_PLACEMENTS = tuple(f"{seg}_{side}" for side in SIDES for seg in LEG_SEGMENTS)
STATUS_ORDER = {"pass": 0, "warn": 1, "fail": 2}


@dataclass(frozen=True)
class CalibrationParams:
    """Sensor-to-segment calibration parameters (spec/thesis_calib_gait_posture.md §2.2, §0.5).

    method: movement used for the heading step: ``"auto"`` (hip FE when detected, else walking; a
        segment that does not rotate during the hip FE, e.g. a foot kept level, uses walking),
        ``"hip_fe"`` (thesis recommendation for patients) or ``"walking"`` (PC8, able-bodied).
    min_standing_s: shortest quiet standing accepted, s (thesis: 1 s suffices).
    target_standing_s: recommended standing, s (3-5 s); shorter standing gives a warning.
    stand_gyr_rad_s: quiet standing if the smoothed gyro norm of every IMU is below this, rad/s.
    stand_acc_m_s2: quiet standing if | |a| − g | of every IMU is below this, m/s².
    active_gyr_rad_s: a leg side is moving if its 1-s smoothed gyro norm exceeds this, rad/s.
    min_fe_repetitions: fewest hip flexion/extension repetitions accepted (thesis ≥ 10).
    min_walking_steps: fewest straight-walking steps accepted (thesis PC8: 8).
    peak_prominence_rad_s: prominence of a repetition / swing peak on the main axis, rad/s (0.3: a hip
        FE of ±18° at 0.6 Hz peaks at ≈ 1.1 rad/s; the short closing step of a paretic leg at ≈ 0.4
        rad/s; gyro noise is < 0.02 rad/s, and stance bumps are left to the one-peak-per-period rule).
    min_peak_fraction: a peak also needs ≥ this fraction of the largest peak (0.1: the gait-initiation
        swing and the short closing step of an 8-step walk peak at 15-40 % of a steady swing but are
        steps; stance bumps are rejected by the one-peak-per-period rule of ``count_cycles``).
    min_planarity: smallest explained variance λ1/(λ1+λ2) of the principal axis (spec: 0.8).
    max_axis_tilt_deg: largest angle between the 3D principal rotation axis and the horizontal
        plane of the standing estimate (agreement standing vs movement); above it → warning.
    max_gravity_spread_deg: largest spread (RMS angle) of the acceleration direction in standing.
    gravity_m_s2: magnitude of gravity, m/s².
    pelvis_method: ``"thighs"`` (heading from the mean thigh z axis, needs orientations),
        ``"sway"`` (medio-lateral sway PCA while walking) or ``"auto"`` (thighs, else sway).
    swap_margin: correlation margin by which a leg sensor must follow the other leg to be flagged
        as left/right swapped.
    """
    method: str = "auto"
    min_standing_s: float = 1.0
    target_standing_s: float = 3.0
    stand_gyr_rad_s: float = 0.1
    stand_acc_m_s2: float = 0.3
    active_gyr_rad_s: float = 0.3
    min_fe_repetitions: int = 10
    min_walking_steps: int = 8
    peak_prominence_rad_s: float = 0.3
    min_peak_fraction: float = 0.1
    min_planarity: float = 0.8
    max_axis_tilt_deg: float = 15.0
    max_gravity_spread_deg: float = 3.0
    gravity_m_s2: float = 9.81
    pelvis_method: str = "auto"
    swap_margin: float = 0.3

    def __post_init__(self):
        if self.method not in ("auto", "hip_fe", "walking"):
            raise ValueError(f"method must be 'auto', 'hip_fe' or 'walking', got {self.method!r}")
        if self.pelvis_method not in ("auto", "thighs", "sway"):
            raise ValueError(f"pelvis_method must be 'auto', 'thighs' or 'sway', got {self.pelvis_method!r}")
        if self.min_standing_s <= 0 or self.min_fe_repetitions < 1 or self.min_walking_steps < 1:
            raise ValueError("min_standing_s, min_fe_repetitions and min_walking_steps must be positive")


PRESETS = MappingProxyType({
    "thesis_hip_fe": CalibrationParams(method="hip_fe"),
    "thesis_pc8": CalibrationParams(method="walking"),
})


@dataclass(frozen=True)
class CalibrationWindows:
    """Half-open ``[start, end)`` sample windows of a calibration trial.

    standing: quiet standing (all IMUs still); hip_fe: side ("left"/"right") -> window of that leg's
    hip flexion/extension repetitions; walking: straight walking; source: ``"auto"`` (detected) or
    ``"manual"`` (given, e.g. from the study manifest). ``None`` = not present.
    """
    standing: tuple[int, int] | None = None
    hip_fe: dict = field(default_factory=dict)
    walking: tuple[int, int] | None = None
    source: str = "auto"

    @staticmethod
    def from_seconds(*, sampling_rate_hz: float, standing=None, hip_fe=None, walking=None) -> "CalibrationWindows":
        """Manual windows given in seconds from the start of the trial (manifest form)."""
        def idx(w):
            return None if w is None else (int(round(w[0] * sampling_rate_hz)), int(round(w[1] * sampling_rate_hz)))
        return CalibrationWindows(standing=idx(standing), hip_fe={k: idx(v) for k, v in (hip_fe or {}).items()},
                                  walking=idx(walking), source="manual")

    def as_dict(self) -> dict:
        return {"standing": self.standing, "hip_fe": dict(self.hip_fe), "walking": self.walking, "source": self.source}


@dataclass(frozen=True)
class ImuCalibration:
    """Calibration of one IMU and its quality indicators.

    placement: where the IMU is (``thigh_left`` …). R_sensor_af: (3, 3) native sensor ← anatomical
    frame (``v_sensor = R v_AF``; the mounting permutation is folded in); all-NaN when it could not be
    computed. quat_sensor_af: the same as a quaternion [w x y z]; a segment orientation is
    ``q_AF = q_sensor ⊗ quat_sensor_af``. method: ``hip_fe``, ``walking``, ``pelvis_thighs``,
    ``pelvis_sway`` or ``none``. status: ``pass`` / ``warn`` / ``fail``; reasons: why not pass.
    planarity: explained variance of the principal axis λ1/(λ1+λ2). gamma_deg: heading rotation
    of Eq. 15. standing_s: standing duration used, s. gravity_m_s2: mean |a| in standing.
    gravity_spread_deg: RMS angle of the standing acceleration about its mean direction.
    n_cycles: repetitions (hip FE) or swings (walking) of this IMU's movement used. axis_tilt_deg:
    angle between the 3D principal rotation axis of the movement and the standing horizontal plane
    (agreement of the standing and movement estimates; 0 = perfect). x_vertical_deg: angle between
    sensor x (after P_mount) and vertical in standing (degenerate below 20°).
    """
    placement: str
    R_sensor_af: np.ndarray
    method: str
    status: str
    reasons: tuple[str, ...] = ()
    planarity: float = float("nan")
    gamma_deg: float = float("nan")
    standing_s: float = 0.0
    gravity_m_s2: float = float("nan")
    gravity_spread_deg: float = float("nan")
    n_cycles: int = 0
    axis_tilt_deg: float = float("nan")
    x_vertical_deg: float = float("nan")

    @property
    def valid(self) -> bool:
        """True when a rotation was computed (it may still carry a warn/fail status)."""
        return bool(np.all(np.isfinite(self.R_sensor_af)))

    @property
    def quat_sensor_af(self) -> np.ndarray:
        if not self.valid:
            return np.full(4, np.nan)
        return quat_from_matrix(self.R_sensor_af)

    def with_status(self, status: str, reason: str) -> "ImuCalibration":
        """A copy with ``reason`` appended and the worse of the two statuses."""
        worst = status if STATUS_ORDER[status] > STATUS_ORDER[self.status] else self.status
        return replace(self, status=worst, reasons=self.reasons + (reason,))

    def as_dict(self) -> dict:
        return {"placement": self.placement, "method": self.method, "status": self.status,
                "reasons": list(self.reasons), "R_sensor_af": self.R_sensor_af.tolist(),
                "planarity": self.planarity, "gamma_deg": self.gamma_deg, "standing_s": self.standing_s,
                "gravity_m_s2": self.gravity_m_s2, "gravity_spread_deg": self.gravity_spread_deg,
                "n_cycles": self.n_cycles, "axis_tilt_deg": self.axis_tilt_deg,
                "x_vertical_deg": self.x_vertical_deg}


@dataclass(frozen=True)
class SessionCalibration:
    """Calibration of every IMU of a session.

    imus: placement -> :class:`ImuCalibration`. windows: the windows used. n_steps: straight-walking
    steps found (both legs). status: worst IMU status (``fail`` also when the trial is missing);
    reasons: session-level reasons (missing trial, swapped sensors, ...). params: what produced it.
    """
    imus: dict
    windows: CalibrationWindows
    status: str
    reasons: tuple[str, ...] = ()
    n_steps: int = 0
    params: CalibrationParams = CalibrationParams()

    def segment_quat(self, placement: str, quat_sensor: np.ndarray) -> np.ndarray:
        """(N, 4) anatomical-frame orientation AF → ENU: ``q_sensor ⊗ q_sensor_af`` (Eq. 17)."""
        from stridelab.estimators.quaternion import quat_mul
        return quat_mul(np.asarray(quat_sensor, float), self.imus[placement].quat_sensor_af)

    def as_dict(self) -> dict:
        return {"status": self.status, "reasons": list(self.reasons), "n_steps": self.n_steps,
                "windows": self.windows.as_dict(), "imus": {k: v.as_dict() for k, v in self.imus.items()}}
