"""Personal data kept out of the warehouse: the ``session`` metadata screened against the study's policy.

The policy comes from ``[privacy]`` of the study manifest (:mod:`studies.privacy`; the default when
the study has no manifest). Refusals raise ``ValueError`` with a reason naming the field and the
kind of problem, never the value (quarantine reasons end up in logs and in the catalog).
"""
from __future__ import annotations

from estimators.recording import SESSION_BODY_FIELDS, SESSION_DESIGN_FIELDS
from pipeline.config import study_manifest
from studies.privacy import PrivacyPolicy, identifier_problem, is_number, key_problem, privacy_policy, value_problem

#: session-metadata fields of the recording format (DESIGN.md "Recording format"): validated on their
#: own, stored; any other non-numeric field is free text
FORMAT_FIELDS = {"study", "participant", "session", "kind", "protocol", "trial", "timezone", "condition",
                 "paretic_side", "pseudonymised", "reference_frame", "accelerometer_only"}
# numeric body measures and study-design marks (trunk gait and MDC, issue #42): stored, checked by pipeline.ingest
FORMAT_FIELDS |= set(SESSION_BODY_FIELDS) | set(SESSION_DESIGN_FIELDS)
ID_FIELDS = ("participant", "session", "trial")
#: fields checked against a closed list elsewhere (kind, IANA zone): not screened as text ("America/New_York")
#: (``reference_frame``, ``accelerometer_only``: closed values the stages read, checked by pipeline.ingest)
_ENUM_FIELDS = {"kind", "timezone", "pseudonymised", "reference_frame", "accelerometer_only"}
#: quantities with a unit in the name (thigh_length_m, sampling_rate_hz): kept for the plausibility checks
_UNIT_SUFFIXES = ("_m", "_hz", "_s", "_deg", "_kg")


def study_policy(study: str) -> PrivacyPolicy:
    """The study's ``[privacy]`` policy (the default when the study has no manifest or no table)."""
    return privacy_policy(study_manifest(study).get("privacy"), f"study {study}: [privacy]")


def screen_session(s: dict, policy: PrivacyPolicy, notes: list[dict] | None = None) -> dict:
    """Refuse personal data anywhere in the (pseudonymised) session metadata ``s``; drop free text the
    policy does not allow-list (a warning in ``notes``). Returns the metadata to store."""
    for k in ID_FIELDS:
        if s.get(k) is not None:
            why = identifier_problem(s[k], policy)
            if why:
                raise ValueError(f"session metadata '{k}' {why}")
    for k, v in s.items():
        why = key_problem(k) if k not in FORMAT_FIELDS else None
        if why is None and k not in _ENUM_FIELDS and not (isinstance(v, str) and is_number(v)):
            why = value_problem(str(v), dates=k not in ID_FIELDS or not policy.allow_date_like_ids,
                                names=k not in ID_FIELDS or not policy.allow_name_like_ids)
        if why:
            raise ValueError(f"'session' metadata field '{k}' looks like personal data: {why}; names, e-mail "
                             f"addresses, birth dates and phone numbers are never stored: export pseudonyms only")
    out = {}
    for k, v in s.items():
        if k in FORMAT_FIELDS or k in policy.free_text_fields or k.endswith(_UNIT_SUFFIXES) \
                or (isinstance(v, str) and is_number(v)):
            out[k] = v
        elif notes is not None:
            notes.append({"severity": "warning", "topic": None,
                          "message": f"metadata field '{k}' dropped: free text is stored only for fields the "
                                     f"study manifest allow-lists ([privacy] free_text_fields)"})
    return out
