"""Personal data kept out of the warehouse, by allow-list (DESIGN.md "Recording format", "Personal data").

* Session metadata is a declared schema (:data:`SCHEMA`): each field the recording format knows has a type
  (identifier, code, closed value, label, number); a study adds fields in its manifest's ``[privacy]``
  (:mod:`stridelab.studies.privacy`: ``free_text_fields``, ``numeric_fields``, ``conditions``). Any other field is dropped
  with a warning, whatever its name (a unit suffix such as ``note_s`` earns nothing) and whatever its value (a
  number too: ``+41791234567``); a value in which the screen finds personal data refuses the recording.
  Text that is kept (labels, allow-listed free text) is screened: names in any script, dates in any common
  form, phone/identity/record numbers, postal and e-mail addresses.
* Placements and reference-event labels come from a controlled vocabulary (:func:`placements`,
  :func:`event_labels`); an unknown placement is refused (map it with ``--topic-map`` or the manifest), an unknown
  label is dropped; event payloads keep their declared keys and numbers.
* File and folder names are never stored: :func:`stored_name` and :func:`stored_path` give keyed hashes of them
  (the content hash is kept beside); the console names the file to the operator.

Refusals raise ``ValueError`` with a reason naming the field and the kind of problem, never the value
(quarantine reasons end up in logs and in the catalog).
"""
from __future__ import annotations

import hashlib
import hmac
import math
import re
from pathlib import Path

from stridelab.estimators.recording import PLACEMENTS, SESSION_BODY_FIELDS, SESSION_DESIGN_FIELDS
from stridelab.pipeline.config import study_manifest
from stridelab.studies.privacy import (PrivacyPolicy, code_problem, identifier_problem, key_problem, privacy_policy,
                             value_problem)

ID_FIELDS = ("participant", "session", "trial")
#: closed values (checked here or, ``kind``, ``timezone``, ``reference_frame``, by stridelab.pipeline.ingest)
ENUMS = {"paretic_side": ("left", "right", "none"), "pseudonymised": ("hmac-sha256",),
         "live_source": ("replay", "ngimu_osc")}        # what fed a `stridelab live` session (pipeline/live/command.py)
#: values of ``condition`` every study knows (a study adds its own with ``[privacy] conditions``)
CONDITIONS = ("healthy", "hemiparetic", "stroke", "parkinson", "multiple_sclerosis", "osteoarthritis",
              "amputee", "cerebral_palsy", "elderly", "unknown")
#: numbers the stages read (plausible ranges checked by stridelab.pipeline.ingest) or an importer records (``counts_per_g``:
#: the UCI conversion used); ``*_length_m`` too
NUMERIC_FIELDS = tuple(dict.fromkeys(("height_m", "mass_kg", "sampling_rate_hz", "thigh_length_m", "shank_length_m",
                                     "foot_length_m", "counts_per_g", *SESSION_BODY_FIELDS, *SESSION_DESIGN_FIELDS)))   # body measures, repeat_baseline (#42; ranges: ingest)
#: the session schema of the recording format: field -> type
SCHEMA = {"study": "identifier", "participant": "identifier", "session": "identifier", "trial": "identifier",
          "kind": "closed", "timezone": "closed", "reference_frame": "closed", "accelerometer_only": "closed",
          "paretic_side": "enum", "pseudonymised": "enum", "live_source": "enum", "condition": "condition", "protocol": "label",
          "reference": "label"}   # reference: which reference system an importer recorded ("scored against")
#: reference-event labels every study knows (activity classes, calibration windows, importer annotations)
EVENT_LABELS = ("sitting", "standing", "walking", "stairs", "lying", "level_walking", "stairs_up", "stairs_down",
                "non_wear", "unscored", "quiet_standing", "hip_flexion_extension", "straight_walking",
                "labelled strides", "movement", "trial", "turning", "transition", "shuffling",
                "INDIP", "Stereophoto")                 # Mobilise-D reference systems (#42: trunk_gait scores on INDIP)
#: numeric keys of a reference event: codes and counts, and the Mobilise-D walking-bout / turn values (#42)
EVENT_NUMBERS = ("code", "repetitions", "steps", "n_strides", "cadence_spm", "stride_length_m", "walking_speed_m_s",
                 "angle_deg")          # steps: the simulator's true step count of an activity bout
#: keys of a reference event that are stored; ``source`` is screened text, the rest closed or numbers
EVENT_KEYS = ("t_ns", "end_ns", "type", "side", "placement", "label", "source", *EVENT_NUMBERS)
EVENT_SIDES = ("left", "right", "both", None)
_LABEL_MAX = 120


def study_policy(study: str) -> PrivacyPolicy:
    """The study's ``[privacy]`` policy (the default when the study has no manifest or no table)."""
    return privacy_policy(study_manifest(study).get("privacy"), f"study {study}: [privacy]")


