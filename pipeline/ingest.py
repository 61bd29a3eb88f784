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

from estimators.recording import SESSION_BODY_RANGES, SESSION_KEYS_REQUIRED, SESSION_KINDS
from pipeline import supersede
from pipeline import privacy
from pipeline.privacy import screen_session, study_policy
from studies.privacy import shown as _safe_shown
from pipeline.pseudonym import SITE_KEYS, pseudonymise
from pipeline.formats.mcap_read import McapFormatError, ReadResult, encoding_fix, iter_blocks
from pipeline.formats.rosbag2 import (bag_info, custom_data_of_mcap, iter_bag_blocks, iter_message_compressed_blocks,
                                      split_bag_parts,
                                      message_compression)
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
    source_path: str                         # stored: a keyed hash of the path (pipeline.privacy.stored_path)
    file_name: str                           # stored: a keyed hash of the name (pipeline.privacy.stored_name)
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
    skipped_topics: list[dict] = field(default_factory=list)   # every topic not ingested: {topic, reason}
    #: every topic of the file for the ingest ledger (``ingest_topics``, migration 015): {topic, outcome, placement,
    #: n_samples, reason}, topic names as the catalog keeps them; the outcome as if the file is ingested (commit()
    #: turns every row into the file's outcome when it is refused or a re-export)
    topics: list[dict] = field(default_factory=list)
    crc_verified: bool | None = None         # every message covered by a checked CRC (False: "unverified")
    settings_hash: str = ""                  # with content_hash, the idempotency key (:func:`settings_hash`)
    settings: dict = field(default_factory=dict)
    sample_hash: str = ""                    # XXH3-128 over the decoded samples of every topic (re-export check)
    legacy_sample_hash: str = ""             # their SHA-256 identity of before, when asked for (IngestOptions)
    display_name: str = ""                   # the file's own name, for the console only (never stored)
    console_reason: str = ""                 # the refusal as the operator needs it (topic names as in the file,
                                             # e.g. for --skip-topic); console only, never stored (``reason`` is)


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
    """`` 'value'`` for a refused enum-like value that is safe to repeat (a code that holds no personal data),
    else nothing: reasons never echo what could be personal data."""
    return _safe_shown(value)


@dataclass
class IngestOptions:
    """Per-run choices: ``session`` fields (``--session FIELD=VALUE``) and ``topic_map`` (``--topic-map
    TOPIC=PLACEMENT``) applied to every recording of the run."""
    session: dict[str, str] = field(default_factory=dict)
    topic_map: dict[str, str] = field(default_factory=dict)
    #: topics the user agrees to leave out (``--skip-topic``): listed as skipped, never an error
    skip_topics: list[str] = field(default_factory=list)
    #: refuse a file not covered by CRCs (``--require-crc``, for strict studies)
    require_crc: bool = False
    #: warnings to record with every recording of the run (what ``--recover`` lost, pipeline/recover.py)
    notes: list[str] = field(default_factory=list)
    #: also compute the samples' SHA-256 identity that recordings ingested before the XXH3 one carry (set by
    #: the coordinator, :func:`pipeline.runner.ingest_files`, when the warehouse holds any)
    legacy_sample_hash: bool = False


def ingest_settings(options: "IngestOptions | dict | None") -> dict:
    """The ingest settings that change what a file becomes in the warehouse (docs/integrity.md): the topic map and
    session fields given on the command line and the topics skipped on request. With the file's content they are
    the idempotency key: the same file ingested with other settings is ingested again (superseding)."""
    if isinstance(options, dict):
        options = IngestOptions(**options)
    options = options or IngestOptions()
    return {"topic_map": dict(sorted(options.topic_map.items())), "session": dict(sorted(options.session.items())),
            "skip_topics": sorted(set(options.skip_topics))}


def settings_hash(options: "IngestOptions | dict | None") -> str:
    """SHA-256 (hex) of :func:`ingest_settings`; recordings ingested before it was kept count as the default."""
    return hashlib.sha256(json.dumps(ingest_settings(options), sort_keys=True).encode()).hexdigest()


DEFAULT_SETTINGS_HASH = settings_hash(None)

