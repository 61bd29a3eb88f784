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
    """``[privacy]`` of a study manifest: what the study declares beyond the recording format's schema.

    ``id_pattern``: regular expression a participant, session or trial id must match in full;
    ``allow_name_like_ids`` / ``allow_date_like_ids``: accept ids with a capitalised word (``Jane``)
    or a calendar date (``1950-03-02``); ``free_text_fields``: session-metadata fields stored as text
    (screened: names in any script, dates, phone/id/record numbers, postal and e-mail addresses);
    ``numeric_fields``: further session fields stored when they hold a plain number (the format's own:
    ``height_m``, ``*_length_m``, ``sampling_rate_hz``); ``conditions``: further values of ``condition``;
    ``placements``: further placements (beyond DESIGN.md's vocabulary); ``event_labels``: further labels of
    reference events; ``terms``: capitalised words free text may hold (device and product names such as
    ``Vicon``) that would otherwise read as a person's name. Any other field is dropped at ingest."""
    id_pattern: str = DEFAULT_ID_PATTERN
    allow_name_like_ids: bool = False
    allow_date_like_ids: bool = False
    free_text_fields: tuple[str, ...] = ()
    numeric_fields: tuple[str, ...] = ()
    conditions: tuple[str, ...] = ()
    placements: tuple[str, ...] = ()
    event_labels: tuple[str, ...] = ()
    terms: tuple[str, ...] = ()

    @property
    def id_regex(self) -> re.Pattern:
        return re.compile(self.id_pattern)


#: list-valued keys of ``[privacy]`` and the pattern each item must match
_LIST_KEYS = {"free_text_fields": r"[A-Za-z0-9_.-]{1,64}", "numeric_fields": r"[a-z][a-z0-9_]{0,63}",
              "conditions": r"[a-z][a-z0-9_-]{0,39}", "placements": r"[a-z][a-z0-9_]{0,39}",
              "event_labels": r"[a-z][a-z0-9_ -]{0,39}", "terms": r"[^\W\d_][\w+.-]{0,39}"}


def privacy_policy(table: dict | None, where: str = "[privacy]") -> PrivacyPolicy:
    """Build and validate a policy from a manifest's ``[privacy]`` table (raises ValueError naming the key)."""
    table = dict(table or {})
    known = {"id_pattern", "allow_name_like_ids", "allow_date_like_ids", *_LIST_KEYS}
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
    lists = {}
    for k, item in _LIST_KEYS.items():
        v = table.get(k, [])
        if not isinstance(v, list) or not all(isinstance(x, str) and re.fullmatch(item, x) for x in v):
            what = "field names" if k.endswith("_fields") else f"values matching {item}"
            raise ValueError(f"{where}.{k}: expected a list of {what}")
        lists[k] = tuple(v)
    return PrivacyPolicy(pat, table.get("allow_name_like_ids", False), table.get("allow_date_like_ids", False),
                         **lists)


# ---- detectors (allow-listed text is still screened; every message names the kind, never the value) ------------

_MONTHS = (r"(?:jan|feb|f[eé]v|m[aä]r|apr|avr|ma[iy]|jun|jui|jul|aug|ao[uû]|sep|o[ck]t|nov|de[cz]|d[eé]c|"
           r"gen|mag|giu|lug|ago|set|dic|ene|abr|dici)[a-zäéû]*\.?")
