"""A study's privacy policy (``[privacy]`` of its manifest) and the detectors of personal data.

Identifiers (participant, session, trial) must be pseudonyms of the study's pattern (default
:data:`DEFAULT_ID_PATTERN`) and, unless the study allows them, neither name-like nor date-like.
Values of any metadata field are screened for e-mail addresses (with or without a top-level
domain), dates (a birth date cannot be told from another date by its value), phone numbers and
person names. The detectors are heuristics on the safe side: a refused pseudonym can be allowed
by the study; personal data that looks like a code (``DOEJ50``) cannot be recognised by anyone.
Every message names the field and the kind of problem, never the value.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = ["DEFAULT_ID_PATTERN", "PrivacyPolicy", "privacy_policy", "identifier_problem", "value_problem",
           "key_problem"]

#: letters and digits, then also '_' and '-', at most 64 characters; ``\Z`` (not ``$``, which matches
#: before a trailing newline: ``'P001\n'``)
DEFAULT_ID_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_-]{0,63}\Z"

#: strings every identifier pattern must refuse (they would become unsafe folder names)
_UNSAFE_SAMPLES = ("", "..", "../x", "a/b", "a\\b", "P001\n", " P001", "P001 ", "a\x00")


@dataclass(frozen=True)
class PrivacyPolicy:
    """``[privacy]`` of a study manifest.

    ``id_pattern``: regular expression a participant, session or trial id must match in full;
    ``allow_name_like_ids`` / ``allow_date_like_ids``: accept ids with a capitalised word (``Jane``)
    or a calendar date (``1950-03-02``); ``free_text_fields``: session-metadata fields stored
    verbatim (still screened for e-mails, dates, phone numbers and names); any other non-numeric
    field outside the recording format's own fields is dropped at ingest with a warning."""
    id_pattern: str = DEFAULT_ID_PATTERN
    allow_name_like_ids: bool = False
    allow_date_like_ids: bool = False
    free_text_fields: tuple[str, ...] = ()

    @property
    def id_regex(self) -> re.Pattern:
        return re.compile(self.id_pattern)


def privacy_policy(table: dict | None, where: str = "[privacy]") -> PrivacyPolicy:
    """Build and validate a policy from a manifest's ``[privacy]`` table (raises ValueError naming the key)."""
    table = dict(table or {})
    known = {"id_pattern", "allow_name_like_ids", "allow_date_like_ids", "free_text_fields"}
    unknown = set(table) - known
    if unknown:
        raise ValueError(f"{where}: unknown field(s) {sorted(unknown)}; known: {sorted(known)}")
    pat = table.get("id_pattern", DEFAULT_ID_PATTERN)
    if not isinstance(pat, str):
        raise ValueError(f"{where}.id_pattern: expected a string")
    try:
        rx = re.compile(pat)
    except re.error as e:
        raise ValueError(f"{where}.id_pattern: not a regular expression ({e})") from None
    bad = [repr(s) for s in _UNSAFE_SAMPLES if rx.fullmatch(s)]
    if bad:
        raise ValueError(f"{where}.id_pattern: accepts unsafe ids ({', '.join(bad)}); ids become folder names")
    for k in ("allow_name_like_ids", "allow_date_like_ids"):
        if not isinstance(table.get(k, False), bool):
            raise ValueError(f"{where}.{k}: expected true/false")
    ft = table.get("free_text_fields", [])
    if not isinstance(ft, list) or not all(isinstance(x, str) and re.fullmatch(r"[A-Za-z0-9_.-]{1,64}", x) for x in ft):
        raise ValueError(f"{where}.free_text_fields: expected a list of field names")
    return PrivacyPolicy(pat, table.get("allow_name_like_ids", False), table.get("allow_date_like_ids", False),
                         tuple(ft))


# ---- detectors ------------------------------------------------------------------------------

_MONTHS = r"(?:jan|feb|m[aä]r|apr|ma[iy]|jun|jul|aug|sep|o[ck]t|nov|de[cz])[a-zä]*\.?"
_DATE = re.compile(
    r"(?<!\d)(?:"
    r"(?:19|20)\d{2}[-_./ ]?(?:0[1-9]|1[0-2])[-_./ ]?(?:0[1-9]|[12]\d|3[01])"        # 1950-03-02, 19500302
    r"|(?:0?[1-9]|[12]\d|3[01])[-_./ ](?:0?[1-9]|1[0-2])[-_./ ](?:(?:19|20)\d{2}|\d{2})"  # 02.03.1950, 2/3/50
    r"|(?:0?[1-9]|1[0-2])/(?:0?[1-9]|[12]\d|3[01])/(?:19|20)\d{2}"                   # 03/02/1950
    rf"|(?:0?[1-9]|[12]\d|3[01])\.?\s*(?i:{_MONTHS}),?\s*(?:19|20)\d{{2}}"             # 2 March 1950
    rf"|(?i:{_MONTHS})\s+(?:0?[1-9]|[12]\d|3[01]),?\s+(?:19|20)\d{{2}}"                # March 2, 1950
    r")(?!\d)")
