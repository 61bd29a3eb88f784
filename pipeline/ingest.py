"""Ingest: MCAP file or rosbag2 bag -> validated series in the Parquet store + catalog rows (one transaction).

:func:`prepare` runs in a worker process: it streams the recording once (decoding, validating and
hashing on the same pass; per-topic clock policy in :mod:`pipeline.ingest_series`; session metadata
sources and topic mapping in :mod:`pipeline.session_sources`), writes the series files atomically and
returns the catalog rows.
:func:`commit` runs in the single writing process. A file that fails any check is quarantined
with a one-line reason; nothing of it reaches the catalog, so it is never half-written.
"""
from __future__ import annotations

import gc
import hashlib
import json
import os
import re
import zoneinfo
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import xxhash

from estimators.recording import PLACEMENTS, SESSION_BODY_RANGES, SESSION_KEYS_REQUIRED, SESSION_KINDS
from pipeline import supersede
from pipeline.privacy import screen_session, study_policy
from studies.privacy import value_problem
from pipeline.pseudonym import SITE_KEYS, pseudonymise
from pipeline.formats.mcap_read import McapFormatError, ReadResult, iter_blocks
from pipeline.formats.rosbag2 import bag_info, custom_data_of_mcap, iter_bag_blocks
from pipeline.ingest_series import (FLUSH_ROWS, GAP_WARN_S, SCHEMAS as _SCHEMAS, SeriesRejected,  # noqa: F401
                                     TopicSeries, check_block)
from pipeline.session_sources import NO_SESSION, SessionSourceError, gather_session, placement_for
from warehouse.catalog import first, Warehouse
from warehouse.store import check_identifier, commit_all, series_relpath

RATE_RANGE_HZ = (5.0, 5000.0)


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
    sample_hash: str = ""                    # XXH3-128 over the decoded samples of every topic (re-export check)
    legacy_sample_hash: str = ""             # their SHA-256 identity of before, when asked for (IngestOptions)


def check_session_metadata(meta: dict[str, dict[str, str]], warehouse_root=None,
                           notes: list[dict] | None = None) -> dict[str, str]:
    """Validate the ``session`` metadata record, pseudonymise site identifiers, refuse personal data and drop
    free text the study does not allow-list (warnings appended to ``notes``); raises IngestRejected."""
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
    try:
        check_identifier(s["study"], "session metadata 'study'")
        s = screen_session(s, study_policy(s["study"]), notes)       # personal data refused, free text dropped
    except ValueError as e:
        raise IngestRejected(str(e).splitlines()[0]) from None
    if s["kind"] not in SESSION_KINDS:
        raise IngestRejected(f"'session' kind{_shown(s['kind'])} is not one of {', '.join(SESSION_KINDS)}")
    tz = s.get("timezone") or "UTC"
    try:
        zoneinfo.ZoneInfo(tz)
    except (zoneinfo.ZoneInfoNotFoundError, ValueError):
        raise IngestRejected(f"'session' timezone{_shown(tz)} is not an IANA time zone name (e.g. Europe/Zurich)") from None
    s["timezone"] = tz
    _check_stage_fields(s)
    return s


#: ``reference_frame`` values (how the orientation stage scores an optical reference pose): ``sensor_enu`` = the
#: reference is the sensor's own orientation in ENU (BROAD: scored as it stands, as ``stridelab bench orientation``
#: does); ``segment_lab`` (the default) = a marker cluster in the lab frame (mounting and lab heading estimated first)
REFERENCE_FRAMES = ("sensor_enu", "segment_lab")