#: topic words that make a topic without a schema look like IMU or magnetometer data
_IMU_WORDS = re.compile(r"imu|mag|gyro|accel", re.IGNORECASE)


def looks_like_imu(topic: str, schema_name: str) -> bool:
    """Whether a topic StrideLab did not ingest looks like IMU or magnetometer data (then skipping it silently
    would lose a sensor): its schema is ``*/Imu`` or ``*/MagneticField`` in any package or encoding, or it has no
    schema and its name says imu/mag/gyro/accel. (``sensor_msgs/msg/Imu``, ``foxglove.Imu``, ``ImuSample`` in any
    encoding look like IMU data; ``sensor_msgs/msg/Temperature`` on ``/imu/temp`` does not.)"""
    name = re.split(r"[/.:]", schema_name or "")[-1].lower()
    if schema_name:
        return "imu" in name or "magneticfield" in name
    return bool(_IMU_WORDS.search(topic))


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


#: the deg/s check that does not depend on the rate's size (:attr:`TopicSeries.gyro_to_gravity_turn`), set a priori: at least this
#: many quasi-static window pairs, the gyroscope's predicted turn of gravity correlated with the measured one at
#: least this well (in absolute value: the correlation guards against a turn that is only noise), and at least this
#: many times as large (1 in rad/s, 57.3 in deg/s; 7.6 is their geometric mean). Checked, not tuned, on the public recordings
#: (../shared/data: BROAD, gaitmap, PyShoe, Voisard, all in rad/s): ratio 0.17-1.69 (docs/integrity.md "Units"),
#: and on the simulated lab recordings of tests/corpus.py: 1.00 in rad/s, 57.2 in deg/s
GYRO_CHECK_PAIRS = 20
GYRO_CHECK_CORRELATION = 0.5
GYRO_DEG_RATIO = 7.6


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
                             f"the recording format needs rad/s (multiply by pi/180 = 0.0174533 at export)")
    ratio, corr, pairs = st.gyro_to_gravity_turn
    if pairs >= GYRO_CHECK_PAIRS and abs(corr) >= GYRO_CHECK_CORRELATION and ratio >= GYRO_DEG_RATIO:
        raise IngestRejected(f"{st.topic}: the gyroscope turns {ratio:.0f} times as far as the gravity direction seen "
                             f"by the accelerometer (57.3 when the rate is in deg/s): the angular rate looks like "
                             f"deg/s; the recording format needs rad/s (multiply by pi/180 = 0.0174533 at export)")


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
    if path.name == "metadata.yaml":
        raise IngestRejected("metadata.yaml is the index of a rosbag2 bag, not a recording: ingest the bag folder "
                             "that holds it instead")
    with open(path, "rb") as f:
        head = f.read(13)
    if head.startswith(b"#ROSBAG V"):
        raise IngestRejected("a ROS 1 bag, not MCAP: convert it to ROS 2 (`rosbags-convert --src FILE --dst FOLDER`) "
                             "and ingest the folder")
    split = split_bag_parts(path)
    if split:
        raise IngestRejected(split)
    return iter_blocks(path, res, on_block=check_block), None


def _message_compressed(path: Path) -> str | None:
    """After the fast reader refused a single file: its format when its messages are compressed one by one
    (rosbags/rosbag2 ``compression_mode: message``: the reader took compressed bytes for CDR), else None. Asked
    only then, so the common path reads no summary twice."""
    if path.is_dir() or path.suffix == ".db3":
        return None
    from mcap.reader import make_reader
    try:                        # the summary's metadata index only: a file without one (truncated, damaged) is
        with open(path, "rb") as f:    # never scanned again here (the mcap library would, in pure Python)
            r = make_reader(f)
            if r.get_summary() is None:
                return None
            return message_compression({m.name: dict(m.metadata) for m in r.iter_metadata()})
    except Exception:  # noqa: BLE001 - no readable summary: not this case; the first error stands
        return None


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


def prepare(path: str | os.PathLike, root: str | os.PathLike, options: IngestOptions | dict | None = None,
            series_root: str | os.PathLike | None = None) -> Prepared:
    """Decode, validate and store one recording (MCAP file or rosbag2 bag directory); never raises for a
    bad recording (quarantines it). ``series_root``: where the series files go if not under ``root`` (a
    repair's scratch folder, pipeline/verify.py)."""
    with _without_gc_pauses():
        return _prepare(path, root, options, series_root)


