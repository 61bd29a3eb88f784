"""Open Sound Control 1.0 packets (messages and bundles) and the x-io NGIMU ``/sensors`` message.

OSC 1.0 (opensoundcontrol.org spec 1.0): every field is big-endian and padded to 4 bytes; a message is an
address string, a type-tag string starting with ``,`` and the arguments (``i`` int32, ``f`` float32, ``s``
string, ``b`` blob, ``h`` int64, ``d`` float64, ``t`` time tag, ``T``/``F``/``N``/``I`` without data); a
bundle is ``#bundle``, a 64-bit NTP time tag (seconds since 1900 + 2^-32 fractions) and elements each
prefixed by their int32 size (nested bundles allowed).

NGIMU (x-io Technologies, user manual, "Sensors" message): ``/sensors`` carries ten float32 arguments,
gyroscope x, y, z (°/s), accelerometer x, y, z (g), magnetometer x, y, z (µT), barometer (hPa); the device
sends its messages inside bundles time-tagged by its (synchronisable) clock. :func:`ngimu_samples` converts
them to the recording format's units (rad/s, m/s², µT).
"""
from __future__ import annotations

import struct

import numpy as np

STANDARD_GRAVITY = 9.80665
NTP_EPOCH_OFFSET_S = 2208988800          # 1900-01-01 -> 1970-01-01
IMMEDIATELY = 1                           # the special time tag "now"


class OscError(ValueError):
    pass


def _string(buf: bytes, p: int) -> tuple[str, int]:
    end = buf.find(b"\0", p)
    if end < 0:
        raise OscError("unterminated OSC string")
    return buf[p:end].decode("ascii", "replace"), (end + 4) & ~3


def parse_message(buf: bytes) -> tuple[str, list]:
    """(address, arguments) of one OSC message."""
    addr, p = _string(buf, 0)
    if not addr.startswith("/"):
        raise OscError(f"not an OSC message (address {addr[:20]!r})")
    if p >= len(buf):
        return addr, []
    tags, p = _string(buf, p)
    if not tags.startswith(","):
        raise OscError("OSC type tag string must start with ','")
    args = []
    for t in tags[1:]:
        if t == "f":
            args.append(struct.unpack_from(">f", buf, p)[0]); p += 4
        elif t == "i":
            args.append(struct.unpack_from(">i", buf, p)[0]); p += 4
        elif t == "d":
            args.append(struct.unpack_from(">d", buf, p)[0]); p += 8
        elif t in ("h", "t"):
            args.append(struct.unpack_from(">q" if t == "h" else ">Q", buf, p)[0]); p += 8
        elif t == "s":
            s, p = _string(buf, p); args.append(s)
        elif t == "b":
            n = struct.unpack_from(">i", buf, p)[0]; args.append(buf[p + 4:p + 4 + n]); p += 4 + ((n + 3) & ~3)
        elif t in "TFNI":
            args.append({"T": True, "F": False, "N": None, "I": float("inf")}[t])
        else:
            raise OscError(f"unsupported OSC type tag {t!r}")
        if p > len(buf):
            raise OscError("OSC message shorter than its type tags say")
    return addr, args


def parse_packet(buf: bytes, timetag: int | None = None) -> list[tuple[int | None, str, list]]:
    """Every message of a packet as (time tag or None, address, arguments); bundles flattened."""
    if buf.startswith(b"#bundle\0"):
        if len(buf) < 16:
            raise OscError("OSC bundle shorter than its header")
        tt = struct.unpack_from(">Q", buf, 8)[0]
        out, p = [], 16
        while p + 4 <= len(buf):
            n = struct.unpack_from(">i", buf, p)[0]
            if n <= 0 or p + 4 + n > len(buf):
                raise OscError("OSC bundle element size out of range")
            out += parse_packet(buf[p + 4:p + 4 + n], tt)
            p += 4 + n
        return out
    addr, args = parse_message(buf)
    return [(timetag, addr, args)]


def timetag_to_ns(tt: int) -> int:
    """NTP time tag -> ns since 1970 (UTC)."""
    sec, frac = tt >> 32, tt & 0xFFFFFFFF
    return (sec - NTP_EPOCH_OFFSET_S) * 1_000_000_000 + (frac * 1_000_000_000 >> 32)


def ns_to_timetag(ns: int) -> int:
    sec, rem = divmod(int(ns), 1_000_000_000)
    return ((sec + NTP_EPOCH_OFFSET_S) << 32) | ((rem << 32) // 1_000_000_000)


def ngimu_samples(packet: bytes) -> list[tuple[int | None, np.ndarray, np.ndarray, np.ndarray]]:
    """(stamp ns or None, gyr rad/s, acc m/s², mag µT) of every ``/sensors`` message of a packet; other
    addresses are skipped. ``OscError`` when a ``/sensors`` message does not carry ten numbers."""
    out = []
    for tt, addr, args in parse_packet(packet):
        if addr != "/sensors":
            continue
        if len(args) < 9 or not all(isinstance(a, (int, float)) for a in args[:9]):
            raise OscError(f"/sensors message with {len(args)} arguments, expected 10 numbers (NGIMU)")
        v = np.asarray(args[:9], dtype=np.float64)
        stamp = None if tt is None or tt == IMMEDIATELY else timetag_to_ns(tt)
        out.append((stamp, np.deg2rad(v[0:3]), v[3:6] * STANDARD_GRAVITY, v[6:9]))
    return out


# ---- writing (tests and the bench's device simulator send real-format packets) ------------------------
def _pad(b: bytes) -> bytes:
    return b + b"\0" * (4 - len(b) % 4)


def encode_message(address: str, args) -> bytes:
    tags, data = ",", b""
    for a in args:
        if isinstance(a, float):
            tags += "f"; data += struct.pack(">f", a)
        elif isinstance(a, int):
            tags += "i"; data += struct.pack(">i", a)
        elif isinstance(a, str):
            tags += "s"; data += _pad(a.encode())
        else:
            raise TypeError(f"cannot encode {type(a).__name__} as OSC")
    return _pad(address.encode()) + _pad(tags.encode()) + data


def encode_bundle(timetag: int, elements: list[bytes]) -> bytes:
    return b"#bundle\0" + struct.pack(">Q", timetag) + b"".join(struct.pack(">i", len(e)) + e for e in elements)


def ngimu_sensors_bundle(t_ns: int, gyr_rad_s, acc_m_s2, mag_ut, baro_hpa: float = 1013.25) -> bytes:
    """A bundle as an NGIMU sends it: one ``/sensors`` message (°/s, g, µT, hPa) time-tagged ``t_ns``."""
    g = np.rad2deg(np.asarray(gyr_rad_s, float))
    a = np.asarray(acc_m_s2, float) / STANDARD_GRAVITY
    m = np.asarray(mag_ut, float)
    return encode_bundle(ns_to_timetag(t_ns), [encode_message("/sensors", [float(x) for x in (*g, *a, *m, baro_hpa)])])