def _check_stage_fields(s: dict) -> None:
    """The session fields stages read (not free text): closed values, refused with one line otherwise."""
    rf = s.get("reference_frame")
    if rf is not None and rf not in REFERENCE_FRAMES:
        raise IngestRejected(f"'session' reference_frame{_shown(rf)} is not one of {', '.join(REFERENCE_FRAMES)}")
    if s.get("repeat_baseline") not in (None, "0", "1"):
        raise IngestRejected("'session' repeat_baseline must be 0 or 1 (1 = one of several baseline sessions)")
    for k, (lo, hi) in SESSION_BODY_RANGES.items():          # numeric body measures (trunk gait, issue #42)
        if s.get(k) is not None:
            try:
                ok = lo <= float(s[k]) <= hi
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise IngestRejected(f"'session' {k} must be a number from {lo} to {hi} (SI units; e.g. "
                                     f"height_m=1.72)")
    ao = s.get("accelerometer_only")
    if ao is not None:
        bad = [p for p in str(ao).split(",") if not re.fullmatch(r"[a-z][a-z0-9_]{0,40}", p.strip())]
        if bad:
            raise IngestRejected("'session' accelerometer_only must be comma-separated placements "
                                 "(e.g. chest,pelvis)")


def _shown(value) -> str:
    """`` 'value'`` for a refused enum-like value that is safe to repeat (a short token that holds no
    personal data), else nothing: reasons never echo what could be personal data."""
    v = str(value)
    ok = re.fullmatch(r"[A-Za-z0-9_/+-]{1,40}", v) and value_problem(v) is None and not _TITLE_WORDS.search(v)
    return f" '{v}'" if ok else ""


_TITLE_WORDS = re.compile(r"[A-Z][a-z]+[_ .-][A-Z][a-z]+$")


@dataclass
class IngestOptions:
    """Per-run choices: ``session`` fields (``--session FIELD=VALUE``) and ``topic_map`` (``--topic-map
    TOPIC=PLACEMENT``) applied to every recording of the run."""
    session: dict[str, str] = field(default_factory=dict)
    topic_map: dict[str, str] = field(default_factory=dict)
    #: also compute the samples' SHA-256 identity that recordings ingested before the XXH3 one carry (set by
    #: the coordinator, :func:`pipeline.runner.ingest_files`, when the warehouse holds any)
    legacy_sample_hash: bool = False


#: IMU clocks whose offsets to the host clock (median log_time - header.stamp) differ by more than
#: this are reported as independent clocks (the multi-IMU stages then align them on log_time)
CLOCK_OFFSET_WARN_S = 0.05


#: plausible ranges of body-segment fields of the session metadata (m); other ``*_length_m`` fields
SEGMENT_RANGES_M = {"height_m": (0.5, 2.5), "thigh_length_m": (0.2, 0.7), "shank_length_m": (0.2, 0.7),
                    "foot_length_m": (0.1, 0.4)}
OTHER_LENGTH_RANGE_M = (0.01, 2.5)
RATE_TOLERANCE = 0.05        # declared sampling_rate_hz vs the rate of the stamps


def _check_plausible(session: dict) -> None:
    """Numbers in the session metadata that the stages use must be numbers in a plausible range."""
    for k, v in session.items():
        if k in SEGMENT_RANGES_M or k.endswith("_length_m") or k == "sampling_rate_hz":
            try:
                x = float(v)
            except (TypeError, ValueError):
                raise IngestRejected(f"session metadata '{k}' is not a number; fix it at export") from None
            lo, hi = (RATE_RANGE_HZ if k == "sampling_rate_hz" else SEGMENT_RANGES_M.get(k, OTHER_LENGTH_RANGE_M))
            if not (lo <= x <= hi):
                raise IngestRejected(f"session metadata '{k}' = {x:g} is outside the plausible range "
                                     f"[{lo:g}, {hi:g}]; fix it at export")