def _prepare(path, root, options, series_root=None) -> Prepared:
    path = Path(path)
    if isinstance(options, dict):
        options = IngestOptions(**options)
    options = options or IngestOptions()
    size, mtime = _stat_signature(path)
    out = Prepared(source_path=privacy.stored_path(path), file_name=privacy.stored_name(path), size_bytes=size,
                   mtime_ns=mtime, display_name=path.name, settings_hash=settings_hash(options),
                   settings=ingest_settings(options))
    states: dict[str, TopicSeries] = {}
    res = ReadResult()
    try:
        blocks, custom = _blocks(path, res)
        try:
            _consume(blocks, out, states, options, series_root or root)
        except McapFormatError:
            fmt = _message_compressed(path)
            if fmt is None:
                raise
            for s in states.values():
                s.abort()
            states.clear()
            out.events = []
            res = ReadResult()
            _consume(iter_message_compressed_blocks(path, res, fmt), out, states, options, series_root or root)
        out.content_hash = res.sha256
        out.crc_verified = res.crc_verified
        if options.require_crc and not out.crc_verified:
            raise IngestRejected("the file carries no CRCs (allowed by MCAP, but a changed byte cannot be detected) "
                                 "and --require-crc was given: re-export it with CRCs (the mcap library, mcap_ros2 and "
                                 "rosbag2 write them by default) or ingest it without --require-crc")
        if custom is None:
            custom = custom_data_of_mcap(res.metadata)
        fields, _sources = gather_session(path, res.metadata, custom, options.session)
        if not fields:
            raise IngestRejected(NO_SESSION)
        session = check_session_metadata({"session": fields}, root, out.issues)
        _check_plausible(session)
        out.metadata = session
        out.issues += [{"severity": "warning", "topic": None, "message": m} for m in options.notes]
        for s in states.values():
            s.finish()
        policy = study_policy(session["study"])
        out.events = privacy.screen_events(out.events, policy, out.issues)
        topic_map = {**_manifest_topics(session["study"]), **options.topic_map}
        in_file = {t.topic for t in res.topics.values()}
        for t in sorted(set(options.topic_map) - in_file):
            raise IngestRejected(f"--topic-map names {t[:80]}, which this file does not have (topics found: "
                                 f"{', '.join(res.found_topics()[:8]) or 'none'}); fix the map (a typo would drop "
                                 f"that sensor)")
        skip_req = set(options.skip_topics)
        unmapped_imu: list[str] = []
        mapped: dict[tuple[str, str], TopicSeries] = {}
        placement_of: dict[str, tuple[str, str]] = {}
        for s in states.values():
            pl = placement_for(s.topic, s.kind, topic_map)
            if s.topic in skip_req or pl is None or s.n == 0:
                if s.topic in skip_req:
                    why = "skipped on request (--skip-topic)"
                elif pl is None:
                    out.ignored_topics.append(s.topic)
                    why = (f"{s.kind} topic without a placement (not named /{s.kind}/<placement> and no --topic-map "
                           f"or manifest [topics] entry)")
                    if s.kind in ("imu", "mag"):
                        unmapped_imu.append(s.topic)
                else:
                    why = "no messages"
                out.skipped_topics.append({"topic": s.topic, "reason": why})
                s.abort()
                continue
            if pl in mapped:
                raise IngestRejected(f"topics {privacy.shown_topic(mapped[pl].topic)} and {privacy.shown_topic(s.topic)}"
                                     f" both map to {pl[1]} of placement{_shown(pl[0])}; map only one of them")
            if pl[0] not in privacy.placements(policy):
                raise IngestRejected(f"{privacy.shown_topic(s.topic, policy)} maps to a placement that is not in the study's "
                                     f"vocabulary ({', '.join(privacy.placements(policy))}); map it with --topic-map "
                                     f"TOPIC=PLACEMENT or the study manifest ([topics], [privacy] placements)")
            mapped[pl] = s
            placement_of[s.topic] = pl
        for ti in res.topics.values():                 # topics the reader did not decode, or without messages
            if ti.kind == "events" or ti.topic in states or ti.topic in {d["topic"] for d in out.skipped_topics}:
                continue
            if ti.topic in skip_req:
                why = "skipped on request (--skip-topic)"
            elif ti.kind is None:
                why = (f"{ti.schema_name or 'no schema'} in {ti.message_encoding or 'no'} encoding is not read by "
                       f"StrideLab" + (f" ({encoding_fix(ti.message_encoding)})"
                                       if looks_like_imu(ti.topic, ti.schema_name) and ti.message_encoding != "cdr"
                                       else ""))
                if looks_like_imu(ti.topic, ti.schema_name):
                    unmapped_imu.append(ti.topic)
            else:
                why = "no messages"
            out.skipped_topics.append({"topic": ti.topic, "reason": why})
        imu_placements = {pl for (pl, prefix) in mapped if prefix == "imu"}
        for (pl, prefix), s in mapped.items():
            if prefix == "mag" and pl not in imu_placements:
                raise IngestRejected(f"{s.topic}: magnetometer mapped to placement {pl[:40]}, which has no IMU in "
                                     f"this file; map it to its IMU's placement (--topic-map {s.topic[:80]}=PLACEMENT)")
        out.skipped_topics.sort(key=lambda d: d["topic"])
        imu = [s for s in mapped.values() if s.kind == "imu"]
        if not imu:
            found = ", ".join(privacy.shown_topic(t) for t in res.found_topics()[:8]) or "none"
            raise IngestRejected(f"no IMU topic with samples mapped to a placement (topics found: {found}); "
                                 f"name them /imu/<placement> or map them with --topic-map TOPIC=PLACEMENT "
                                 f"(or a [topics] table in the study manifest)")
        if unmapped_imu:
            t = unmapped_imu[0]
            reason = next(d["reason"] for d in out.skipped_topics if d["topic"] == t)
            raise IngestRejected(f"topic {t[:80]} looks like IMU/magnetometer data but would be skipped ({reason}): "
                                 f"map it with --topic-map {t[:80]}=PLACEMENT, or pass --skip-topic {t[:80]} to "
                                 f"ingest the file without it")
        for s in mapped.values():
            placement = placement_of[s.topic][0]
            if s.kind == "imu":
                _check_units(s)
            rate = s.rate_hz
            if s.kind in ("imu", "mag") and not (RATE_RANGE_HZ[0] <= rate <= RATE_RANGE_HZ[1]):
                raise IngestRejected(f"{s.topic}: sample rate {rate:.2f} Hz is outside "
                                     f"{RATE_RANGE_HZ[0]:g}–{RATE_RANGE_HZ[1]:g} Hz")
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
                                          _series_name(prefix, res.sha256, out.settings_hash))
                           for (placement, prefix), _ in ordered])
        for ((placement, prefix), s), rel in zip(ordered, rels):
            for m in s.warnings():
                out.issues.append({"severity": "warning", "topic": _stored_topic(s.topic, placement, prefix),
                                   "message": m})
            s.writer = None
            out.sensors.append({"topic": _stored_topic(s.topic, placement, prefix), "placement": placement, "kind": s.kind, "n_samples": s.n,
                                "sampling_rate_hz": s.rate_hz, "start_ns": s.t0, "end_ns": s.last_t,
                                "series_path": rel})
            if s.kind == "imu":
                out.n_samples += s.n
        out.start_ns = min(s.t0 for s in imu)
        out.end_ns = max(s.last_t for s in imu)
        out.ignored_topics = sorted({privacy.shown_topic(t) for t in set(out.ignored_topics) | set(res.ignored_topics)})
        by_key = {placement_of[t]: s for t, s in ((s.topic, s) for s in mapped.values())}
        out.sample_hash = sample_hash(by_key)
        if options.legacy_sample_hash:
            out.legacy_sample_hash = legacy_sample_hash(by_key)
        for e in out.events:
            if "t_ns" not in e or "type" not in e:
                raise IngestRejected("/reference/events: an annotation lacks 't_ns' or 'type'")
        out.events = _unique_events(out.events, out.issues)
        out.topics = _topic_rows(out, res)
    except (IngestRejected, McapFormatError, SeriesRejected, SessionSourceError, ValueError) as e:
        for s in states.values():
            s.abort()
        out.status = "quarantined"
        out.console_reason = str(e).splitlines()[0] if str(e) else type(e).__name__
        out.reason = _redacted(out.console_reason, path, list(states) + list(res.found_topics()))
        out.sensors, out.events = [], []
        out.topics = [{"topic": privacy.shown_topic(t), "outcome": "quarantined"} for t in sorted(
            set(states) | {t.topic for t in res.topics.values()} | {d["topic"] for d in out.skipped_topics})]
        if not out.content_hash:
            out.content_hash = _content_hash(path)
    except BaseException:
        for s in states.values():
            s.abort()
        raise
    return out


