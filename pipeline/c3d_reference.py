"""``stridelab import c3d``: optical markers of a C3D file as the reference of a recording (DESIGN.md "Recording
format": a C3D file beside the recording is an accepted alternative for optical markers).

``stridelab import c3d markers.c3d --recording walk.mcap --segment foot_left=LHEE,LTOE,LMT5 [--offset-s S]``
writes one MCAP into the inbox, ``<recording>+c3d-<hash>.mcap`` (file names are not kept: keyed hashes of them,
:func:`stridelab.pipeline.privacy.stored_name`):

* every record of the recording unchanged: its channels and messages (log times and header stamps as they were,
  topics StrideLab does not decode included), its metadata records and attachments;
* per ``--segment PLACEMENT=M1[,M2,M3]`` a topic ``/reference/pose/<placement>`` (``geometry_msgs/msg/PoseStamped``,
  CDR, ``frame_id`` ``c3d_lab``), one message per marker frame: position = marker M1 (the point whose path gives
  stride lengths and foot trajectories, e.g. the heel), orientation = the rigid cluster M1-M2-M3 (x = M1→M2,
  z = x × M1→M3, y = z × x, :func:`stridelab.pipeline.formats.c3d.cluster_orientation`), NaN with one marker or while a
  marker is occluded (C3D residual < 0 or all-zero coordinates);
* the ``session`` record of the recording plus ``reference`` (which file and markers, for the Accuracy page) and
  ``reference_frame = segment_lab`` (a marker cluster in the lab frame: the orientation stage estimates the
  sensor's mounting on the segment and the lab's heading before scoring).

Units: ``POINT:UNITS`` (mm, cm, m) converted to metres. Lab frame: z up, as in most gait labs; ``--up y`` for a
y-up capture volume (rotated +90° about x: (x, y, z) → (x, −z, y)).

Clocks: the C3D has no wall clock. Frame i of the file (i = 0 the first frame stored, whatever the capture's
``first_frame``) is stamped ``t_imu0 + offset_s + i / rate``, where ``t_imu0`` is the earliest ``header.stamp`` of
the recording's ``/imu/*`` topics and ``offset_s`` (default 0: capture and IMUs started by one trigger) the time of
the C3D's first frame after the first IMU sample (negative: the capture started first). Frames outside the
recording's span are kept (the stages score only where both exist); a C3D that does not overlap the recording at
all is refused.

The output holds the same samples as the recording: put it in the inbox *instead of* the recording, or, when the
recording is already ingested, run ``stridelab run --replace <output>`` so it supersedes it.
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stridelab.pipeline.formats import ros2_cdr
from stridelab.pipeline.temp_names import temporary_name

POSE_SCHEMA = "geometry_msgs/msg/PoseStamped"
FRAME_ID = "c3d_lab"


class C3DImportRejected(ValueError):
    """One line: file, what is wrong, what to do."""


@dataclass(frozen=True)
class Segment:
    placement: str
    markers: tuple[str, ...]


def _output_name(recording: Path, c3d: Path) -> str:
    """``<recording>+c3d-<keyed hash of the C3D's name>.mcap``: the recording's stem when StrideLab gave it (an
    importer's ``xio-f<hash>``), else a keyed hash of it too (file names may hold a participant's name)."""
    from stridelab.pipeline.privacy import name_token
    rec = recording.stem if re.fullmatch(r"[a-z0-9]+-f[a-p]{10}|rec-[a-p]{10}", recording.stem) else \
        "rec-" + name_token(recording.name)
    return f"{rec}+c3d-{name_token(c3d.name)}.mcap"


def reference_text(segments: list[Segment], units: str, rate_hz: float, offset_s: float) -> str:
    """The session's ``reference`` label: the markers of each placement, or (when that would pass the label's
    120 characters, stridelab.pipeline.privacy: many segments) the marker count and the placements or their number."""
    tail = f"; {units} -> m, {rate_hz:g} Hz, offset {offset_s:g} s)"
    text = "C3D markers (" + "; ".join(f"{s.placement} = {'/'.join(s.markers)}" for s in segments) + tail
    n = sum(len(s.markers) for s in segments)
    if len(text) > 120:
        text = f"C3D markers ({n} on " + ", ".join(s.placement for s in segments) + tail
    if len(text) > 120:
        text = f"C3D markers ({n} on {len(segments)} segments" + tail
    return text


def parse_segments(items) -> list[Segment]:
    """``PLACEMENT=M1[,M2,M3]`` options -> segments (raises C3DImportRejected)."""
    out = []
    for it in items:
        pl, sep, labels = str(it).partition("=")
        names = tuple(x.strip() for x in labels.split(",") if x.strip())
        if not sep or not re.fullmatch(r"[a-z][a-z0-9_]*", pl.strip()) or len(names) not in (1, 3):
            raise C3DImportRejected(f"--segment {it!r}: expected PLACEMENT=MARKER or PLACEMENT=M1,M2,M3 "
                                    f"(e.g. --segment foot_left=LHEE,LTOE,LMT5)")
        out.append(Segment(pl.strip(), names))
    if not out:
        raise C3DImportRejected("give at least one --segment PLACEMENT=M1,M2,M3 (e.g. foot_left=LHEE,LTOE,LMT5): "
                                "which markers make the reference of which sensor")
    if len({s.placement for s in out}) != len(out):
        raise C3DImportRejected("--segment: a placement is given twice")
    return out


def segment_poses(markers, segments: list[Segment], up: str = "z") -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """placement -> (pos (N, 3) m, quat (N, 4) [w x y z] segment → lab) from a :class:`MarkerData`."""
    from stridelab.estimators.quaternion import quat_from_matrix
    from stridelab.pipeline.formats.c3d import MarkerData, cluster_orientation
    pos = markers.pos_m
    if up == "y":
        pos = np.stack([pos[..., 0], -pos[..., 2], pos[..., 1]], axis=-1)
    elif up != "z":
        raise C3DImportRejected(f"--up {up!r}: expected z or y")
    md = MarkerData(markers.labels, pos, markers.rate_hz, markers.first_frame, "m")
    out = {}
    for s in segments:
        try:
            p = md.marker(s.markers[0]).copy()
            q = np.full((len(p), 4), np.nan)
            if len(s.markers) == 3:
                R = cluster_orientation(md, s.markers)
                ok = np.isfinite(R).all(axis=(1, 2))
                q[ok] = quat_from_matrix(R[ok])
        except KeyError as e:
            raise C3DImportRejected(f"--segment {s.placement}: {e.args[0]}") from None
        out[s.placement] = (p, q)
    return out


def _imu_start_ns(recording: Path) -> tuple[int, int]:
    """(earliest, latest) header.stamp of the recording's IMU topics, read by the project's own reader."""
    from stridelab.pipeline.formats.mcap_read import McapFormatError, ReadResult, iter_blocks
    lo, hi = None, None
    try:
        for b in iter_blocks(recording, ReadResult()):
            if b.kind == "imu" and len(b.t_ns):
                lo = int(b.t_ns.min()) if lo is None else min(lo, int(b.t_ns.min()))
                hi = int(b.t_ns.max()) if hi is None else max(hi, int(b.t_ns.max()))
    except McapFormatError as e:
        raise C3DImportRejected(f"{recording}: {e}") from None
    if lo is None:
        raise C3DImportRejected(f"{recording}: no /imu/<placement> messages; give the recording the markers "
                                f"belong to")
    return lo, hi


def import_c3d_reference(c3d: Path, recording: Path, inbox: Path, segments: list[Segment], *,
                         offset_s: float = 0.0, up: str = "z") -> Path:
    """Write ``inbox/<recording>+<c3d>.mcap`` (module docstring); raises :class:`C3DImportRejected`."""
    from mcap.reader import make_reader
    from mcap.writer import Writer
    from stridelab.pipeline.formats.c3d import C3DFormatError, read_c3d_markers
    c3d, recording, inbox = Path(c3d), Path(recording), Path(inbox)
    if not recording.is_file() or recording.suffix.lower() != ".mcap":
        raise C3DImportRejected(f"{recording}: --recording must be the recording's .mcap file")
    try:
        markers = read_c3d_markers(c3d)
    except C3DFormatError as e:
        raise C3DImportRejected(f"{c3d}: {e}" if str(c3d) not in str(e) else str(e)) from None
    if not np.isfinite(offset_s):
        raise C3DImportRejected(f"--offset-s {offset_s}: expected a number of seconds")
    poses = segment_poses(markers, segments, up)
    t0, t1 = _imu_start_ns(recording)
    n = markers.pos_m.shape[0]
    t_ref = t0 + np.rint((offset_s + np.arange(n) / markers.rate_hz) * 1e9).astype(np.int64)
    if n == 0 or t_ref[-1] < t0 or t_ref[0] > t1:
        raise C3DImportRejected(f"{c3d}: its {n / markers.rate_hz:.1f} s of markers at --offset-s {offset_s:g} do "
                                f"not overlap the recording's {(t1 - t0) / 1e9:.1f} s; check --offset-s")
    inbox.mkdir(parents=True, exist_ok=True)
    out = inbox / _output_name(recording, c3d)
    tmp = temporary_name(out)
    try:
        with open(recording, "rb") as src, open(tmp, "wb") as dst:
            reader = make_reader(src)
            w = Writer(dst)
            w.start(profile="ros2", library="stridelab import c3d")
            schemas, channels = {}, {}
            taken = set()
            for schema, channel, msg in reader.iter_messages(log_time_order=False):
                if channel.id not in channels:
                    sid = 0
                    if schema is not None:
                        if schema.id not in schemas:
                            schemas[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
                        sid = schemas[schema.id]
                    channels[channel.id] = w.register_channel(channel.topic, channel.message_encoding, sid,
                                                              dict(channel.metadata))
                    taken.add(channel.topic)
                w.add_message(channels[channel.id], msg.log_time, msg.data, msg.publish_time, msg.sequence)
            clash = [f"/reference/pose/{p}" for p in poses if f"/reference/pose/{p}" in taken]
            if clash:
                raise C3DImportRejected(f"{recording}: already has {', '.join(clash)}; give the markers another "
                                        f"--segment placement or start from the recording without them")
            psid = w.register_schema(POSE_SCHEMA, "ros2msg", ros2_cdr.SCHEMAS[POSE_SCHEMA].encode())
            for pl, (p, q) in poses.items():
                cid = w.register_channel(f"/reference/pose/{pl}", "cdr", psid)
                payload = ros2_cdr.encode_pose(t_ref, p, q, FRAME_ID)
                for i in range(n):
                    w.add_message(cid, int(t_ref[i]), payload[i].tobytes(), int(t_ref[i]), i)
            meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            if "session" not in meta:
                raise C3DImportRejected(f"{recording}: no 'session' metadata record; import or ingest it with "
                                        f"--session fields first")
            meta["session"].update({"reference": reference_text(segments, markers.units, markers.rate_hz, offset_s),
                                    "reference_frame": "segment_lab"})
            for name, md in meta.items():
                w.add_metadata(name, md)
            for a in reader.iter_attachments():
                w.add_attachment(a.create_time, a.log_time, a.name, a.media_type, a.data)
            w.finish()
        os.replace(tmp, out)
    except C3DImportRejected:
        raise
    except Exception as e:  # noqa: BLE001 - the mcap library raises several types on a damaged recording
        raise C3DImportRejected(f"{recording}: not a readable MCAP recording "
                                f"({str(e).splitlines()[0] if str(e) else type(e).__name__})") from None
    finally:
        tmp.unlink(missing_ok=True)
    return out
