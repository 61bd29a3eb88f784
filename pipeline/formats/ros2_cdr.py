"""Vectorised ROS 2 CDR encoding and decoding for the message types of the recording format.

One message per sample is what ROS 2 tools expect, but a per-message Python codec runs at about
14,000 samples/s. Here a whole channel is encoded as one NumPy structured array (all messages of a
channel share one frame_id, hence one byte layout) and decoded by numba kernels that walk the raw
chunk bytes. Layout rules (OMG XCDR1, little endian, encapsulation header ``00 01 00 00``): primitives
aligned to their size relative to the byte after the 4-byte encapsulation header; strings are a
uint32 length (including the terminating NUL) followed by the bytes.
"""
from __future__ import annotations

import numpy as np
from numba import njit

_SEP = "=" * 80 + "\n"
_TIME = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
_HEADER = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
_VEC3 = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
_QUAT = "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"
_POINT = "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n"
_POSE = "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n"

SCHEMAS = {
    "sensor_msgs/msg/Imu": (
        "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n"
        "geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n"
        "geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n"
        + _SEP + _HEADER + _SEP + _TIME + _SEP + _QUAT + _SEP + _VEC3),
    "sensor_msgs/msg/MagneticField": (
        "std_msgs/Header header\ngeometry_msgs/Vector3 magnetic_field\nfloat64[9] magnetic_field_covariance\n"
        + _SEP + _HEADER + _SEP + _TIME + _SEP + _VEC3),
    # as in ROS 2 Jazzy and later (``variance`` added after ``range``)
    "sensor_msgs/msg/Range": (
        "uint8 ULTRASOUND=0\nuint8 INFRARED=1\nstd_msgs/Header header\nuint8 radiation_type\n"
        "float32 field_of_view\nfloat32 min_range\nfloat32 max_range\nfloat32 range\nfloat32 variance\n"
        + _SEP + _HEADER + _SEP + _TIME),
    "geometry_msgs/msg/PoseStamped": (
        "std_msgs/Header header\ngeometry_msgs/Pose pose\n"
        + _SEP + _HEADER + _SEP + _TIME + _SEP + _POSE + _SEP + _POINT + _SEP + _QUAT),
}

#: reference annotations (gait events, activity labels) on ``/reference/events``
ANNOTATION = "stridelab_msgs/msg/Annotation"
SCHEMAS[ANNOTATION] = (
    "# A reference annotation: an instant (end_ns = -1) or an interval, in warehouse time (UTC ns)\n"
    "int64 t_ns\nint64 end_ns\nstring type\nstring side\nstring placement\nstring label\n"
    "# every field of the annotation as a JSON object (fields beyond those above included)\n"
    "string json\n")

#: number of float64 after the header for the all-double message types
N_DOUBLES = {"sensor_msgs/msg/Imu": 37, "sensor_msgs/msg/MagneticField": 12,
             "geometry_msgs/msg/PoseStamped": 7}
#: which doubles the decoder extracts (index into the doubles after the header)
IMU_FIELDS = np.array([13, 14, 15, 25, 26, 27])          # angular_velocity xyz, linear_acceleration xyz
MAG_FIELDS = np.array([0, 1, 2])                          # magnetic_field xyz (tesla)
POSE_FIELDS = np.array([0, 1, 2, 6, 3, 4, 5])             # position xyz, orientation w x y z


def _header_size(frame_id: bytes) -> int:
    """Bytes from payload start to the end of the header's frame_id (NUL included)."""
    return 4 + 4 + 4 + 4 + len(frame_id) + 1


def _align(pos: int, n: int) -> int:
    """Absolute position ``pos`` aligned to ``n`` relative to the byte after the encapsulation header."""
    rel = pos - 4
    return 4 + (rel + n - 1) // n * n


def encode_doubles(schema: str, t_ns: np.ndarray, values: np.ndarray, frame_id: str) -> np.ndarray:
    """Encode messages whose body (after the header) is float64 only; returns ``(N, L)`` uint8.

    ``values`` has shape (N, N_DOUBLES[schema]) in wire order.
    """
    fid = frame_id.encode()
    start = _align(_header_size(fid), 8)
    nd = N_DOUBLES[schema]
    names = ["encap", "sec", "nsec", "slen", "frame", "body"]
    formats = ["(4,)u1", "<i4", "<u4", "<u4", f"S{len(fid) + 1}", f"({nd},)<f8"]
    offsets = [0, 4, 8, 12, 16, start]
    dt = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": start + 8 * nd})
    n = len(t_ns)
    out = np.zeros(n, dtype=dt)
    out["encap"] = (0, 1, 0, 0)
    sec, nsec = np.divmod(np.asarray(t_ns, dtype=np.int64), 1_000_000_000)
    if n and (sec.min() < -2**31 or sec.max() >= 2**31):
        raise ValueError("timestamp outside the int32 seconds range of builtin_interfaces/Time")
    out["sec"] = sec
    out["nsec"] = nsec
    out["slen"] = len(fid) + 1
    out["frame"] = fid
    out["body"] = values
    return out.view(np.uint8).reshape(n, dt.itemsize)


