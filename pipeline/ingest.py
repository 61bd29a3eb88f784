"""Ingest: MCAP file -> validated series in the Parquet store + catalog rows (one transaction).

:func:`prepare` runs in a worker process: it streams the file once (decoding, validating and
hashing on the same pass), writes the series files atomically and returns the catalog rows.
:func:`commit` runs in the single writing process. A file that fails any check is quarantined
with a one-line reason; nothing of it reaches the catalog, so it is never half-written.
"""
from __future__ import annotations

import json
import os
import re
import zoneinfo
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pyarrow as pa

from estimators.recording import PLACEMENTS, SESSION_KEYS_REQUIRED, SESSION_KINDS
from pipeline.pseudonym import SITE_KEYS, pseudonymise
from pipeline.formats.mcap_read import Block, McapFormatError, ReadResult, iter_blocks, read_metadata
from warehouse.catalog import first, Warehouse
from warehouse.store import SeriesWriter, check_identifier, series_relpath

GAP_WARN_S = 1.0            # gaps longer than this are recorded as warnings (the data are kept)
RATE_RANGE_HZ = (5.0, 5000.0)
FLUSH_ROWS = 1 << 20
_PERSONAL_KEYS = re.compile(r"(^|_)(name|first_?name|last_?name|surname|email|e_?mail|birth|dob|address|phone)($|_)",
                            re.I)
_EMAIL = re.compile(r"[^@\s]+@[^@\s]+\.[A-Za-z]{2,}")

_SCHEMAS = {
    "imu": pa.schema([("t_ns", pa.int64()), ("log_ns", pa.int64())]
                     + [(c, pa.float64()) for c in ("gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z")]),
    "mag": pa.schema([("t_ns", pa.int64()), ("log_ns", pa.int64())]
                     + [(c, pa.float64()) for c in ("mag_x", "mag_y", "mag_z")]),
    "reference_pose": pa.schema([("t_ns", pa.int64()), ("log_ns", pa.int64())]
                                + [(c, pa.float64()) for c in ("px", "py", "pz", "qw", "qx", "qy", "qz")]),
    "range": pa.schema([("t_ns", pa.int64()), ("log_ns", pa.int64())]
                       + [(c, pa.float64()) for c in ("field_of_view", "min_range_m", "max_range_m", "range_m")]),
}


class IngestRejected(ValueError):
    """The file is quarantined; ``str(err)`` is the one-line reason."""


@dataclass
class Prepared:
    """What a worker hands back to the writer for one file."""
    source_path: str
    file_name: str
    size_bytes: int
    mtime_ns: int
    content_hash: str = ""
    status: str = "ingested"                 # ingested | quarantined
    reason: str = ""
    metadata: dict = field(default_factory=dict)
    sensors: list[dict] = field(default_factory=list)
    issues: list[dict] = field(default_factory=list)
    events: list[dict] = field(default_factory=list)
    start_ns: int | None = None
    end_ns: int | None = None
    n_samples: int = 0
    ignored_topics: list[str] = field(default_factory=list)


def check_session_metadata(meta: dict[str, dict[str, str]], warehouse_root=None) -> dict[str, str]:
    """Validate the ``session`` metadata record and pseudonymise site identifiers (raises IngestRejected)."""
    if "session" not in meta:
        raise IngestRejected("no 'session' metadata record (study, participant, session, kind): "
                             "add it when exporting (DESIGN.md 'Recording format')")
    s = dict(meta["session"])
    if any(s.get(k) for k in SITE_KEYS):
        if not s.get("study"):
            raise IngestRejected("'session' metadata lacks study")
        s.setdefault("participant", "pending")
        try:
            s = pseudonymise(s, warehouse_root)
        except ValueError as e:
            raise IngestRejected(str(e)) from None
    missing = [k for k in SESSION_KEYS_REQUIRED if not s.get(k)]
    if missing:
        raise IngestRejected(f"'session' metadata lacks {', '.join(missing)}")
    for k, v in s.items():
        if _PERSONAL_KEYS.search(k) or _EMAIL.search(str(v)):
            raise IngestRejected(f"'session' metadata field '{k}' looks like personal data (names, e-mail "
                                 f"addresses, birth dates are never stored); export pseudonyms only")
    if s["kind"] not in SESSION_KINDS:
        raise IngestRejected(f"'session' kind '{s['kind']}' is not one of {', '.join(SESSION_KINDS)}")
    try:
        for k in ("study", "participant", "session"):
            check_identifier(s[k], f"session metadata '{k}'")
        if s.get("trial"):
            check_identifier(s["trial"], "session metadata 'trial'")
    except ValueError as e:
        raise IngestRejected(str(e)) from None
    tz = s.get("timezone") or "UTC"
    try:
        zoneinfo.ZoneInfo(tz)
    except (zoneinfo.ZoneInfoNotFoundError, ValueError):
        raise IngestRejected(f"'session' timezone '{tz}' is not an IANA time zone (e.g. Europe/Zurich)") from None
    s["timezone"] = tz
    return s