_ORD = r"(?:st|nd|rd|th|er|e|\.)?"
_Y = r"(?:1[89]|20)?\d{2}"
_DATE = re.compile(
    r"(?<!\d)(?:"
    r"(?:1[89]|20)\d{2}[-_./ ]?(?:0[1-9]|1[0-2])[-_./ ]?(?:0[1-9]|[12]\d|3[01])"     # 1950-03-02, 19500302
    r"|\d{1,2}[-_./]\d{1,2}[-_./]\d{2,4}"                                             # 02.03.1950, 12/31/51
    r"|\d{1,2}\s+\d{1,2}\s+(?:1[89]|20)\d{2}"                                         # 02 03 1950
    rf"|(?i:\d{{1,2}}{_ORD}[\s./-]*(?:of\s+)?{_MONTHS}[\s,./-]*{_Y})"                # 12-MAR-1951, 12th March 1951
    rf"|(?i:(?<![^\W\d_]){_MONTHS}[\s./-]*\d{{1,2}}{_ORD},?[\s./-]*{_Y})"             # March 12th, 1951 (not 'offset 0.25')
    rf"|(?i:\b{_MONTHS}[\s,./-]*(?:1[89]|20)\d{{2}})"                                 # March 1951
    r"|(?i:\b(?:born|geb(?:oren)?|n[ée]e?|dob|d\.o\.b|birth\w*|geburt\w*|naissance)\b\W{0,3}\d{2,4})"  # born 1951
    r")(?!\d)")
_EMAIL = re.compile(r"[^\s@<>(),;:\"']+@[^\s@<>(),;:\"']+")       # jane.doe@hospital: no TLD needed
_DIGIT_GROUPS = re.compile(r"\+?\d(?:[\d \t()/.-]*\d)?")
_LONG_DIGITS = re.compile(r"\d{6,}")
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_ADDRESS = re.compile(
    r"(?i:\b[^\W\d_]{2,}(?:stra(?:ss|ß)e|str\.|gasse|weg|platz|allee|ring|damm|ufer)\s*\d+)"
    r"|(?i:\b\d+[a-z]?,?\s+(?:[^\W\d_]+\s+){1,3}(?:street|st\.?|road|rd\.?|avenue|ave\.?|lane|ln\.?|boulevard|blvd\.?|"
    r"drive|dr\.?|way|court|ct\.?|place|pl\.?|terrace|square)(?!\w))"
    r"|(?i:\b(?:rue|avenue|av\.|chemin|ch\.|route|boulevard|bd|via|viale|piazza|corso|calle|avenida|plaza|rua|ulica|"
    r"ul\.|straat|laan|weg)\s+(?:[^\W\d_]+[\s'-]+){0,4}[^\W\d_]+,?\s*\d+)"
    r"|(?:\b(?:CH|D|F|A|I)?-?\d{4,5}\s+[^\W\d_a-z][^\W\d_]+)"                          # 8001 Zürich
    r"|(?i:\b(?:p\.?\s?o\.?\s+box|postfach|case postale)\b)")
_CUES = ("mr", "mrs", "ms", "miss", "dr", "prof", "herr", "frau", "mme", "mlle", "patient", "patientin",
         "name", "nom", "named", "called", "signed", "sig")
_WORDS = re.compile(r"[^\W\d_]+(?:['’][^\W\d_]+)*")
_TITLE_TOKEN = re.compile(r"^[A-ZÄÖÜ][a-zäöüß]{2,}$")

#: capitalised words that are device, product, data-set or unit names, not people (what the project's own
#: importers and simulator write); a study adds its own with ``[privacy] terms``
TERMS = frozenset(w.lower() for w in (
    "APDM", "Opal", "Xsens", "MT", "Manager", "MTw", "Vicon", "Qualisys", "OptiTrack", "PyShoe", "BROAD", "CSV",
    "IMU", "IMUs", "FCC", "TOE", "FM5", "UCI", "C3D", "Axivity", "CWA", "AX3", "AX6", "Voisard", "TrialBoundaries",
    "Shimmer", "NilsPod", "gaitmap", "Mobilise", "Mobilise-D", "ROS", "MCAP", "HDF5", "ENU", "NED", "ISB", "GPS",
    "TUG", "MWT", "Hz", "Vicon", "Nexus", "StrideLab", "Delsys", "Noraxon", "Movella", "Qualisys", "Motive",
    "Kistler", "GAITRite", "Zebris", "Opals", "HC", "PD", "MS", "OA", "TKA", "THA", "ACL",
    "INDIP", "Stereophoto", "MicroWB"))                                  # Mobilise-D reference systems, bouts