def _check_units(st: TopicSeries) -> None:
    acc_med = st.acc_norm_median
    if 0.5 < acc_med < 2.0:
        raise IngestRejected(f"{st.topic}: acceleration median norm is {acc_med:.2f}, which looks like g; "
                             f"the recording format needs m/s² (multiply by 9.80665 at export)")
    if acc_med > 200:
        raise IngestRejected(f"{st.topic}: acceleration median norm is {acc_med:.0f}, not m/s² "
                             f"(raw ADC counts or mm/s²?); export calibrated m/s²")
    gyr = st.gyr_p99
    if gyr > 35.0:
        raise IngestRejected(f"{st.topic}: angular rate 99th percentile is {gyr:.0f}, which looks like deg/s; "
                             f"the recording format needs rad/s")


def _stat_signature(path: Path) -> tuple[int, int]:
    """(size, mtime) of a file, or of the data files of a bag directory (sum, newest)."""
    if path.is_dir():
        files = [p for p in path.iterdir() if p.is_file()]
        return sum(p.stat().st_size for p in files), max((p.stat().st_mtime_ns for p in files), default=0)
    st = path.stat()
    return st.st_size, st.st_mtime_ns


def _blocks(path: Path, res: ReadResult):
    """(block iterator, rosbag2 custom data) of a recording file or bag directory."""
    if path.is_dir():
        info = bag_info(path)
        return iter_bag_blocks(info, res, on_block=check_block), info.custom_data
    if path.suffix == ".db3":
        raise IngestRejected("a .db3 file is read with its bag directory: ingest the directory that holds "
                             "metadata.yaml")
    return iter_blocks(path, res, on_block=check_block), None