_EMAIL = re.compile(r"[^\s@<>(),;:\"']+@[^\s@<>(),;:\"']+")       # jane.doe@hospital: no TLD needed
_PHONE = re.compile(r"(?<![\w.])(?:\+|00)?\(?\d[\d\s()./-]{5,}\d(?![\w])")
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_WORD = r"[A-ZÄÖÜÉÈ][a-zäöüßéèàçñ]+(?:-[A-Z][a-zäöüß]+)?"
_NAME_PAIR = re.compile(rf"(?<![\w]){_WORD}(?:,\s*|[ ._]+){_WORD}(?![\w])")      # Jane Doe, Doe, Jane, Jane.Doe
_NAME_CUE = re.compile(r"(?<![\w])(?i:mr|mrs|ms|miss|dr|herr|frau|mme|patient|patientin|name|nom|named|called)"
                       r"\.?:?\s+[A-ZÄÖÜ][a-zäöü]")
_TITLE_TOKEN = re.compile(r"^[A-ZÄÖÜ][a-zäöüß]{2,}$")

#: key tokens that name a kind of personal data (English, German, French)
_PERSONAL_KEY_TOKENS = {
    "name", "names", "firstname", "lastname", "surname", "givenname", "vorname", "nachname", "nom", "prenom",
    "email", "mail", "phone", "tel", "telefon", "telephone", "mobile", "handy", "natel", "fax",
    "birth", "birthdate", "birthday", "dob", "geburtsdatum", "geburtstag", "geb", "born", "naissance",
    "address", "adresse", "street", "strasse", "zip", "plz", "ssn", "ahv", "insurance", "versicherung", "initials"}
_PERSONAL_KEY_PARTS = ("birth", "geburt", "phone", "telefon", "mail", "adress", "address", "surname", "firstname",
                       "lastname", "vorname", "nachname", "naissance")


def _tokens(text: str) -> list[str]:
    """Words of an identifier or key: split at non-letters and at lower->upper case changes."""
    return [t for t in re.split(r"[^A-Za-zÄÖÜäöüß]+|(?<=[a-zäöüß])(?=[A-ZÄÖÜ])", text) if t]


def key_problem(key: str) -> str | None:
    """What kind of personal data a metadata field's *name* announces (``geburtsdatum``, ``tel``), or None."""
    k = key.lower()
    if {t.lower() for t in _tokens(key)} & _PERSONAL_KEY_TOKENS or any(p in k for p in _PERSONAL_KEY_PARTS):
        return "its name announces personal data (names, birth dates, phone numbers, e-mail or postal addresses)"
    return None


def is_number(value: str) -> bool:
    return bool(_NUMBER.fullmatch(value.strip()))


def value_problem(value: str, *, dates: bool = True, names: bool = True) -> str | None:
    """The kind of personal data found in a metadata value, or None (never the value itself); ``dates`` /
    ``names`` False skip those two detectors (ids of a study that allows them)."""
    if _EMAIL.search(value):
        return "it holds an e-mail address"
    if dates and _DATE.search(value):
        return "it holds a calendar date (a birth date is personal data; recording times are in the samples)"
    for m in _PHONE.finditer(_DATE.sub(" ", value)):       # an allowed date is not a phone number
        digits = sum(c.isdigit() for c in m.group())
        if 7 <= digits <= 15 and not (is_number(m.group()) and not m.group().lstrip("+").startswith("0")):
            return "it holds a phone number"
    if names and (_NAME_PAIR.search(value) or _NAME_CUE.search(value)):
        return "it holds what looks like a person's name"
    return None


def identifier_problem(value, policy: PrivacyPolicy) -> str | None:
    """Why ``value`` is not an acceptable pseudonym under ``policy``, or None."""
    if not isinstance(value, str) or not policy.id_regex.fullmatch(value) or "\n" in value or ".." in value \
            or "/" in value or "\\" in value:
        return (f"is not a safe identifier: it does not match the study's pseudonym pattern {policy.id_pattern} "
                f"(letters and digits, e.g. a study code and a number)")
    if not policy.allow_date_like_ids and _DATE.search(value):
        return ("looks like it contains a date (a birth date is personal data); use a pseudonym, or set "
                "allow_date_like_ids in the study manifest's [privacy]")
    if not policy.allow_name_like_ids and (any(_TITLE_TOKEN.match(t) for t in _tokens(value))
                                            or _NAME_PAIR.search(value)):
        return ("looks like a name (a capitalised word); use a pseudonym (a study code and a number), or set "
                "allow_name_like_ids in the study manifest's [privacy]")
    return None