#: the ledger's topic for a file of which no topic could be read (refused before its channels were known)
WHOLE_FILE = "(whole file)"


def _topic_rows(out: Prepared, res: ReadResult) -> list[dict]:
    """Every topic of an ingested file for the ledger: each ingested series, the reference events, each skipped
    topic with its reason, and any other channel of the file (none is left out without a row)."""
    rows = [{"topic": d["topic"], "outcome": "ingested", "placement": d["placement"], "n_samples": d["n_samples"]}
            for d in out.sensors]
    if out.events:
        rows.append({"topic": "/reference/events", "outcome": "ingested", "n_samples": len(out.events)})
    rows += [{"topic": privacy.shown_topic(d["topic"]), "outcome": "skipped", "reason": d["reason"]}
             for d in out.skipped_topics]
    listed = {d["topic"] for d in out.skipped_topics} | {r["topic"] for r in rows}
    for ti in res.topics.values():
        if ti.topic not in listed and privacy.shown_topic(ti.topic) not in listed:
            rows.append({"topic": privacy.shown_topic(ti.topic), "outcome": "skipped", "reason": "no messages"})
    return sorted(rows, key=lambda r: (r["outcome"] != "ingested", r["topic"]))


def _record_topics(wh: Warehouse, p: Prepared, run_id: str | None, status: str, reason: str = "") -> None:
    """The file's rows of the ingest ledger (migration 015), in the commit's transaction: as prepared when the file
    is ingested, else every topic with the file's outcome and reason."""
    if run_id is None or not wh.has_column("ingest_topics", "outcome"):
        return
    if status == "ingested":
        rows = p.topics
    else:
        rows = [{"topic": r["topic"], "outcome": status, "reason": reason} for r in p.topics] or \
               [{"topic": WHOLE_FILE, "outcome": status, "reason": reason}]
    wh.insert("ingest_topics", [{"run_id": run_id, "content_hash": p.content_hash, "file_name": p.file_name,
                                 "topic": r["topic"], "outcome": r["outcome"], "placement": r.get("placement"),
                                 "n_samples": r.get("n_samples"), "reason": r.get("reason")} for r in rows])