def _placement_of(topic: str, kind: str) -> tuple[str, str]:
    """(placement, series name prefix) of a recording-format topic."""
    parts = topic.strip("/").split("/")
    if kind == "reference_pose":
        return parts[2] if len(parts) > 2 else "", "reference_pose"
    if kind == "range":
        return parts[1] if len(parts) > 1 else "", f"range-{parts[2] if len(parts) > 2 else 'A'}"
    return parts[1] if len(parts) > 1 else "", kind


class _TopicState:
    """Streaming validation and buffered Parquet writing for one topic."""

    def __init__(self, topic: str, kind: str):
        self.topic, self.kind = topic, kind
        self.placement, self.prefix = _placement_of(topic, kind)
        self.last_t: int | None = None
        self.n = 0
        self.t0: int | None = None
        self.buf: list[Block] = []
        self.buf_rows = 0
        self.writer: SeriesWriter | None = None
        self.dt_medians: list[float] = []
        self.acc_norm_medians: list[float] = []
        self.gyr_p99: list[float] = []
        self.gaps: list[tuple[int, float]] = []
        self.n_nan = 0

    def add(self, b: Block) -> None:
        t = b.t_ns
        if len(t) == 0:
            return
        if self.kind == "range":
            pass        # REP-117: +inf beyond max range, -inf below min, NaN invalid: legitimate readings
        elif self.kind == "reference_pose" and not np.isinf(b.values).any():
            self.n_nan += int(np.isnan(b.values).any(axis=1).sum())      # occluded markers: kept as NaN
        elif not np.isfinite(b.values).all():
            bad = np.flatnonzero(~np.isfinite(b.values).all(axis=1))
            raise IngestRejected(f"{self.topic}: {len(bad)} samples with NaN/inf values (first at sample "
                                 f"{self.n + int(bad[0])}); fix or drop them at export")
        full = t if self.last_t is None else np.concatenate([[self.last_t], t])
        d = np.diff(full)
        if len(d) and d.min() <= 0:
            i = int(np.flatnonzero(d <= 0)[0])
            what = "duplicated timestamp" if d[i] == 0 else "timestamps go backwards"
            at = self.n + i - (0 if self.last_t is None else 1) + 1
            raise IngestRejected(f"{self.topic}: {what} at sample {at} (header.stamp {int(full[i + 1])} ns "
                                 f"after {int(full[i])} ns); the sensor clock must increase strictly")
        if len(d):
            self.dt_medians.append(float(np.median(d[::7])))      # a subsample is plenty for a median
        if self.t0 is None:
            self.t0 = int(t[0])
        if self.kind == "imu":
            sub = b.values[::7]
            gyr, acc = sub[:, :3], sub[:, 3:]
            self.acc_norm_medians.append(float(np.median(np.linalg.norm(acc, axis=1))))
            self.gyr_p99.append(float(np.percentile(np.abs(gyr), 99)))
        if len(d):
            big = np.flatnonzero(d > GAP_WARN_S * 1e9)
            for i in big[:20]:
                self.gaps.append((int(full[i]), float(d[i]) / 1e9))
        self.last_t = int(t[-1])
        self.n += len(t)
        self.buf.append(b)
        self.buf_rows += len(t)

    def table(self) -> pa.Table:
        t = np.concatenate([b.t_ns for b in self.buf])
        log = np.concatenate([b.log_ns for b in self.buf])
        v = np.concatenate([b.values for b in self.buf])
        if self.kind == "mag":
            v = v * 1e6          # tesla on the wire -> µT in the warehouse
        schema = _SCHEMAS[self.kind]
        cols = [pa.array(t), pa.array(log)] + [pa.array(np.ascontiguousarray(v[:, k])) for k in range(v.shape[1])]
        self.buf, self.buf_rows = [], 0
        return pa.Table.from_arrays(cols, schema=schema)

    @property
    def rate_hz(self) -> float:
        return 1e9 / float(np.median(self.dt_medians)) if self.dt_medians else float("nan")


def _check_units(st: _TopicState) -> None:
    acc_med = float(np.median(st.acc_norm_medians))
    if 0.5 < acc_med < 2.0:
        raise IngestRejected(f"{st.topic}: acceleration median norm is {acc_med:.2f}, which looks like g; "
                             f"the recording format needs m/s² (multiply by 9.80665 at export)")
    if acc_med > 200:
        raise IngestRejected(f"{st.topic}: acceleration median norm is {acc_med:.0f}, not m/s² "
                             f"(raw ADC counts or mm/s²?); export calibrated m/s²")
    gyr = float(np.median(st.gyr_p99))
    if gyr > 35.0:
        raise IngestRejected(f"{st.topic}: angular rate 99th percentile is {gyr:.0f}, which looks like deg/s; "
                             f"the recording format needs rad/s")


