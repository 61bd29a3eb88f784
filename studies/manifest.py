"""Study manifests: one TOML file per study (``studies/<study>/study.toml``), read into frozen dataclasses.

The manifest holds everything the simulator needs (participants, lab protocol, free-living length,
sensor model) and, under ``[stages.<name>]``, optional per-study stage parameters that the pipeline
reads itself (``pipeline/config.py``), and under ``[compute.<name>]`` (``<session kind> = true``) the
opt-in outputs the study asks for (e.g. ``[compute.orientation] free_living = true``). ``load_manifest`` validates every field and raises a
``ValueError`` naming the file and the field.
"""
from __future__ import annotations

import re

import datetime as _dt
import tomllib
import zoneinfo
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

from stridelab.studies.privacy import PrivacyPolicy, identifier_problem, privacy_policy

__all__ = ["DEFAULT_MANIFEST", "ParticipantSpec", "LabProtocol", "FreeLivingSpec", "SensorModelSpec",
           "StudyManifest", "load_manifest"]

#: the embedded default study (4 participants, one hemiparetic)
DEFAULT_MANIFEST = Path(__file__).resolve().parent / "demo" / "study.toml"


@dataclass(frozen=True)
class ParticipantSpec:
    """One participant: ``id`` pseudonym (e.g. "P001"); ``sex`` "F"/"M"; ``height_m``; ``thigh_m`` and
    ``shank_m`` (hip-knee and knee-ankle joint-centre distances); ``speed_m_s`` comfortable walking
    speed; ``cadence_steps_min``; ``condition`` "healthy" | "hemiparetic"; ``paretic_side`` "left" |
    "right" (hemiparetic only); ``severity`` 0..1 scaling the asymmetry. ``follow_up_speed_m_s``,
    ``follow_up_cadence_steps_min``, ``follow_up_severity``: the values at the last lab visit of a programme
    (``[study] visits`` > 1), reached linearly over the visits; None = as at baseline."""
    id: str
    sex: str = "F"
    height_m: float = 1.70
    thigh_m: float = 0.42
    shank_m: float = 0.40
    speed_m_s: float = 1.25
    cadence_steps_min: float = 110.0
    condition: str = "healthy"
    paretic_side: str | None = None
    severity: float = 0.0
    follow_up_speed_m_s: float | None = None
    follow_up_cadence_steps_min: float | None = None
    follow_up_severity: float | None = None

    @property
    def hemiparetic(self) -> bool:
        return self.condition == "hemiparetic"

    def at_visit(self, visit: int, visits: int) -> "ParticipantSpec":
        """The participant at lab visit ``visit`` (1-based) of ``visits``: baseline values at visit 1, the
        ``follow_up_*`` values at the last visit, linear in between."""
        if visits <= 1 or visit <= 1:
            return self
        f = (min(visit, visits) - 1) / (visits - 1)
        kw = {}
        for name in ("speed_m_s", "cadence_steps_min", "severity"):
            end = getattr(self, f"follow_up_{name}")
            if end is not None:
                kw[name] = getattr(self, name) + f * (end - getattr(self, name))
        return replace(self, **kw) if kw else self


@dataclass(frozen=True)
class LabProtocol:
    """Lab session protocol: ``quiet_standing_s``, ``hip_repetitions`` (per leg), ``straight_steps`` of the
    calibration trial; ``walking_trials`` × ``walking_trial_s``; ``distance_sensors`` and
    ``optical_reference`` switches."""
    quiet_standing_s: float = 4.0
    hip_repetitions: int = 10
    straight_steps: int = 8
    walking_trials: int = 2
    walking_trial_s: float = 30.0
    distance_sensors: bool = True
    optical_reference: bool = True
    lower_back: bool = False          # a belt-worn lower-back IMU (L4/L5) beside the segment sensors


@dataclass(frozen=True)
class FreeLivingSpec:
    """Free-living chest recording: ``hours`` long, starting at ``start_local`` ("HH:MM") on the day after
    the lab session."""
    hours: float = 24.0
    start_local: str = "00:00"
    lower_back: bool = False          # a belt-worn lower-back IMU beside the chest IMU, on the same trunk model


