"""Reader for Axivity AX3 / AX6 ``.cwa`` files through scikit-digital-health (``skdh.io.ReadCwa``, Pfizer; its
compiled reader follows the Open Movement block layout: 1024-byte ``MD`` header, 512-byte ``AX`` data blocks).

skdh returns acceleration in g, angular velocity in deg/s and (naive local) timestamps in s; the reader converts
to m/s², rad/s and int64 ns. The CWA clock is the device's local time without a zone: the timestamps are taken
as UTC unless ``tz_name`` says where the device was set up.

Before skdh sees the file, :func:`check_cwa_blocks` checks the block structure of Open Movement's ``cwa.h``: size
1024 + 512·k with k ≥ 1, every data block tagged ``AX`` with length 508 and a zero 16-bit word-wise sum (its
checksum), a known rate code. skdh itself keeps a block that fails its checksum (it only prints a warning and
returns altered samples) and aborts the whole process (a Fortran runtime error) on a file without data blocks, so
a damaged file is refused here with one line instead.

scikit-digital-health (with LightGBM, PyWavelets and avro) is an optional extra, not a dependency of StrideLab:
``pip install 'stridelab[cwa]'`` (pyproject ``[project.optional-dependencies] cwa``). Without it, a CWA file that
passes the block checks is refused with a one-line message saying so; nothing is written.
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


def check_cwa_blocks(path: Path, raw: bytes) -> None:
    """Raise ``ValueError`` (one line: file, what is wrong, what to do) unless ``raw`` has the CWA block structure
    (module docstring)."""
    if len(raw) < 1024 or raw[:2] != b"MD":
        raise ValueError(f"{path}: not an Axivity CWA file (no 1024-byte 'MD' header)")
    body = len(raw) - 1024
    if body < 512:
        raise ValueError(f"{path}: CWA file without data blocks (header only); download the recording again")
    if body % 512:
        raise ValueError(f"{path}: CWA file truncated ({body % 512} bytes of a partial 512-byte data block at the "
                         f"end); copy it again from the device")
    blocks = np.frombuffer(raw, dtype="<u2", offset=1024).reshape(-1, 256)
    tag_ok = (blocks[:, 0] == 0x5841) & (blocks[:, 1] == 508)             # "AX", 508 bytes after the 4-byte tag
    if not tag_ok.all():
        raise ValueError(f"{path}: data block {int(np.argmin(tag_ok))} of {len(blocks)} is not an 'AX' block; the "
                         f"file is damaged: copy it again from the device")
    bad = np.flatnonzero(blocks.sum(axis=1, dtype=np.uint64) % 65536)
    if len(bad):
        raise ValueError(f"{path}: {len(bad)} of {len(blocks)} data blocks fail their checksum (first: block "
                         f"{int(bad[0])}); the file is damaged: copy it again from the device")
    rate = raw[1024 + 24]
    if not 6 <= (rate & 0x0F) <= 15:
        raise ValueError(f"{path}: unknown CWA sample-rate code {rate:#04x}; not a recording of an AX3/AX6")


def load_cwa(path: str | Path, tz_name: str | None = None) -> CwaRecording:
    """Read one CWA file; raises ``ValueError`` naming the file and the problem."""
    path = Path(path)
    raw = path.read_bytes() if path.is_file() else b""
    check_cwa_blocks(path, raw)
    device_id = struct.unpack_from("<H", raw, 5)[0]
    import warnings
    try:
        from skdh.io import ReadCwa
    except ImportError:
        raise ValueError(f"{path}: reading Axivity CWA files needs the optional extra 'cwa' (scikit-digital-health): "
                         f"pip install 'stridelab[cwa]'") from None
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
