"""Reader for Axivity AX3 / AX6 ``.cwa`` files through scikit-digital-health (``skdh.io.ReadCwa``, Pfizer; its
compiled reader follows the Open Movement block layout: 1024-byte ``MD`` header, 512-byte ``AX`` data blocks).

skdh returns acceleration in g, angular velocity in deg/s and (naive local) timestamps in s; the reader converts
to m/s², rad/s and int64 ns. The CWA clock is the device's local time without a zone: the timestamps are taken
as UTC unless ``tz_name`` says where the device was set up.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["CwaRecording", "load_cwa"]

G0 = 9.80665


@dataclass(frozen=True)
class CwaRecording:
    """``t_ns`` (N,) int64; ``acc`` (N, 3) m/s²; ``gyr`` (N, 3) rad/s or None (AX3); ``mag`` None;
    ``sampling_rate_hz``; ``device_id`` from the header."""
    t_ns: np.ndarray
    acc: np.ndarray
    gyr: np.ndarray | None
    mag: np.ndarray | None
    sampling_rate_hz: float
    device_id: int


def load_cwa(path: str | Path, tz_name: str | None = None) -> CwaRecording:
    """Read one CWA file; raises ``ValueError`` naming the file and the problem."""
    path = Path(path)
    head = path.read_bytes()[:1024] if path.is_file() else b""
    if len(head) < 1024 or head[:2] != b"MD":
        raise ValueError(f"{path}: not an Axivity CWA file (no 1024-byte 'MD' header)")
    device_id = struct.unpack_from("<H", head, 5)[0]
    import warnings
    from skdh.io import ReadCwa
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            d = ReadCwa(ext_error="raise").predict(file=str(path), tz_name=tz_name)
        except Exception as e:  # noqa: BLE001 - skdh's C reader raises several types for a damaged file
            raise ValueError(f"{path}: the CWA reader failed ({str(e).splitlines()[0] if str(e) else type(e).__name__})") from None
    t = np.asarray(d["time"], dtype=np.float64)
    acc = np.asarray(d["accel"], dtype=np.float64) * G0
    if len(t) < 2:
        raise ValueError(f"{path}: no samples in the data blocks")
    gyr = np.deg2rad(np.asarray(d["gyro"], dtype=np.float64)) if "gyro" in d else None
    t_ns = np.rint(t * 1e9).astype(np.int64)
    return CwaRecording(t_ns=t_ns, acc=acc, gyr=gyr, mag=None, sampling_rate_hz=float(d["fs"]), device_id=device_id)