@contextmanager
def _without_gc_pauses():
    """The cyclic garbage collector off while a recording streams through. Each chunk allocates a few
    dozen small objects, which triggered a collection every ~15 chunks, each one walking every object of
    the process (numba and pyarrow bring about a million): 3-5 % of an ingest's CPU in ``perf``. The
    reading path makes no reference cycles, so nothing accumulates; the collector resumes afterwards."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def prepare(path: str | os.PathLike, root: str | os.PathLike, options: IngestOptions | dict | None = None) -> Prepared:
    """Decode, validate and store one recording (MCAP file or rosbag2 bag directory); never raises for a
    bad recording (quarantines it)."""
    with _without_gc_pauses():
        return _prepare(path, root, options)


def _prepare(path, root, options) -> Prepared:
    path = Path(path)
    if isinstance(options, dict):
        options = IngestOptions(**options)
    options = options or IngestOptions()
    size, mtime = _stat_signature(path)
    out = Prepared(source_path=str(path.resolve()), file_name=path.name, size_bytes=size, mtime_ns=mtime)
    states: dict[str, TopicSeries] = {}
    res = ReadResult()
    try:
        blocks, custom = _blocks(path, res)
        for b in blocks:
            if b.kind == "events":
                out.events += [dict(v) for v in b.values]
                continue
            s = states.get(b.topic)
            if s is None:
                s = states[b.topic] = TopicSeries(b.topic, b.kind, Path(root), options.legacy_sample_hash)
            s.add(b)
        out.content_hash = res.sha256
        if custom is None:
            custom = custom_data_of_mcap(res.metadata)
        fields, _sources = gather_session(path, res.metadata, custom, options.session)
        if not fields:
            raise IngestRejected(NO_SESSION)
        session = check_session_metadata({"session": fields}, root, out.issues)
        _check_plausible(session)
        out.metadata = session
        for s in states.values():
            s.finish()
        topic_map = {**_manifest_topics(session["study"]), **options.topic_map}
        mapped: dict[tuple[str, str], TopicSeries] = {}
        placement_of: dict[str, tuple[str, str]] = {}
        for s in states.values():
            pl = placement_for(s.topic, s.kind, topic_map)
            if pl is None or s.n == 0:
                if pl is None:
                    out.ignored_topics.append(s.topic)
                s.abort()
                continue
            if pl in mapped:
                raise IngestRejected(f"topics {mapped[pl].topic} and {s.topic} both map to {pl[1]} of placement "
                                     f"{pl[0]}; map only one of them")
            mapped[pl] = s
            placement_of[s.topic] = pl
        imu = [s for s in mapped.values() if s.kind == "imu"]
        if not imu:
            found = ", ".join(res.found_topics()[:8]) or "none"
            raise IngestRejected(f"no IMU topic with samples mapped to a placement (topics found: {found}); "
                                 f"name them /imu/<placement> or map them with --topic-map TOPIC=PLACEMENT "
                                 f"(or a [topics] table in the study manifest)")
        for s in mapped.values():
            placement = placement_of[s.topic][0]
            if s.kind == "imu":
                _check_units(s)
            rate = s.rate_hz
            if s.kind in ("imu", "mag") and not (RATE_RANGE_HZ[0] <= rate <= RATE_RANGE_HZ[1]):
                raise IngestRejected(f"{s.topic}: sample rate {rate:.2f} Hz is outside "
                                     f"{RATE_RANGE_HZ[0]:g}–{RATE_RANGE_HZ[1]:g} Hz")
            if s.kind == "imu" and placement not in PLACEMENTS:
                out.issues.append({"severity": "warning", "topic": s.topic,
                                   "message": f"placement '{placement}' is not a standard placement"})
            check_identifier(placement, f"placement of topic {s.topic}")
            declared = session.get("sampling_rate_hz")
            if declared and s.kind == "imu" and abs(rate / float(declared) - 1.0) > RATE_TOLERANCE:
                raise IngestRejected(f"{s.topic}: the session metadata declares {float(declared):g} Hz but the "
                                     f"stamps give {rate:.2f} Hz; fix sampling_rate_hz or the time stamps")
        offsets = {s.topic: s.clock_offset_s for s in imu}
        if len(imu) > 1 and max(offsets.values()) - min(offsets.values()) > CLOCK_OFFSET_WARN_S:
            spread = max(offsets.values()) - min(offsets.values())
            out.issues.append({"severity": "warning", "topic": None,
                               "message": f"the IMUs run on independent clocks (their offsets to log_time differ by "
                                          f"{spread:.3f} s): multi-IMU stages align them on log_time and resample "
                                          f"onto one grid"})
        ordered = sorted(mapped.items(), key=lambda kv: kv[1].topic)
        rels = commit_all([s.writer for _, s in ordered],
                          [series_relpath(session["study"], session["participant"], session["session"], placement,
                                          f"{prefix}-{res.sha256[:16]}") for (placement, prefix), _ in ordered])
        for ((placement, prefix), s), rel in zip(ordered, rels):
            for m in s.warnings():
                out.issues.append({"severity": "warning", "topic": s.topic, "message": m})
            s.writer = None
            out.sensors.append({"topic": s.topic, "placement": placement, "kind": s.kind, "n_samples": s.n,
                                "sampling_rate_hz": s.rate_hz, "start_ns": s.t0, "end_ns": s.last_t,
                                "series_path": rel})
            if s.kind == "imu":
                out.n_samples += s.n
        out.start_ns = min(s.t0 for s in imu)
        out.end_ns = max(s.last_t for s in imu)
        out.ignored_topics = sorted(set(out.ignored_topics) | set(res.ignored_topics))
        by_key = {placement_of[t]: s for t, s in ((s.topic, s) for s in mapped.values())}
        out.sample_hash = sample_hash(by_key)
        if options.legacy_sample_hash:
            out.legacy_sample_hash = legacy_sample_hash(by_key)
        for e in out.events:
            if "t_ns" not in e or "type" not in e:
                raise IngestRejected("/reference/events: an annotation lacks 't_ns' or 'type'")
    except (IngestRejected, McapFormatError, SeriesRejected, SessionSourceError, ValueError) as e:
        for s in states.values():
            s.abort()
        out.status = "quarantined"
        out.reason = str(e).splitlines()[0] if str(e) else type(e).__name__
        out.sensors, out.events = [], []
        if not out.content_hash:
            out.content_hash = _content_hash(path)
    except BaseException:
        for s in states.values():
            s.abort()
        raise
    return out


def _manifest_topics(study: str) -> dict[str, str]:
    """The study manifest's ``[topics]`` table (topic -> placement), {} when there is none."""
    from pipeline.config import study_manifest
    t = study_manifest(study).get("topics", {})
    return {str(k): str(v) for k, v in t.items()} if isinstance(t, dict) else {}


