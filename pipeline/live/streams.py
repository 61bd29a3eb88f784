"""A recording (MCAP file or rosbag2 bag directory) as per-sensor arrays, for replay and calibration.

Reuses the ingest's readers (``stridelab.pipeline.formats.mcap_read.iter_blocks``, ``rosbag2.iter_bag_blocks``), so a
file the nightly run accepts is a file the live session can replay, and a corrupt one is refused with the
same one-line reason.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from stridelab.pipeline.formats.mcap_read import McapFormatError, ReadResult, iter_blocks
from stridelab.pipeline.formats.rosbag2 import bag_info, is_bag, iter_bag_blocks
from stridelab.pipeline.session_sources import placement_for


@dataclass
class SensorStream:
    """One IMU: ``t_ns`` sensor stamps, ``log_ns`` host (arrival) times, gyr rad/s, acc m/s², mag µT or None."""
    t_ns: np.ndarray
    log_ns: np.ndarray
    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray | None = None


@dataclass
class Streams:
    """Every IMU of a recording and its ``session`` metadata."""
    sensors: dict[str, SensorStream]
    metadata: dict[str, str] = field(default_factory=dict)

    @property
    def sampling_rate_hz(self) -> float:
        rates = [1e9 / np.median(np.diff(s.t_ns)) for s in self.sensors.values() if len(s.t_ns) > 1]
        if not rates:
            raise ValueError("the recording has no IMU with at least two samples")
        return float(round(np.median(rates), 6))


def read_streams(path: str | Path, topic_map: dict[str, str] | None = None) -> Streams:
    """IMU (and magnetometer) streams per placement of ``path``; ``ValueError`` naming the file when it is not
    a readable recording or holds no IMU."""
    path = Path(path)
    res = ReadResult()
    try:
        if path.is_dir():
            if not is_bag(path):
                raise ValueError(f"{path}: a directory but not a rosbag2 bag (no metadata.yaml); "
                                 f"give an .mcap file or a bag directory")
            info = bag_info(path)
            blocks = iter_bag_blocks(info, res)
        elif path.is_file():
            blocks = iter_blocks(path, res)
        else:
            raise ValueError(f"{path}: no such file; give a recording-format .mcap file or a rosbag2 bag directory")
        parts: dict[tuple[str, str], list] = {}
        for b in blocks:
            pl = placement_for(b.topic, b.kind, topic_map or {})
            if pl is None or pl[1] not in ("imu", "mag"):
                continue
            parts.setdefault(pl, []).append(b)
    except McapFormatError as e:
        raise ValueError(f"{path}: {e}") from None
    sensors = {}
    for (placement, kind), bl in parts.items():
        if kind != "imu":
            continue
        t = np.concatenate([b.t_ns for b in bl])
        log = np.concatenate([b.log_ns for b in bl])
        v = np.concatenate([b.values for b in bl]).astype(np.float64)
        order = np.argsort(t, kind="stable")
        t, log, v = t[order], log[order], v[order]
        keep = np.r_[True, np.diff(t) > 0]           # a repeated stamp is one sample
        mag = None
        mb = parts.get((placement, "mag"))
        if mb:
            tm = np.concatenate([b.t_ns for b in mb])
            vm = np.concatenate([b.values for b in mb]).astype(np.float64) * 1e6     # tesla on the wire -> µT
            idx = np.searchsorted(tm, t[keep])
            ok = (idx < len(tm)) & (tm[np.minimum(idx, len(tm) - 1)] == t[keep])
            if ok.all():
                mag = vm[idx]
        sensors[placement] = SensorStream(t[keep], log[keep], np.ascontiguousarray(v[keep, 0:3]),
                                          np.ascontiguousarray(v[keep, 3:6]), mag)
    if not sensors:
        found = ", ".join(res.found_topics()) or "nothing"
        raise ValueError(f"{path}: no IMU topic (/imu/<placement>) found; found {found}")
    meta = dict(res.metadata.get("session", {}))
    return Streams(sensors, meta)
