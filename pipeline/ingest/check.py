"""Ingest, phase 2 of 3: check. What decides whether a read recording may be stored, each refusal one line.

:func:`check_recording` runs the checks of a whole recording after :mod:`stridelab.pipeline.ingest.read` streamed it:
session metadata (:func:`check_session_metadata`: declared schema, pseudonyms, personal data by
:mod:`stridelab.pipeline.privacy`), topic placements and skips (nothing dropped without a record), units (m/s², rad/s:
:func:`check_units`, two independent deg/s checks), rates and clock offsets. The per-block checks (finite values,
stamps, the unit statistics) run earlier, on the reader's threads (:func:`stridelab.pipeline.ingest.series.check_block`);
the clock policy is :mod:`stridelab.pipeline.clock_policy`.
"""
from __future__ import annotations

import json
import re
import zoneinfo
from pathlib import Path

from stridelab.estimators.recording import SESSION_BODY_RANGES, SESSION_KEYS_REQUIRED, SESSION_KINDS
from stridelab.pipeline import privacy
from stridelab.pipeline.formats.mcap_read import ReadResult, encoding_fix
from stridelab.pipeline.formats.rosbag2 import custom_data_of_mcap
from stridelab.pipeline.ingest.model import IngestOptions, IngestRejected, Prepared
from stridelab.pipeline.ingest.series import TopicSeries
from stridelab.pipeline.privacy import screen_session, study_policy
from stridelab.pipeline.pseudonym import SITE_KEYS, pseudonymise
from stridelab.pipeline.session_sources import NO_SESSION, gather_session, placement_for
from stridelab.studies.privacy import shown as _safe_shown
from stridelab.warehouse.store import check_identifier


def check_recording(path: Path, root, res: ReadResult, custom: dict | None, states: dict[str, TopicSeries],
                    options: IngestOptions, out: Prepared) -> tuple[dict, dict, dict]:
    """Everything that decides whether a read recording may be stored, in order: CRC coverage (``--require-crc``),
    session metadata (sources, schema, personal data, plausible values), the series' last slices (their own
    checks: clocks, repeats), reference events, the topics' placements (``--topic-map``, ``--skip-topic``, the
    manifest; every topic not ingested listed with the reason in ``out.skipped_topics``), units, rates and clock
    offsets. Raises :class:`IngestRejected` (or a reader's / series' refusal); returns (session fields,
    (placement, series name) -> series, topic -> (placement, series name))."""
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
    check_plausible(session)
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
            check_units(s)
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
    for e in out.events:
        if "t_ns" not in e or "type" not in e:
            raise IngestRejected("/reference/events: an annotation lacks 't_ns' or 'type'")
    return session, mapped, placement_of


RATE_RANGE_HZ = (5.0, 5000.0)


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


def check_plausible(session: dict) -> None:
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


def check_units(st: TopicSeries) -> None:
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


def redacted(reason: str, path: Path, topics) -> str:
    """A quarantine reason without the file's name or path and without non-standard topic names (a reader's
    message may quote them); the console names the file to the operator."""
    for t in sorted(set(topics), key=len, reverse=True):
        if t and privacy.shown_topic(t) != t:
            reason = reason.replace(t, privacy.shown_topic(t))
    for x in sorted({str(path), str(path.resolve()), str(path.parent), path.name}, key=len, reverse=True):
        if len(x) > 3:
            reason = reason.replace(x, "the file")
    return reason


def unique_events(events: list[dict], notes: list[dict]) -> list[dict]:
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


def _manifest_topics(study: str) -> dict[str, str]:
    """The study manifest's ``[topics]`` table (topic -> placement), {} when there is none."""
    from stridelab.pipeline.config import study_manifest
    t = study_manifest(study).get("topics", {})
    return {str(k): str(v) for k, v in t.items()} if isinstance(t, dict) else {}