def _tokens(text: str) -> list[str]:
    """Words of an identifier or key: split at non-letters and at lower->upper case changes."""
    return [t for t in re.split(r"[^A-Za-zÄÖÜäöüß]+|(?<=[a-zäöüß])(?=[A-ZÄÖÜ])", text) if t]


def key_problem(key: str) -> str | None:
    """What kind of personal data a metadata field's *name* announces (``geburtsdatum``, ``tel``), or None."""
    k = key.lower()
    if {t.lower() for t in _tokens(key)} & _PERSONAL_KEY_TOKENS or any(p in k for p in _PERSONAL_KEY_PARTS):
        return "its name announces personal data (names, birth dates, phone numbers, e-mail or postal addresses)"
    return None


_PERSONAL_KEY_TOKENS = {
    "name", "names", "firstname", "lastname", "surname", "givenname", "vorname", "nachname", "nom", "prenom",
    "email", "mail", "phone", "tel", "telefon", "telephone", "mobile", "handy", "natel", "fax",
    "birth", "birthdate", "birthday", "dob", "geburtsdatum", "geburtstag", "geb", "born", "naissance",
    "address", "adresse", "street", "strasse", "zip", "plz", "ssn", "ahv", "insurance", "versicherung", "initials",
    "mrn", "nhs", "avs", "patient", "patientid"}
_PERSONAL_KEY_PARTS = ("birth", "geburt", "phone", "telefon", "mail", "adress", "address", "surname", "firstname",
                       "lastname", "vorname", "nachname", "naissance")


def is_number(value: str) -> bool:
    return bool(_NUMBER.fullmatch(value.strip()))


def _caseless(word: str) -> bool:
    """A word of a script without letter case (Han, Kana, Hangul, Arabic, Hebrew, Thai, Devanagari, ...)."""
    return word.upper() == word.lower()


def _name_like(word: str, terms: frozenset) -> bool:
    return word.lower() not in terms and (word[0].isupper() or _caseless(word))


def name_problem(value: str, terms=()) -> str | None:
    """"what looks like a person's name" in any script: two name-like words in a row (capitalised or all
    capitals, ``José Núñez``, ``Иван Петров``, ``JANE DOE``, ``Doe, Jane``), any word of a script without letter
    case (``王小明``: names there are not told from other words by their shape), or a title or cue before a
    capitalised word (``Dr Weber``, ``patient Weber``). ``terms``: capitalised words known not to be names."""
    terms = TERMS | {t.lower() for t in terms}
    spans = [m.span() for t in terms if not _WORDS.fullmatch(t)        # terms of several words (Mobilise-D)
             for m in re.finditer(rf"(?<![\w-]){re.escape(t)}(?![\w-])", value, re.IGNORECASE)]
    words = list(_WORDS.finditer(value))
    in_term = [any(a <= m.start() and m.end() <= b for a, b in spans) for m in words]
    for i, m in enumerate(words):
        w = m.group()
        if _caseless(w) and not any(c.isascii() for c in w):
            return "it holds what looks like a person's name (a word of a script without letter case)"
        if i + 1 < len(words):
            nxt = words[i + 1]
            gap = value[m.end():nxt.start()]
            if re.fullmatch(r"[\s._,'’-]{1,3}", gap):
                if (not in_term[i] and not in_term[i + 1] and _name_like(w, terms) and _name_like(nxt.group(), terms)
                        and len(w) + len(nxt.group()) >= 4):
                    return "it holds what looks like a person's name"
                if w.lower() in _CUES and nxt.group()[0].isupper() and nxt.group().lower() not in terms:
                    return "it holds what looks like a person's name"
    return None