@dataclass(frozen=True)
class SensorModelSpec:
    """IMU error model (base: Yun et al. 2012 Table II, spec/foot_papers.md A7.3). Units in the names;
    ``mounting_misalignment_deg`` is a (min, max) range of the sensor-to-segment rotation angle.
    ``SensorModelSpec.ideal()`` gives the noise-free, error-free model (mounting rotations stay: they
    are geometry, not error)."""
    noise_scale: float = 1.0
    acc_noise_m_s2: float = 0.033
    gyr_noise_rad_s: float = 0.0076
    mag_noise_uT: float = 0.082
    acc_bias_m_s2: float = 0.049
    gyr_bias_deg_s: float = 0.5
    gyr_bias_rw_deg_s_sqrt_s: float = 0.01
    mag_bias_uT: float = 1.0
    scale_factor_pct: float = 1.0
    axis_misalignment_deg: float = 0.5
    mounting_misalignment_deg: tuple[float, float] = (5.0, 20.0)
    wobble_deg_per_g: float = 0.8
    wobble_mm_per_g: float = 1.5
    earth_field_uT: float = 48.0
    earth_dip_deg: float = 63.0
    mag_disturbance_uT: float = 12.0
    optical_pos_noise_m: float = 0.0005
    optical_rot_noise_deg: float = 0.3
    range_noise_m: float = 0.003

    @classmethod
    def ideal(cls, mounting_misalignment_deg: tuple[float, float] = (5.0, 20.0)) -> "SensorModelSpec":
        """No noise, bias, scale, misalignment, wobble, magnetic disturbance or reference noise."""
        return cls(noise_scale=0.0, acc_bias_m_s2=0.0, gyr_bias_deg_s=0.0, gyr_bias_rw_deg_s_sqrt_s=0.0,
                   mag_bias_uT=0.0, scale_factor_pct=0.0, axis_misalignment_deg=0.0,
                   mounting_misalignment_deg=tuple(mounting_misalignment_deg), wobble_deg_per_g=0.0,
                   wobble_mm_per_g=0.0, mag_disturbance_uT=0.0, optical_pos_noise_m=0.0,
                   optical_rot_noise_deg=0.0, range_noise_m=0.0)


@dataclass(frozen=True)
class StudyManifest:
    """A study manifest (see ``studies/demo/study.toml`` for every field, documented)."""
    name: str
    seed: int
    timezone: str = "Europe/Zurich"
    sampling_rate_hz: float = 100.0
    first_lab_date: _dt.date = _dt.date(2026, 3, 2)
    lab_start_local: str = "09:00"
    visits: int = 1                   # lab visits per participant (a programme: baseline, follow-ups)
    visit_interval_days: int = 42     # days between a participant's visits
    participants: tuple[ParticipantSpec, ...] = ()
    lab: LabProtocol = LabProtocol()
    free_living: FreeLivingSpec = FreeLivingSpec()
    sensor_model: SensorModelSpec = SensorModelSpec()
    stages: MappingProxyType = field(default_factory=lambda: MappingProxyType({}), compare=False)
    #: ``[topics]``: recording topic -> placement, for recordings whose topics are not /imu/<placement>
    topics: MappingProxyType = field(default_factory=lambda: MappingProxyType({}), compare=False)
    privacy: PrivacyPolicy = PrivacyPolicy()
    path: Path | None = field(default=None, compare=False)

    def with_free_living_hours(self, hours: float) -> "StudyManifest":
        """Copy with another free-living recording length (the ``--hours`` option)."""
        if not (0.0 < float(hours) <= 48.0):
            raise ValueError(f"free-living hours must be in (0, 48], got {hours}")
        return replace(self, free_living=replace(self.free_living, hours=float(hours)))

    def with_seed(self, seed: int) -> "StudyManifest":
        return replace(self, seed=int(seed))

    def with_sensor_model(self, sensor_model: SensorModelSpec) -> "StudyManifest":
        return replace(self, sensor_model=sensor_model)


# ---- loading and validation ----------------------------------------------------------------

_TOP_KEYS = {"study", "lab", "free_living", "sensor_model", "participants", "stages", "topics", "compute",
             "privacy"}
_SESSION_KINDS = ("lab", "free_living", "calibration")