def placements(policy: PrivacyPolicy) -> tuple[str, ...]:
    """The placement vocabulary: DESIGN.md's plus the study's ``[privacy] placements``."""
    base = tuple(PLACEMENTS) + tuple(p for p in ("lower_back",) if p not in PLACEMENTS)    # DESIGN.md's list
    return base + tuple(p for p in policy.placements if p not in base)


def event_labels(policy: PrivacyPolicy) -> tuple[str, ...]:
    return EVENT_LABELS + policy.event_labels


def shown_field(key: str) -> str:
    """A field name as a reason may show it: the name when it is a code (``geburtsdatum``, ``note_s``), else a
    stand-in (a key can be anything: ``Jane Doe``)."""
    return f"'{key}'" if code_problem(key) is None else "(a field whose name is not shown)"


def _plain_number(v) -> bool:
    """A plain decimal number that does not look like a phone, identity or record number."""
    s = str(v).strip()
    if not re.fullmatch(r"-?(?:[1-9]\d{0,4}|0)(?:\.\d{1,6})?", s):
        return False
    return math.isfinite(float(s))


def _text_problem(v: str, policy: PrivacyPolicy) -> str | None:
    if "\n" in v or "\r" in v or any(ord(c) < 32 for c in v):
        return "it holds line breaks or control characters"
    if len(v) > _LABEL_MAX:
        return f"it is longer than {_LABEL_MAX} characters"
    return value_problem(v, terms=policy.terms)


def _refuse(key: str, why: str) -> ValueError:
    return ValueError(f"'session' metadata field {shown_field(key)} looks like personal data: {why}; names, e-mail "
                      f"and postal addresses, birth dates, phone and record numbers are never stored: export "
                      f"pseudonyms only")


def screen_session(s: dict, policy: PrivacyPolicy, notes: list[dict] | None = None) -> dict:
    """The session metadata ``s`` checked against the declared schema: personal data refused (ValueError),
    fields the schema and the study do not declare dropped (a warning in ``notes``). Returns what to store."""
    for k in ID_FIELDS:
        if s.get(k) is not None:
            why = identifier_problem(s[k], policy)
            if why:
                raise ValueError(f"session metadata '{k}' {why}")
    out, dropped = {}, []
    for k, v in s.items():
        v = str(v)
        kind = SCHEMA.get(k)
        if kind is None and (k in NUMERIC_FIELDS or k.endswith("_length_m") or k in policy.numeric_fields):
            kind = "number"
        if kind is None and k in policy.free_text_fields:
            kind = "text"
        if kind is None:
            why = key_problem(k) or _text_problem(v, policy)
            if why:                                 # a personal value in an undeclared field: the export is wrong
                raise _refuse(k, why)
            dropped.append(k)
            continue
        if kind in ("identifier", "closed"):
            out[k] = v
        elif kind == "enum":
            if v not in ENUMS[k]:
                raise ValueError(f"'session' {k} is not one of {', '.join(ENUMS[k])}")
            out[k] = v
        elif kind == "condition":
            if v not in CONDITIONS + policy.conditions:
                why = _text_problem(v, policy)
                if why:
                    raise _refuse(k, why)
                raise ValueError(f"'session' condition is not in the study's vocabulary ({', '.join(CONDITIONS)}, "
                                 f"or add it to [privacy] conditions of the study manifest)")
            out[k] = v
        elif kind == "number":
            if not _plain_number(v):
                why = value_problem(v)
                if why:
                    raise _refuse(k, why)
                raise ValueError(f"session metadata {shown_field(k)} is not a number (a plain decimal); fix it at export")
            out[k] = v
        else:                                       # label (protocol) and allow-listed free text
            why = _text_problem(v, policy)
            if why:
                raise _refuse(k, why)
            out[k] = v
    for k in dropped if notes is not None else ():
        notes.append({"severity": "warning", "topic": None,
                      "message": f"metadata field {shown_field(k)} dropped: the session schema does not declare it "
                                 f"(a study declares more with [privacy] free_text_fields or numeric_fields)"})
    return out


def screen_events(events: list[dict], policy: PrivacyPolicy, notes: list[dict] | None = None) -> list[dict]:
    """Reference events keeping only what the vocabulary allows: type a code, side and placement closed values,
    label from :func:`event_labels` (else dropped), ``source`` screened text (else dropped), the keys of
    :data:`EVENT_NUMBERS` kept as plain numbers (floats rounded to 6 decimals; None kept; a number that could be a
    phone or record number dropped); other keys dropped. Raises ValueError (one line, no value) for an event whose type is not a code."""
    pls, labels = placements(policy), event_labels(policy)
    out, n_drop = [], 0
    for e in events:
        if "type" in e and code_problem(e.get("type", "")) is not None and not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,39}",
                                                                             str(e.get("type", ""))):
            raise ValueError("/reference/events: an annotation's 'type' is not a code (letters, digits, '_'); "
                             "free text goes nowhere")
        if "type" in e and value_problem(str(e["type"])):
            raise ValueError("/reference/events: an annotation's 'type' looks like personal data")
        k = {x: e[x] for x in ("t_ns", "end_ns", "type") if x in e}
        for key, val in e.items():
            if key in ("t_ns", "end_ns", "type"):
                continue
            keep = False
            if key == "side":
                keep = val in EVENT_SIDES
            elif key == "placement":
                keep = val is None or val in pls
            elif key == "label":
                keep = val is None or val in labels
            elif key == "source":
                keep = isinstance(val, str) and _text_problem(val, policy) is None
            elif key in EVENT_NUMBERS:
                if val is None:                 # a value the reference does not give (NaN in the export)
                    keep = True
                elif isinstance(val, (int, float)) and not isinstance(val, bool) and math.isfinite(val):
                    val = round(val, 6) if isinstance(val, float) else val     # no digit run hides in the decimals
                    keep = _plain_number(val)
            if keep:
                k[key] = val
            else:
                n_drop += 1
        out.append(k)
    if n_drop and notes is not None:
        notes.append({"severity": "warning", "topic": "/reference/events",
                      "message": f"{n_drop} reference-event value{'s' if n_drop > 1 else ''} dropped: labels and "
                                 f"placements come from the study's vocabulary, other keys hold numbers or codes "
                                 f"([privacy] event_labels / placements of the study manifest add values)"})
    return out