def number_problem(value: str) -> str | None:
    """A number that looks like a phone, identity or record number: 6+ digits in a row (``MRN00482913``) or 7+
    digits in groups (``+41 79 123 45 67``); dates are found by the date detector first."""
    v = _DATE.sub(" ", value)
    if _LONG_DIGITS.search(v):
        return "it holds what looks like a phone number or an identity or record number"
    for m in _DIGIT_GROUPS.finditer(v):
        if sum(c.isdigit() for c in m.group()) >= 7:
            return "it holds what looks like a phone number or an identity or record number"
    return None


def value_problem(value: str, *, dates: bool = True, names: bool = True, terms=()) -> str | None:
    """The kind of personal data found in a metadata value, or None (never the value itself); ``dates`` /
    ``names`` False skip those two detectors (ids of a study that allows them)."""
    if _EMAIL.search(value):
        return "it holds an e-mail address"
    if dates and _DATE.search(value):
        return "it holds a calendar date (a birth date is personal data; recording times are in the samples)"
    why = number_problem(value if dates else _DATE.sub(" ", value))
    if why:
        return why
    if _ADDRESS.search(value):
        return "it holds what looks like a postal address"
    if names:
        return name_problem(value, terms)
    return None


#: a code: lower-case ASCII letters, digits, '_' and '-' (``level_walking``, ``10mwt``)
_CODE = re.compile(r"[a-z0-9][a-z0-9_-]{0,39}\Z")


def code_problem(value) -> str | None:
    """Why ``value`` is not a safe code (a short lower-case token without dates or long numbers), or None."""
    v = str(value)
    if not _CODE.match(v):
        return "is not a code (lower-case letters, digits, '_' or '-', at most 40)"
    why = value_problem(v, names=False)
    return f"is not a code: {why}" if why else None


def identifier_problem(value, policy: PrivacyPolicy) -> str | None:
    """Why ``value`` is not an acceptable pseudonym under ``policy``, or None."""
    if not isinstance(value, str) or not policy.id_regex.fullmatch(value) or "\n" in value or ".." in value \
            or "/" in value or "\\" in value:
        return (f"is not a safe identifier: it does not match the study's pseudonym pattern {policy.id_pattern} "
                f"(letters and digits, e.g. a study code and a number)")
    if not policy.allow_date_like_ids and _DATE.search(value):
        return ("looks like it contains a date (a birth date is personal data); use a pseudonym, or set "
                "allow_date_like_ids in the study manifest's [privacy]")
    if re.fullmatch(r"PS-[A-Z2-7]{12}", value):          # a keyed pseudonym (stridelab.pipeline.pseudonym)
        return None
    if _LONG_DIGITS.search(_DATE.sub(" ", value)) or _EMAIL.search(value):
        return ("looks like a phone, identity or record number (6 digits or more in a row); use a pseudonym, or "
                "give the site's number as site_id (it is replaced by a keyed pseudonym)")
    caps = [t for t in _tokens(value) if len(t) >= 3 and t.isupper()]
    if not policy.allow_name_like_ids and (any(_TITLE_TOKEN.match(t) for t in _tokens(value))
                                            or _NAME_PAIR.search(value) or len(caps) >= 2):
        return ("looks like a name (a capitalised word); use a pseudonym (a study code and a number), or set "
                "allow_name_like_ids in the study manifest's [privacy]")
    return None


_WORD = r"[A-ZÄÖÜÉÈ][a-zäöüßéèàçñ]+(?:-[A-Z][a-zäöüß]+)?"
_NAME_PAIR = re.compile(rf"(?<![\w]){_WORD}(?:,\s*|[ ._]+){_WORD}(?![\w])")      # Jane Doe, Doe, Jane, Jane.Doe


def shown(value, limit: int = 40) -> str:
    """`` 'value'`` when ``value`` is safe to repeat in a reason (a code), else nothing."""
    v = str(value)
    return f" '{v}'" if len(v) <= limit and code_problem(v) is None else ""