class _Ctx:
    def __init__(self, path: Path):
        self.path = path

    def err(self, where: str, msg: str) -> ValueError:
        return ValueError(f"{self.path}: [{where}] {msg}")


def _take(ctx: _Ctx, table: dict, where: str, cls, overrides: dict | None = None):
    """Build dataclass ``cls`` from TOML ``table``, type-checking each field against the default's type."""
    if not isinstance(table, dict):
        raise ctx.err(where, f"expected a table, got {type(table).__name__}")
    known = {f.name: f for f in fields(cls) if f.name not in ("stages", "path", "privacy")}
    unknown = set(table) - set(known)
    if unknown:
        raise ctx.err(where, f"unknown field(s) {sorted(unknown)}; known: {sorted(known)}")
    kw: dict[str, Any] = {}
    defaults = cls.__dataclass_fields__
    for name, val in table.items():
        default = defaults[name].default
        kw[name] = _coerce(ctx, f"{where}.{name}", val, default)
    kw.update(overrides or {})
    try:
        return cls(**kw)
    except TypeError as e:  # a required field is missing
        raise ctx.err(where, str(e)) from None


def _coerce(ctx: _Ctx, where: str, val, default):
    if isinstance(default, bool):
        if not isinstance(val, bool):
            raise ctx.err(where, f"expected true/false, got {val!r}")
        return val
    if isinstance(default, int) and not isinstance(default, bool):
        if isinstance(val, bool) or not isinstance(val, int):
            raise ctx.err(where, f"expected an integer, got {val!r}")
        return val
    if isinstance(default, float):
        if isinstance(val, bool) or not isinstance(val, (int, float)):
            raise ctx.err(where, f"expected a number, got {val!r}")
        return float(val)
    if isinstance(default, tuple):
        if not isinstance(val, list) or len(val) != len(default) or \
                not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in val):
            raise ctx.err(where, f"expected a list of {len(default)} numbers, got {val!r}")
        return tuple(float(v) for v in val)
    if isinstance(default, _dt.date):
        if isinstance(val, _dt.date):
            return val
        try:
            return _dt.date.fromisoformat(str(val))
        except ValueError:
            raise ctx.err(where, f"expected a date YYYY-MM-DD, got {val!r}") from None
    if default is None and isinstance(val, (int, float)) and not isinstance(val, bool):
        return float(val)                   # optional numbers (follow_up_*): None = not given
    if isinstance(default, str) or default is None:
        if not isinstance(val, str):
            raise ctx.err(where, f"expected a string, got {val!r}")
        return val
    return val


def _check_hhmm(ctx: _Ctx, where: str, s: str) -> None:
    try:
        _dt.time.fromisoformat(s)
    except ValueError:
        raise ctx.err(where, f"expected a local time HH:MM, got {s!r}") from None


def _validate_participant(ctx: _Ctx, i: int, p: ParticipantSpec, policy: PrivacyPolicy) -> None:
    why = identifier_problem(p.id, policy)
    if why:      # the id is not repeated: it may be personal data
        raise ctx.err(f"participants[{i}].id", f"the id {why}")
    where = f"participants[{i}] ({p.id})"
    if p.sex not in ("F", "M"):
        raise ctx.err(f"{where}.sex", f"expected 'F' or 'M', got {p.sex!r}")
    checks = [("height_m", 1.0, 2.3), ("thigh_m", 0.25, 0.65), ("shank_m", 0.25, 0.65),
              ("speed_m_s", 0.2, 2.0), ("cadence_steps_min", 50.0, 140.0), ("severity", 0.0, 1.0),
              ("follow_up_speed_m_s", 0.2, 2.0), ("follow_up_cadence_steps_min", 50.0, 140.0),
              ("follow_up_severity", 0.0, 1.0)]
    for name, lo, hi in checks:
        v = getattr(p, name)
        if name.startswith("follow_up_") and v is None:
            continue
        if not isinstance(v, float) or not (lo <= v <= hi):
            raise ctx.err(f"{where}.{name}", f"{v} outside the plausible range [{lo}, {hi}]")
    if p.condition not in ("healthy", "hemiparetic"):
        raise ctx.err(f"{where}.condition", f"expected 'healthy' or 'hemiparetic', got {p.condition!r}")
    if p.hemiparetic and p.paretic_side not in ("left", "right"):
        raise ctx.err(f"{where}.paretic_side", f"hemiparetic needs paretic_side 'left' or 'right', got {p.paretic_side!r}")
    stride_len = p.speed_m_s * 120.0 / p.cadence_steps_min
    if stride_len > 1.9 * (p.thigh_m + p.shank_m):
        raise ctx.err(where, f"speed/cadence give a stride of {stride_len:.2f} m, too long for the legs "
                             f"({p.thigh_m + p.shank_m:.2f} m); lower speed_m_s or raise cadence_steps_min")