def _content_hash(path: Path) -> str:
    """SHA-256 of a file; for a bag directory, of its files' SHA-256 in name order."""
    if path.is_dir():
        import hashlib
        files = sorted(p for p in path.iterdir() if p.is_file())
        return hashlib.sha256("\n".join(_sha256(p) for p in files).encode()).hexdigest()
    return _sha256(path)


#: prefix of the sample hashes (``recordings.sample_hash``) by :func:`sample_hash`; the earlier ones are 64 hex
#: digits of SHA-256 without a prefix (:func:`legacy_sample_hash`)
SAMPLE_HASH_PREFIX = "xxh3-128:"


def sample_hash(series: dict) -> str:
    """Identity of a recording by content: the same samples exported again (another file name, writer,
    chunking, compression or topic names) give the same hash. ``series``: (placement, series name) ->
    TopicSeries; hashed in key order over each series' header stamps and values (XXH3-128 digests).

    It finds re-exports, nothing more: the file's identity (``content_hash``) stays SHA-256 of its bytes,
    which anyone can check with ``sha256sum``. A non-cryptographic 128-bit hash cannot collide by accident
    (2^-128 per pair); a file made to collide on purpose would only be reported as a re-export, not ingested."""
    return SAMPLE_HASH_PREFIX + _combined(xxhash.xxh3_128(), series, lambda s: (s.stamp_digest, s.value_digest))


def legacy_sample_hash(series: dict) -> str:
    """The samples' identity as recordings ingested before :data:`SAMPLE_HASH_PREFIX` carry it (SHA-256 over
    the same fields); needs series created with ``legacy_digest=True``."""
    return _combined(hashlib.sha256(), series, lambda s: s.legacy)


def _combined(h, series: dict, digests) -> str:
    """``h`` over each series' key, kind and its (stamps, values) digests, in key order."""
    for key in sorted(series):
        s = series[key]
        stamps, values = digests(s)
        h.update(f"{key[0]}\0{key[1]}\0{s.kind}\0".encode() + stamps.digest() + values.digest())
    return h.hexdigest()


def has_legacy_sample_hashes(con) -> bool:
    """Whether the catalog holds recordings with a sample hash of before :data:`SAMPLE_HASH_PREFIX`."""
    return first(con.execute("SELECT 1 FROM recordings WHERE sample_hash IS NOT NULL AND NOT starts_with("
                             "sample_hash, ?) LIMIT 1", [SAMPLE_HASH_PREFIX])) is not None


def _sha256(path: Path) -> str:
    import hashlib
    if path.is_dir():
        return _content_hash(path)
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
    """Content hash of a file (or bag directory) seen before with the same path, size and mtime (no read needed)."""
    size, mtime = _stat_signature(path)
    r = first(wh.con.execute("SELECT content_hash FROM inbox_seen WHERE source_path = ? AND size_bytes = ? AND mtime_ns = ?",
                       [str(path.resolve()), size, mtime]))
    return r[0] if r else None