def _stored_topic(topic: str, placement: str, prefix: str) -> str:
    """The topic as the catalog keeps it: a standard name as it is, any other (a mapped topic, which may carry a
    device label or a name) as the standard name of its placement."""
    if privacy.shown_topic(topic) == topic:
        return topic
    if prefix.startswith("range-"):
        return f"/range/{placement}/{prefix[len('range-'):]}"
    return f"/{prefix.replace('reference_pose', 'reference/pose')}/{placement}"


def _redacted(reason: str, path: Path, topics) -> str:
    """A quarantine reason without the file's name or path and without non-standard topic names (a reader's
    message may quote them); the console names the file to the operator."""
    for t in sorted(set(topics), key=len, reverse=True):
        if t and privacy.shown_topic(t) != t:
            reason = reason.replace(t, privacy.shown_topic(t))
    for x in sorted({str(path), str(path.resolve()), str(path.parent), path.name}, key=len, reverse=True):
        if len(x) > 3:
            reason = reason.replace(x, "the file")
    return reason


def _unique_events(events: list[dict], notes: list[dict]) -> list[dict]:
    """Reference events de-duplicated like samples: an annotation repeated exactly (a duplicated chunk, a
    message written twice) is kept once, with a warning."""
    seen, out = set(), []
    for e in events:
        key = json.dumps(e, sort_keys=True, default=str)
        if key not in seen:
            seen.add(key)
            out.append(e)
    if len(out) < len(events):
        notes.append({"severity": "warning", "topic": "/reference/events",
                      "message": f"{len(events) - len(out)} exact duplicate reference events dropped"})
    return out