# ---- file and folder names ----------------------------------------------------------------------

def _name_key() -> bytes:
    """The key of stored names: the pseudonymisation key when it exists (outside the warehouse; then a stored
    name cannot be linked to a guessed file name), else a fixed domain string (a stored name then confirms only
    an exact guess of the whole name)."""
    from stridelab.pipeline.pseudonym import key_path
    try:
        text = key_path().read_text().strip()
    except OSError:
        text = ""
    return (text if len(text) >= 32 else "stridelab-stored-name-v1").encode()


def _digest(what: str, text: str) -> str:
    return hmac.new(_name_key(), f"{what}\0{text}".encode("utf-8", "surrogateescape"), hashlib.sha256).hexdigest()


def stored_name(path: str | Path) -> str:
    """The name a recording file or bag folder is stored under: ``rec-`` + 16 hex digits of a keyed hash of its
    name + the suffix when it is ``.mcap`` / ``.db3`` (the same name gives the same stored name: ``--replace`` and
    the same-name check keep working)."""
    name = Path(path).name
    suffix = Path(name).suffix.lower() if Path(name).suffix.lower() in (".mcap", ".db3") else ""
    return f"rec-{_digest('name', name)[:16]}{suffix}"


def name_token(name: str) -> str:
    """10 letters (a-p) of the keyed hash of a file name, for names StrideLab gives in its place (an imported
    recording's file name and trial): letters only, so that no digit run reads as a record number."""
    return stored_name(name)[4:14].translate(str.maketrans("0123456789abcdef", "abcdefghijklmnop"))


def stored_path(path: str | Path) -> str:
    """What the catalog keeps of a recording's absolute path (the re-ingest shortcut needs only equality)."""
    return f"path-{_digest('path', str(Path(path).resolve()))[:32]}"


#: words a topic name may be made of to be shown as it is (beside the placements): ROS 2 conventions and sensor
#: vocabulary; a topic with any other word (``/karl_huber/imu``) is shown as a keyed hash
TOPIC_WORDS = frozenset((
    "imu", "mag", "range", "reference", "pose", "events", "data", "data_raw", "raw", "filtered", "magnetic_field",
    "sensor", "sensors", "device", "devices", "left", "right", "foot", "shank", "thigh", "pelvis", "chest", "back",
    "lower_back", "wrist", "ankle", "knee", "hip", "trunk", "sternum", "lumbar", "head", "arm", "accel", "gyro",
    "temperature", "temp", "tf", "tf_static", "clock", "rosout", "parameter_events", "diagnostics", "status",
    "camera", "image", "points", "odom", "joint_states", "robot_description", "a", "b"))


def _topic_word(w: str, vocabulary) -> bool:
    return w in vocabulary or w in TOPIC_WORDS or w in ("A", "B") or bool(re.fullmatch(r"[a-z]{1,12}_?\d{1,3}|[ab]|\d{1,3}", w))


def shown_topic(topic: str, policy: PrivacyPolicy | None = None) -> str:
    """A topic name as a stored reason or warning may show it: made of known words only (the placements,
    :data:`TOPIC_WORDS`, ``imu0``: ``/imu/foot_left``, ``/foot_left/imu/data_raw``), as it is; any other as
    ``a topic (name not shown, <8 hex digits of its keyed hash>)`` (a topic may carry a device label or a name).
    ``topic (schema)`` entries keep the schema."""
    t = str(topic)
    m = re.fullmatch(r"(.*) \(([\w/ ]{1,80})\)", t)
    if m:
        return f"{shown_topic(m.group(1), policy)} ({m.group(2)})"
    vocabulary = set(placements(policy or PrivacyPolicy()))
    parts = t.split("/")
    if len(t) <= 120 and t.startswith("/") and all(_topic_word(w, vocabulary) for w in parts[1:]):
        return t
    return f"a topic (name not shown, {_digest('topic', t)[:8]})"