def commit(wh: Warehouse, p: Prepared, replace: bool = False) -> CommitResult:
    """Write one prepared file's catalog rows in a single transaction (idempotent by content hash).

    A file with the samples of an ingested recording is a re-export: recorded, not ingested again. With
    ``replace`` the file supersedes the recordings with its samples or its file name (pipeline/supersede.py)."""
    con = wh.con
    now = datetime.now(timezone.utc).replace(tzinfo=None)
    with wh.transaction():
        con.execute("INSERT OR IGNORE INTO inbox_seen VALUES (?, ?, ?, ?)",
                    [p.source_path, p.size_bytes, p.mtime_ns, p.content_hash])
        prev = first(con.execute("SELECT status, reason FROM recordings WHERE content_hash = ?", [p.content_hash]))
        if prev is not None and replace and prev[0] == "reexport":
            con.execute("DELETE FROM recordings WHERE content_hash = ?", [p.content_hash])   # now deliberate
            prev = None
        if prev is not None:
            return CommitResult("duplicate", f"{p.file_name}: already {prev[0]} (same content), nothing changed")
        if not wh.has_column("recordings", "sample_hash"):
            p.sample_hash = p.legacy_sample_hash = ""   # a catalog before migration 009 (only tests open one
            #                                             without migrating)
        old = supersede.previous_versions(con, p) if p.status == "ingested" and replace else []
        if p.status == "ingested" and not replace and p.sample_hash:
            same = first(con.execute("SELECT file_name, session_id FROM recordings WHERE sample_hash IN (?, ?) "
                                     "AND status = 'ingested'", [p.sample_hash,
                                                                 p.legacy_sample_hash or p.sample_hash]))
            if same is not None:
                reason = (f"same samples as {same[0]} (session {same[1]}), ingested before: a re-export, not "
                          f"ingested again; to correct that recording, rerun with --replace {p.file_name}")
                wh.insert("recordings", [{"content_hash": p.content_hash, "file_name": p.file_name,
                                          "source_path": p.source_path, "size_bytes": p.size_bytes,
                                          "status": "reexport", "reason": reason, "sample_hash": p.sample_hash,
                                          "ingested_at": now}])
                return CommitResult("reexport", f"{p.file_name}: {reason}")
        emptied = supersede.sessions_emptied(con, old)
        if p.status == "ingested" and not old:
            clash = first(con.execute("SELECT content_hash, session_id FROM recordings WHERE file_name = ? "
                                "AND status = 'ingested'", [p.file_name]))
            if clash is not None:
                p.status = "quarantined"
                p.reason = (f"a different file with the same name was ingested before (sha256 {clash[0][:12]}…, "
                            f"session {clash[1]}); rename the file if it is a new recording")
        if p.status == "ingested":
            owner = first(con.execute("SELECT study, participant_id, kind FROM sessions WHERE session_id = ?",
                                      [p.metadata["session"]]))
            if p.metadata["session"] in emptied:
                owner = None              # the session goes away with the recordings this file supersedes
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
        superseded = supersede.supersede(con, old, p, emptied)
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
                                  "end_ns": p.end_ns, "n_samples": p.n_samples, "ingested_at": now,
                                  **({"sample_hash": p.sample_hash} if p.sample_hash else {})}])
        wh.insert("sensors", [dict(r, content_hash=p.content_hash) for r in p.sensors])
        wh.insert("recording_issues", [dict(r, content_hash=p.content_hash) for r in p.issues])
        wh.insert("reference_events", [{
            "content_hash": p.content_hash, "session_id": s["session"], "t_ns": int(e["t_ns"]),
            "end_ns": int(e["end_ns"]) if e.get("end_ns") is not None else None, "type": str(e["type"]),
            "side": e.get("side"), "placement": e.get("placement"), "label": e.get("label"),
            "payload": json.dumps(e, sort_keys=True)} for e in p.events])
        if superseded:
            supersede.refresh_session_span(con, s["session"])
    msg = f"{p.file_name}: ingested {p.n_samples:,} IMU samples into session {s['session']}"
    if superseded:
        msg += f", superseding {', '.join(superseded)}"
    if p.issues:
        msg += f" ({len(p.issues)} warning{'s' if len(p.issues) > 1 else ''}: {p.issues[0]['message']})"
    return CommitResult("ingested", msg)