def _series_name(prefix: str, sha256: str, settings: str) -> str:
    """A series file's name: kind and content hash, and the settings hash when the settings are not the default
    (a re-ingest of the file with other settings writes new files; the old ones stay for the old snapshots)."""
    name = f"{prefix}-{sha256[:16]}"
    return name if settings in ("", DEFAULT_SETTINGS_HASH) else f"{name}-{settings[:8]}"


def _consume(blocks, out: Prepared, states: dict, options: IngestOptions, series_root) -> None:
    for b in blocks:
        if b.kind == "events":
            out.events += [dict(v) for v in b.values]
            continue
        s = states.get(b.topic)
        if s is None:
            s = states[b.topic] = TopicSeries(b.topic, b.kind, Path(series_root), options.legacy_sample_hash)
        s.add(b)


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


def _console(p: Prepared) -> str:
    """How the console names a file: its own name (the operator's; the catalog keeps only a keyed hash of it)."""
    return p.display_name or p.file_name


def stored_settings_hash(con, content_hash: str) -> str:
    """The settings hash a recording was ingested with (the default for recordings from before migration 013)."""
    r = first(con.execute("SELECT settings_hash FROM recordings WHERE content_hash = ?", [content_hash]))
    return (r[0] if r else None) or DEFAULT_SETTINGS_HASH


def _integrity_columns(wh: Warehouse, p: Prepared) -> dict:
    """The recordings columns of migration 013 (none on an older catalog)."""
    if not wh.has_column("recordings", "settings_hash"):
        return {}
    return {"crc_verified": p.crc_verified, "settings_hash": p.settings_hash or DEFAULT_SETTINGS_HASH,
            "ingest_settings": json.dumps(p.settings, sort_keys=True),
            # topic names as the catalog may keep them (a non-standard topic may carry a name: pipeline.privacy)
            "skipped_topics": json.dumps([{**d, "topic": privacy.shown_topic(d["topic"])} for d in p.skipped_topics])
            if p.skipped_topics else None}


def _supersede_same_file(con, p: Prepared, why: str, now) -> str:
    """The same file ingested again (``--replace``, or other ingest settings): the earlier ingest is kept in
    ``superseded_ingests``, its rows go, and its session's stages rerun. Returns the phrase for the report."""
    old = first(con.execute("SELECT settings_hash, ingest_settings, file_name, session_id, n_samples, ingested_at, "
                            "status FROM recordings WHERE content_hash = ?", [p.content_hash]))
    sensors = [dict(zip(("topic", "placement", "kind", "n_samples"), r)) for r in con.execute(
        "SELECT topic, placement, kind, n_samples FROM sensors WHERE content_hash = ? ORDER BY topic",
        [p.content_hash]).fetchall()]
    con.execute("INSERT INTO superseded_ingests VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                [p.content_hash, old[0] or DEFAULT_SETTINGS_HASH, old[1], old[2], old[3], old[4],
                 json.dumps(sensors), old[5], now, f"ingested again with {why}"])
    for t in ("sensors", "recording_issues", "reference_events", "recordings"):
        con.execute(f'DELETE FROM "{t}" WHERE content_hash = ?', [p.content_hash])
    sid = old[3]
    if sid is not None:
        left = first(con.execute("SELECT count(*) FROM recordings WHERE session_id = ? AND status = 'ingested'",
                                 [sid]))[0]
        if left == 0 and sid != p.metadata.get("session"):
            supersede.supersede(con, [], p, {sid})               # the session held only this file
        else:
            con.execute("DELETE FROM stage_state WHERE session_id = ?", [sid])   # same inputs' hash: rerun
            if left:
                supersede.refresh_session_span(con, sid)
    return f"superseding its earlier ingest ({old[6]}, {why})"


@dataclass
class CommitResult:
    status: str          # ingested | duplicate | quarantined
    message: str