def prepare(path: str | os.PathLike, root: str | os.PathLike) -> Prepared:
    """Decode, validate and store one MCAP file; never raises for a bad file (quarantines it)."""
    path = Path(path)
    st = path.stat()
    out = Prepared(source_path=str(path.resolve()), file_name=path.name, size_bytes=st.st_size,
                   mtime_ns=st.st_mtime_ns)
    states: dict[str, _TopicState] = {}
    res = ReadResult()
    session: dict | None = None
    try:
        meta = read_metadata(path) if st.st_size else {}
        if meta:
            session = check_session_metadata(meta, root)
        for b in iter_blocks(path, res):
            if b.kind == "events":
                out.events += [dict(v) for v in b.values]
                continue
            s = states.get(b.topic)
            if s is None:
                s = states[b.topic] = _TopicState(b.topic, b.kind)
            s.add(b)
            if s.buf_rows >= FLUSH_ROWS:
                _flush(s, root, session, res, path)
        out.content_hash = res.sha256
        if session is None:
            session = check_session_metadata(res.metadata, root)
        out.metadata = session
        if not any(s.kind == "imu" for s in states.values()):
            raise IngestRejected("no /imu/<placement> topic with samples")
        for s in states.values():
            if s.kind == "imu":
                _check_units(s)
            rate = s.rate_hz
            if s.kind in ("imu", "mag") and not (RATE_RANGE_HZ[0] <= rate <= RATE_RANGE_HZ[1]):
                raise IngestRejected(f"{s.topic}: sample rate {rate:.2f} Hz is outside "
                                     f"{RATE_RANGE_HZ[0]:g}–{RATE_RANGE_HZ[1]:g} Hz")
            if s.kind == "imu" and s.placement not in PLACEMENTS:
                out.issues.append({"severity": "warning", "topic": s.topic,
                                   "message": f"placement '{s.placement}' is not a standard placement"})
            check_identifier(s.placement, f"placement of topic {s.topic}")
        for s in states.values():
            _flush(s, root, session, res, path)
        for s in states.values():
            if s.n_nan:
                out.issues.append({"severity": "warning", "topic": s.topic,
                                   "message": f"{s.n_nan} reference samples without a pose (occlusion), kept as NaN"})
            for t_gap, dur in s.gaps:
                when = datetime.fromtimestamp(t_gap / 1e9, tz=timezone.utc).isoformat(timespec="seconds")
                out.issues.append({"severity": "warning", "topic": s.topic,
                                   "message": f"gap of {dur:.1f} s after {when} (data kept; estimators "
                                              f"treat the two sides as separate segments)"})
            rel = s.writer.commit(s.writer.relpath.replace("-pending.parquet", f"-{res.sha256[:16]}.parquet"))
            out.sensors.append({"topic": s.topic, "placement": s.placement, "kind": s.kind, "n_samples": s.n,
                                "sampling_rate_hz": s.rate_hz, "start_ns": s.t0, "end_ns": s.last_t,
                                "series_path": rel})
            if s.kind == "imu":
                out.n_samples += s.n
        imu = [s for s in states.values() if s.kind == "imu"]
        out.start_ns = min(s.t0 for s in imu)
        out.end_ns = max(s.last_t for s in imu)
        out.ignored_topics = res.ignored_topics
        for e in out.events:
            if "t_ns" not in e or "type" not in e:
                raise IngestRejected("/reference/events: an annotation lacks 't_ns' or 'type'")
    except (IngestRejected, McapFormatError, ValueError) as e:
        for s in states.values():
            if s.writer is not None:
                s.writer.abort()
        out.status = "quarantined"
        out.reason = str(e).splitlines()[0] if str(e) else type(e).__name__
        out.sensors, out.events = [], []
        if not out.content_hash:
            out.content_hash = _sha256(path)
    return out


def _flush(s: _TopicState, root, session, res: ReadResult, path: Path) -> None:
    if not s.buf:
        return
    if session is None:
        raise IngestRejected("no 'session' metadata index; re-export the file with a summary section")
    if s.writer is None:
        # the content hash is known only after the full pass: the file gets its final name
        # (kind + content hash) when it is committed
        rel = series_relpath(session["study"], session["participant"], session["session"], s.placement,
                             f"{s.prefix}-pending")
        s.writer = SeriesWriter(Path(root), rel, _SCHEMAS[s.kind])
    s.writer.write(s.table())


def _sha256(path: Path) -> str:
    import hashlib
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for b in iter(lambda: f.read(1 << 22), b""):
            h.update(b)
    return h.hexdigest()


@dataclass
class CommitResult:
    status: str          # ingested | duplicate | quarantined
    message: str