def load_manifest(path_or_dir: str | Path | None = None) -> StudyManifest:
    """Read and validate a study manifest.

    ``path_or_dir``: a ``study.toml`` file, or a study folder holding one; ``None`` = the demo study
    (``DEFAULT_MANIFEST``). Raises ``ValueError`` naming the file and the field on any problem.
    """
    path = Path(path_or_dir) if path_or_dir is not None else DEFAULT_MANIFEST
    if path.is_dir():
        path = path / "study.toml"
    ctx = _Ctx(path)
    if not path.is_file():
        raise ValueError(f"{path}: study manifest not found (expected a study.toml file or a folder holding one)")
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{path}: invalid TOML ({e})") from None
    unknown = set(raw) - _TOP_KEYS
    if unknown:
        raise ctx.err("top level", f"unknown table(s) {sorted(unknown)}; known: {sorted(_TOP_KEYS)}")
    study = raw.get("study")
    if not isinstance(study, dict) or "name" not in study or "seed" not in study:
        raise ctx.err("study", "the [study] table with at least 'name' and 'seed' is required")
    if not isinstance(study["name"], str) or not study["name"]:
        raise ctx.err("study.name", f"expected a non-empty string, got {study['name']!r}")
    if not re.fullmatch(r"[A-Za-z0-9._-]{1,128}", study["name"]) or ".." in study["name"]:
        # the study id becomes a warehouse folder name and a query value: the warehouse's identifier rule
        raise ctx.err("study.name", f"must use letters, digits, '.', '_', '-' only (no '..'), got {study['name']!r}")
    if isinstance(study["seed"], bool) or not isinstance(study["seed"], int) or study["seed"] < 0:
        raise ctx.err("study.seed", f"expected a non-negative integer, got {study['seed']!r}")
    head = {k: v for k, v in study.items() if k not in ("name", "seed")}
    tmp = _take(ctx, head, "study", _StudyHead)
    try:
        zoneinfo.ZoneInfo(tmp.timezone)
    except (zoneinfo.ZoneInfoNotFoundError, ValueError):
        raise ctx.err("study.timezone", f"unknown IANA time zone {tmp.timezone!r}") from None
    if not (1 <= tmp.visits <= 12):
        raise ctx.err("study.visits", f"{tmp.visits} outside [1, 12]")
    if not (1 <= tmp.visit_interval_days <= 365):
        raise ctx.err("study.visit_interval_days", f"{tmp.visit_interval_days} outside [1, 365]")
    if not (10.0 <= tmp.sampling_rate_hz <= 2000.0):
        raise ctx.err("study.sampling_rate_hz", f"{tmp.sampling_rate_hz} outside [10, 2000]")
    _check_hhmm(ctx, "study.lab_start_local", tmp.lab_start_local)

    lab = _take(ctx, raw.get("lab", {}), "lab", LabProtocol)
    if not (1.0 <= lab.quiet_standing_s <= 30.0):
        raise ctx.err("lab.quiet_standing_s", f"{lab.quiet_standing_s} outside [1, 30]")
    if not (1 <= lab.hip_repetitions <= 40):
        raise ctx.err("lab.hip_repetitions", f"{lab.hip_repetitions} outside [1, 40]")
    if not (2 <= lab.straight_steps <= 40):
        raise ctx.err("lab.straight_steps", f"{lab.straight_steps} outside [2, 40]")
    if not (0 <= lab.walking_trials <= 10):
        raise ctx.err("lab.walking_trials", f"{lab.walking_trials} outside [0, 10]")
    if not (15.0 <= lab.walking_trial_s <= 600.0):
        raise ctx.err("lab.walking_trial_s", f"{lab.walking_trial_s} outside [15, 600]")

    fl = _take(ctx, raw.get("free_living", {}), "free_living", FreeLivingSpec)
    if not (0.0 < fl.hours <= 48.0):
        raise ctx.err("free_living.hours", f"{fl.hours} outside (0, 48]")
    _check_hhmm(ctx, "free_living.start_local", fl.start_local)

    sm = _take(ctx, raw.get("sensor_model", {}), "sensor_model", SensorModelSpec)
    for f in fields(SensorModelSpec):
        v = getattr(sm, f.name)
        vals = v if isinstance(v, tuple) else (v,)
        if any(x < 0 for x in vals):
            raise ctx.err(f"sensor_model.{f.name}", f"must be >= 0, got {v}")
    lo, hi = sm.mounting_misalignment_deg
    if lo > hi or hi > 90:
        raise ctx.err("sensor_model.mounting_misalignment_deg", f"expected [min, max] with min <= max <= 90, got {[lo, hi]}")
    if not (0 < sm.earth_dip_deg < 90 or -90 < sm.earth_dip_deg <= 0):
        raise ctx.err("sensor_model.earth_dip_deg", f"{sm.earth_dip_deg} outside (-90, 90)")

    try:
        privacy = privacy_policy(raw.get("privacy"), "privacy")
    except ValueError as e:
        raise ctx.err("privacy", str(e)) from None
    plist = raw.get("participants", [])
    if not isinstance(plist, list) or not plist:
        raise ctx.err("participants", "at least one [[participants]] entry is required")
    parts = []
    for i, t in enumerate(plist):
        if not isinstance(t, dict) or "id" not in t:
            raise ctx.err(f"participants[{i}]", "each [[participants]] entry needs an 'id'")
        p = _take(ctx, t, f"participants[{i}]", ParticipantSpec)
        _validate_participant(ctx, i, p, privacy)
        parts.append(p)
    ids = [p.id for p in parts]
    if len(set(ids)) != len(ids):
        raise ctx.err("participants", f"duplicate participant ids in {ids}")
    stages = raw.get("stages", {})
    if not isinstance(stages, dict):
        raise ctx.err("stages", "expected a table of [stages.<name>] tables")
    topics = raw.get("topics", {})
    if not isinstance(topics, dict):
        raise ctx.err("topics", "expected a table of \"/topic\" = \"placement\" entries")
    for k, v in topics.items():
        if not k.startswith("/") or not isinstance(v, str) or not re.fullmatch(r"[A-Za-z0-9_-]{1,64}", v):
            raise ctx.err(f"topics.{k}", "expected \"/topic\" = \"placement\" (letters, digits, '_', '-')")
    compute = raw.get("compute", {})
    if not isinstance(compute, dict) or not all(isinstance(v, dict) for v in compute.values()):
        raise ctx.err("compute", "expected [compute.<stage>] tables of <session kind> = true/false")
    for stage_name, kinds in compute.items():
        for k, v in kinds.items():
            if k not in _SESSION_KINDS or not isinstance(v, bool):
                raise ctx.err(f"compute.{stage_name}.{k}", f"expected <session kind> = true/false with a kind in "
                                                           f"{list(_SESSION_KINDS)}, got {k} = {v!r}")
    return StudyManifest(name=study["name"], seed=int(study["seed"]), timezone=tmp.timezone,
                         sampling_rate_hz=tmp.sampling_rate_hz, first_lab_date=tmp.first_lab_date,
                         lab_start_local=tmp.lab_start_local, visits=tmp.visits,
                         visit_interval_days=tmp.visit_interval_days, participants=tuple(parts), lab=lab,
                         free_living=fl, sensor_model=sm, stages=MappingProxyType(stages),
                         topics=MappingProxyType(dict(topics)), privacy=privacy, path=path)


@dataclass(frozen=True)
class _StudyHead:
    timezone: str = "Europe/Zurich"
    sampling_rate_hz: float = 100.0
    first_lab_date: _dt.date = _dt.date(2026, 3, 2)
    lab_start_local: str = "09:00"
    visits: int = 1
    visit_interval_days: int = 42