def encode_imu(t_ns, acc, gyr, frame_id: str) -> np.ndarray:
    """sensor_msgs/Imu: orientation unknown (identity, covariance[0] = -1 per REP-145). ``gyr`` None: an
    accelerometer-only device (angular velocity zero with angular_velocity_covariance[0] = -1, REP-145)."""
    n = len(t_ns)
    v = np.zeros((n, 37))
    v[:, 3] = 1.0          # orientation w
    v[:, 4] = -1.0         # orientation_covariance[0] = -1: no orientation estimate
    if gyr is None:
        v[:, 16] = -1.0    # angular_velocity_covariance[0] = -1: no angular velocity
    else:
        v[:, 13:16] = gyr
    v[:, 25:28] = acc
    return encode_doubles("sensor_msgs/msg/Imu", t_ns, v, frame_id)


def encode_mag(t_ns, mag_ut, frame_id: str) -> np.ndarray:
    """sensor_msgs/MagneticField, tesla on the wire (input µT)."""
    v = np.zeros((len(t_ns), 12))
    v[:, 0:3] = np.asarray(mag_ut) * 1e-6
    return encode_doubles("sensor_msgs/msg/MagneticField", t_ns, v, frame_id)


def encode_pose(t_ns, pos, quat_wxyz, frame_id: str) -> np.ndarray:
    """geometry_msgs/PoseStamped (orientation on the wire is x, y, z, w)."""
    q = np.asarray(quat_wxyz)
    v = np.concatenate([np.asarray(pos), q[:, 1:4], q[:, :1]], axis=1)
    return encode_doubles("geometry_msgs/msg/PoseStamped", t_ns, v, frame_id)


def encode_range(t_ns, range_m, min_range, max_range, frame_id: str, field_of_view=0.05,
                 variance=0.0) -> np.ndarray:
    """sensor_msgs/Range (INFRARED) as in ROS 2 Jazzy (five float32, the last ``variance``), aligned to 4."""
    fid = frame_id.encode()
    pos = _header_size(fid)                       # radiation_type (uint8) right after the string
    start = _align(pos + 1, 4)
    dt = np.dtype({"names": ["encap", "sec", "nsec", "slen", "frame", "rad", "f"],
                   "formats": ["(4,)u1", "<i4", "<u4", "<u4", f"S{len(fid) + 1}", "u1", "(5,)<f4"],
                   "offsets": [0, 4, 8, 12, 16, pos, start], "itemsize": start + 20})
    n = len(t_ns)
    out = np.zeros(n, dtype=dt)
    out["encap"] = (0, 1, 0, 0)
    sec, nsec = np.divmod(np.asarray(t_ns, dtype=np.int64), 1_000_000_000)
    out["sec"], out["nsec"], out["slen"], out["frame"], out["rad"] = sec, nsec, len(fid) + 1, fid, 1
    out["f"] = np.stack([np.full(n, field_of_view), np.full(n, min_range), np.full(n, max_range),
                         np.asarray(range_m), np.full(n, variance)], axis=1)
    return out.view(np.uint8).reshape(n, dt.itemsize)


def _cdr_string(out: bytearray, text: str) -> None:
    b = text.encode() + b"\0"
    out += b"\0" * (-(len(out) - 4) % 4)
    out += len(b).to_bytes(4, "little") + b


def encode_annotation(ev: dict) -> bytes:
    """One ``stridelab_msgs/msg/Annotation`` (CDR, little endian)."""
    import json
    out = bytearray(b"\x00\x01\x00\x00")
    end = ev.get("end_ns")
    out += int(ev["t_ns"]).to_bytes(8, "little", signed=True)
    out += int(-1 if end is None else end).to_bytes(8, "little", signed=True)
    for k in ("type", "side", "placement", "label"):
        _cdr_string(out, "" if ev.get(k) is None else str(ev[k]))
    _cdr_string(out, json.dumps(ev, sort_keys=True))
    return bytes(out)


def decode_annotation(raw: bytes) -> dict:
    """The annotation dict of one ``stridelab_msgs/msg/Annotation`` (from its ``json`` field, checked
    against the typed fields); raises ValueError when the message is malformed."""
    import json
    if len(raw) < 20 or raw[:2] != b"\x00\x01":
        raise ValueError("not a little-endian CDR message")
    t_ns = int.from_bytes(raw[4:12], "little", signed=True)
    p = 20
    texts = []
    for _ in range(5):
        p += -(p - 4) % 4
        n = int.from_bytes(raw[p:p + 4], "little")
        if n < 1 or p + 4 + n > len(raw) or raw[p + 3 + n] != 0:
            raise ValueError("string runs past the message")
        texts.append(raw[p + 4:p + 3 + n].decode())
        p += 4 + n
    ev = json.loads(texts[4])
    if not isinstance(ev, dict) or int(ev.get("t_ns", t_ns)) != t_ns or str(ev.get("type", "")) != texts[0]:
        raise ValueError("json field disagrees with the typed fields")
    return ev


