"""Reader for APDM Opal HDF5 files, format version 5 (APDM "HDF5 file format", Mobility Lab / Moveo Explorer).

Layout read (v5): ``/Sensors/<case id>/Accelerometer`` (N, 3) m/s², ``Gyroscope`` (N, 3) rad/s, ``Magnetometer``
(N, 3) µT (optional), ``Time`` (N,) uint64 µs since 1970-01-01 UTC; ``/Sensors/<case id>/Configuration`` attributes
``Label 0`` (the monitor label, e.g. ``Right Foot``, ``Lumbar``, ``Sternum``) and ``Sample Rate`` (Hz). Units are
already StrideLab's; times become int64 ns. Labels map to placements by :data:`LABEL_PLACEMENTS` (case and
spaces ignored); an unknown label maps to no placement (the importer refuses the file, or takes ``--placement``
for a single sensor): a label is never taken as a placement.
Older layouts (v3/v4: ``/<case id>/Calibrated/...``) are refused with a line saying so.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["ApdmSensor", "ApdmRecording", "load_apdm", "LABEL_PLACEMENTS"]

LABEL_PLACEMENTS = {
    "rightfoot": "foot_right", "leftfoot": "foot_left", "rightankle": "shank_right", "leftankle": "shank_left",
    "rightshank": "shank_right", "leftshank": "shank_left", "rightthigh": "thigh_right", "leftthigh": "thigh_left",
    "lumbar": "pelvis", "pelvis": "pelvis", "sacrum": "pelvis", "sternum": "chest", "chest": "chest",
}


@dataclass(frozen=True)
class ApdmSensor:
    """One Opal: ``case_id``, ``label`` as stored, ``placement``; ``t_ns`` (N,) int64 UTC; acc m/s², gyr rad/s,
    mag µT or None; ``sampling_rate_hz`` from the configuration."""
    case_id: str
    label: str
    placement: str
    t_ns: np.ndarray
    acc: np.ndarray
    gyr: np.ndarray
    mag: np.ndarray | None
    sampling_rate_hz: float


@dataclass(frozen=True)
class ApdmRecording:
    sensors: list[ApdmSensor]
    t0_ns: int
    format_version: int


def _attr_str(v) -> str:
    if isinstance(v, bytes):
        return v.decode("utf-8", "replace")
    if isinstance(v, np.ndarray):
        return _attr_str(v.ravel()[0]) if v.size else ""
    return str(v)


def placement_of(label: str) -> str:
    """The placement of a monitor label, "" when the label is not in :data:`LABEL_PLACEMENTS` (a label is
    free text, e.g. a participant's name: never taken as a placement)."""
    key = re.sub(r"[^a-z]", "", label.lower())
    return LABEL_PLACEMENTS.get(key, "")


def load_apdm(path: str | Path) -> ApdmRecording:
    """Read every sensor of an APDM v5 file; raises ``ValueError`` naming the file and the problem."""
    import h5py
    path = Path(path)
    try:
        h = h5py.File(path, "r")
    except OSError as e:
        raise ValueError(f"{path}: not an HDF5 file ({str(e).splitlines()[0]})") from None
    with h:
        version = int(np.ravel(h.attrs.get("FileFormatVersion", [0]))[0])
        if "Sensors" not in h:
            raise ValueError(f"{path}: no /Sensors group (file format version {version or 'unknown'}); only the "
                             f"APDM v5 layout is read: re-export it from Mobility Lab / Moveo as HDF5 v5")
        sensors = []
        for case_id in sorted(h["Sensors"]):
            g = h["Sensors"][case_id]
            missing = [k for k in ("Accelerometer", "Gyroscope", "Time") if k not in g]
            if missing:
                raise ValueError(f"{path}: /Sensors/{case_id} lacks {', '.join(missing)}")
            cfg = g["Configuration"].attrs if "Configuration" in g else {}
            label = _attr_str(cfg.get("Label 0", case_id)) or case_id
            t_us = np.asarray(g["Time"][()], dtype=np.int64).ravel()
            acc = np.asarray(g["Accelerometer"][()], dtype=np.float64)
            gyr = np.asarray(g["Gyroscope"][()], dtype=np.float64)
            mag = np.asarray(g["Magnetometer"][()], dtype=np.float64) if "Magnetometer" in g else None
            n = len(t_us)
            for name, x in (("Accelerometer", acc), ("Gyroscope", gyr), ("Magnetometer", mag)):
                if x is not None and x.shape != (n, 3):
                    raise ValueError(f"{path}: /Sensors/{case_id}/{name} has shape {x.shape}, expected ({n}, 3) "
                                     f"like Time")
            rate = cfg.get("Sample Rate")
            fs = float(np.ravel(rate)[0]) if rate is not None else (1e6 / float(np.median(np.diff(t_us))) if n > 1
                                                                      else float("nan"))
            sensors.append(ApdmSensor(case_id, label, placement_of(label), t_us * 1000, acc, gyr, mag, fs))
    if not sensors:
        raise ValueError(f"{path}: /Sensors holds no sensor")
    return ApdmRecording(sensors=sensors, t0_ns=int(min(s.t_ns[0] for s in sensors if len(s.t_ns))),
                         format_version=version)