def known_hash(wh: Warehouse, path: Path) -> str | None:
    """Content hash of a file (or bag directory) seen before with the same path, size and mtime (no read needed)."""
    size, mtime = _stat_signature(path)
    r = first(wh.con.execute("SELECT content_hash FROM inbox_seen WHERE source_path = ? AND size_bytes = ? AND mtime_ns = ?",
                       [privacy.stored_path(path), size, mtime]))
    return r[0] if r else None


def commit(wh: Warehouse, p: Prepared, replace: bool = False, run_id: str | None = None) -> CommitResult:
    """Write one prepared file's catalog rows in a single transaction (idempotent by content hash); with
    ``run_id``, also the file's topics in the run's ingest ledger (``ingest_topics``).

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
        again = ""
        if prev is not None and wh.has_column("recordings", "settings_hash"):
            if replace or stored_settings_hash(con, p.content_hash) != (p.settings_hash or DEFAULT_SETTINGS_HASH):
                if p.status != "ingested":
                    _record_topics(wh, p, run_id, "quarantined", p.reason)
                    return CommitResult("quarantined", f"{_console(p)}: ingesting it again failed, the earlier "
                                                       f"ingest ({prev[0]}) stays: {p.reason}")
                again = _supersede_same_file(con, p, "--replace" if replace else "other ingest settings", now)
                prev = None
        if prev is not None:
            _record_topics(wh, p, run_id, "duplicate", f"already {prev[0]} (same content and ingest settings)")
            return CommitResult("duplicate", f"{_console(p)}: already {prev[0]} (same content), nothing changed")
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
                          f"ingested again; to correct that recording, rerun with --replace and this file")
                wh.insert("recordings", [{"content_hash": p.content_hash, "file_name": p.file_name,
                                          "source_path": p.source_path, "size_bytes": p.size_bytes,
                                          "status": "reexport", "reason": reason, "sample_hash": p.sample_hash,
                                          "ingested_at": now}])
                _record_topics(wh, p, run_id, "reexport", reason)
                return CommitResult("reexport", f"{_console(p)}: {reason}")
        emptied = supersede.sessions_emptied(con, old)
        shown = p.console_reason if p.status == "quarantined" and p.console_reason else None   # refused by prepare
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
        extra = _integrity_columns(wh, p)
        if p.status == "quarantined":
            wh.insert("recordings", [{"content_hash": p.content_hash, "file_name": p.file_name,
                                      "source_path": p.source_path, "size_bytes": p.size_bytes,
                                      "status": "quarantined", "reason": p.reason, "ingested_at": now, **extra}])
            _record_topics(wh, p, run_id, "quarantined", p.reason)
            return CommitResult("quarantined", f"{_console(p)}: quarantined: {shown or p.reason}")
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
                                  "end_ns": p.end_ns, "n_samples": p.n_samples, "ingested_at": now, **extra,
                                  **({"sample_hash": p.sample_hash} if p.sample_hash else {})}])
        wh.insert("sensors", [dict(r, content_hash=p.content_hash) for r in p.sensors])
        wh.insert("recording_issues", [dict(r, content_hash=p.content_hash) for r in p.issues])
        wh.insert("reference_events", [{
            "content_hash": p.content_hash, "session_id": s["session"], "t_ns": int(e["t_ns"]),
            "end_ns": int(e["end_ns"]) if e.get("end_ns") is not None else None, "type": str(e["type"]),
            "side": e.get("side"), "placement": e.get("placement"), "label": e.get("label"),
            "payload": json.dumps(e, sort_keys=True)} for e in p.events])
        _record_topics(wh, p, run_id, "ingested")
        if superseded or again:
            supersede.refresh_session_span(con, s["session"])
    msg = f"{_console(p)}: ingested {p.n_samples:,} IMU samples into session {s['session']}"
    if again:
        msg += f", {again}"
    if superseded:
        msg += f", superseding {', '.join(superseded)}"
    if p.skipped_topics:
        msg += (f"; {len(p.skipped_topics)} topic{'s' if len(p.skipped_topics) > 1 else ''} skipped: "
                + "; ".join(f"{d['topic']}: {d['reason']}" for d in p.skipped_topics))   # every one (issue #47)
    if p.issues:
        msg += f" ({len(p.issues)} warning{'s' if len(p.issues) > 1 else ''}: {p.issues[0]['message']})"
    return CommitResult("ingested", msg)