def known_hash(wh: Warehouse, path: Path) -> str | None:
    """Content hash of a file seen before with the same path, size and mtime (no read needed)."""
    st = path.stat()
    r = first(wh.con.execute("SELECT content_hash FROM inbox_seen WHERE source_path = ? AND size_bytes = ? AND mtime_ns = ?",
                       [str(path.resolve()), st.st_size, st.st_mtime_ns]))
    return r[0] if r else None


def commit(wh: Warehouse, p: Prepared) -> CommitResult:
    """Write one prepared file's catalog rows in a single transaction (idempotent by content hash)."""
    con = wh.con
    now = datetime.now(timezone.utc).replace(tzinfo=None)
    with wh.transaction():
        con.execute("INSERT OR IGNORE INTO inbox_seen VALUES (?, ?, ?, ?)",
                    [p.source_path, p.size_bytes, p.mtime_ns, p.content_hash])
        prev = first(con.execute("SELECT status, reason FROM recordings WHERE content_hash = ?", [p.content_hash]))
        if prev is not None:
            return CommitResult("duplicate", f"{p.file_name}: already {prev[0]} (same content), nothing changed")
        if p.status == "ingested":
            clash = first(con.execute("SELECT content_hash, session_id FROM recordings WHERE file_name = ? "
                                "AND status = 'ingested'", [p.file_name]))
            if clash is not None:
                p.status = "quarantined"
                p.reason = (f"a different file with the same name was ingested before (sha256 {clash[0][:12]}…, "
                            f"session {clash[1]}); rename the file if it is a new recording")
        if p.status == "ingested":
            owner = first(con.execute("SELECT study, participant_id, kind FROM sessions WHERE session_id = ?",
                                      [p.metadata["session"]]))
            if owner is not None and tuple(owner[:2]) != (p.metadata["study"], p.metadata["participant"]):
                p.status = "quarantined"
                p.reason = (f"session id {p.metadata['session']} already belongs to {owner[0]}/{owner[1]}, not "
                            f"{p.metadata['study']}/{p.metadata['participant']}; session ids must be unique")
            elif owner is not None and owner[2] != p.metadata["kind"]:
                p.status = "quarantined"
                p.reason = (f"session {p.metadata['session']} is a '{owner[2]}' session but this recording says kind "
                            f"'{p.metadata['kind']}'; all recordings of a session need the same kind")
        if p.status == "quarantined":
            wh.insert("recordings", [{"content_hash": p.content_hash, "file_name": p.file_name,
                                      "source_path": p.source_path, "size_bytes": p.size_bytes,
                                      "status": "quarantined", "reason": p.reason, "ingested_at": now}])
            return CommitResult("quarantined", f"{p.file_name}: quarantined: {p.reason}")
        s = p.metadata
        con.execute("INSERT OR IGNORE INTO participants VALUES (?, ?)", [s["study"], s["participant"]])
        row = first(con.execute("SELECT study, participant_id, start_ns, end_ns FROM sessions WHERE session_id = ?",
                          [s["session"]]))
        if row is None:
            con.execute("INSERT INTO sessions VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                        [s["session"], s["study"], s["participant"], s["kind"], s.get("protocol"), s["timezone"],
                         p.start_ns, p.end_ns])
        else:
            con.execute("UPDATE sessions SET start_ns = least(start_ns, ?), end_ns = greatest(end_ns, ?) "
                        "WHERE session_id = ?", [p.start_ns, p.end_ns, s["session"]])
        wh.insert("recordings", [{"content_hash": p.content_hash, "file_name": p.file_name,
                                  "source_path": p.source_path, "size_bytes": p.size_bytes, "status": "ingested",
                                  "session_id": s["session"], "trial": s.get("trial"),
                                  "metadata": json.dumps(s, sort_keys=True), "start_ns": p.start_ns,
                                  "end_ns": p.end_ns, "n_samples": p.n_samples, "ingested_at": now}])
        wh.insert("sensors", [dict(r, content_hash=p.content_hash) for r in p.sensors])
        wh.insert("recording_issues", [dict(r, content_hash=p.content_hash) for r in p.issues])
        wh.insert("reference_events", [{
            "content_hash": p.content_hash, "session_id": s["session"], "t_ns": int(e["t_ns"]),
            "end_ns": int(e["end_ns"]) if e.get("end_ns") is not None else None, "type": str(e["type"]),
            "side": e.get("side"), "placement": e.get("placement"), "label": e.get("label"),
            "payload": json.dumps(e, sort_keys=True)} for e in p.events])
    msg = f"{p.file_name}: ingested {p.n_samples:,} IMU samples into session {s['session']}"
    if p.issues:
        msg += f" ({len(p.issues)} warning{'s' if len(p.issues) > 1 else ''}: {p.issues[0]['message']})"
    return CommitResult("ingested", msg)