# ---- decoding kernels --------------------------------------------------------------------

@njit(cache=True, nogil=True)
def _u32(buf, p):
    return np.uint32(buf[p]) | (np.uint32(buf[p + 1]) << 8) | (np.uint32(buf[p + 2]) << 16) | (np.uint32(buf[p + 3]) << 24)


@njit(cache=True, nogil=True)
def _read_header(buf, p, L):
    """The little-endian encapsulation and ``std_msgs/Header`` of the message at ``p`` (``L`` bytes): (status 0 ok,
    1 big-endian or unknown encapsulation, 2 too short; stamp ns; its nanoseconds field; frame_id length with NUL)."""
    if L < 16 or buf[p] != 0 or buf[p + 1] != 1:
        return (1 if L >= 16 else 2), np.int64(0), np.int64(0), np.int64(0)
    sec = np.int64(np.int32(_u32(buf, p + 4)))
    nsec = np.int64(_u32(buf, p + 8))
    return 0, sec * 1_000_000_000 + nsec, nsec, np.int64(_u32(buf, p + 12))


@njit(cache=True, nogil=True)
def decode_doubles_kernel(buf, starts, lengths, fields, n_doubles, out_t, out_vals_u8, status):
    """Decode header stamp and selected float64 fields of N messages.

    ``buf`` uint8 chunk bytes; ``starts``/``lengths`` payload positions; ``fields`` indices of the
    doubles to extract; ``n_doubles`` float64 after the header in the schema; ``out_vals_u8`` is the
    uint8 view of a float64 (len(fields), N) array (column-major). ``status[i]``: 0 ok, 1 big-endian or unknown
    encapsulation, 2 message too short, 3 payload size not the schema's (up to 3 bytes of end padding
    allowed), 4 nanoseconds >= 1e9.
    """
    nf = fields.shape[0]
    for i in range(starts.shape[0]):
        p = starts[i]
        L = lengths[i]
        code, t_ns, nsec, slen = _read_header(buf, p, L)
        if code:
            status[i] = code
            continue
        out_t[i] = t_ns
        rel = 16 + slen - 4
        body = 4 + (rel + 7) // 8 * 8
        need = body + 8 * n_doubles
        if need > L:
            status[i] = 2
            continue
        if L - need > 3:
            status[i] = 3
            continue
        if nsec >= 1_000_000_000:
            status[i] = 4
            continue
        n = starts.shape[0]
        for k in range(nf):
            src = p + body + 8 * fields[k]
            dst = (k * n + i) * 8                  # column-major: each field's values contiguous
            for b in range(8):
                out_vals_u8[dst + b] = buf[src + b]


@njit(cache=True, nogil=True)
def decode_range_kernel(buf, starts, lengths, n_floats, out_t, out_vals_u8, status):
    """Decode sensor_msgs/Range: stamp and the first four float32 (fov, min, max, range) of
    ``n_floats`` (5 with Jazzy's ``variance``, 4 before); status codes as decode_doubles_kernel."""
    for i in range(starts.shape[0]):
        p = starts[i]
        L = lengths[i]
        code, t_ns, nsec, slen = _read_header(buf, p, L)
        if code:
            status[i] = code
            continue
        out_t[i] = t_ns
        pos = 16 + slen + 1
        rel = pos - 4
        start = 4 + (rel + 3) // 4 * 4
        if start + 4 * n_floats > L:
            status[i] = 2
            continue
        if L - (start + 4 * n_floats) > 3:
            status[i] = 3
            continue
        if nsec >= 1_000_000_000:
            status[i] = 4
            continue
        for b in range(16):
            out_vals_u8[i * 16 + b] = buf[p + start + b]


def decode_doubles(buf: np.ndarray, starts, lengths, fields: np.ndarray, n_doubles: int):
    """Vectorised decode; returns (t_ns int64 (N,), values float64 (N, len(fields)), status uint8 (N,)).

    ``values`` is Fortran-ordered (each column contiguous), which is what the column store wants."""
    n = len(starts)
    t = np.zeros(n, dtype=np.int64)
    cols = np.zeros((len(fields), n), dtype=np.float64)
    status = np.zeros(n, dtype=np.uint8)
    decode_doubles_kernel(buf, starts, lengths, fields.astype(np.int64), n_doubles, t,
                          cols.reshape(-1).view(np.uint8), status)
    return t, cols.T, status


def decode_range(buf: np.ndarray, starts, lengths, variance: bool = True):
    """Vectorised decode of sensor_msgs/Range; values columns fov, min, max, range (float32 -> float64)."""
    n = len(starts)
    t = np.zeros(n, dtype=np.int64)
    vals = np.zeros((n, 4), dtype=np.float32)
    status = np.zeros(n, dtype=np.uint8)
    decode_range_kernel(buf, starts, lengths, 5 if variance else 4, t, vals.reshape(-1).view(np.uint8), status)
    return t, vals.astype(np.float64), status
