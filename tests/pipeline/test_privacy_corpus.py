"""Personal-data corpus (issue 47 point 1): each variant in its own recording, made with real writers (the
project's mcap_write, mcap_ros2, rosbags, ezc3d + ``stridelab import``, h5py + ``stridelab import apdm``), run
through ``stridelab run`` into a real warehouse with stages and participant reports. Then every text column of
every table of every DuckDB file under the home (catalog and snapshots), every path under the home, every text
file under the home and the text of every participant report (PDF text by pypdf, HTML text by html.parser) is
searched for each variant's values. Per variant: stored (found anywhere: must be 0), refused (the file was
quarantined or the import refused it), dropped (ingested without the value).

``python -m tests.pipeline.test_privacy_corpus HOME_DIR`` builds the corpus, runs it and prints the table."""
from __future__ import annotations

import html.parser
import json
import os
import re
import sys
from dataclasses import dataclass, field, replace
from pathlib import Path

import pytest

from stridelab.estimators.recording import Recording
from stridelab.pipeline.formats.mcap_write import write_recording
from tests.corpus import small_recording

PYTHON = [sys.executable, "-m", "stridelab"]
STUDY_TOML = """[privacy]
# the one free-text field of the corpus study: stored only after the screen
free_text_fields = ["comment"]

[topics]
"/Otto_Brandt/imu" = "foot_left"
"""


@dataclass
class Variant:
    id: str
    what: str
    needles: tuple[str, ...]                 # what must be found nowhere (case-insensitive)
    files: list[str] = field(default_factory=list)     # inbox names of what the variant put there
    import_refused: bool = False
    imported: bool = False                   # files written by `stridelab import` (audited like the warehouse)


def _rec(i: int, **meta) -> Recording:
    r = small_recording(seconds=12, seed=i, participant=f"C{i:02d}", session=f"C{i:02d}-s1", trial="walk-1",
                        study="corpus")
    return replace(r, metadata={**r.metadata, **meta})


def _write(v: Variant, inbox: Path, name: str, rec: Recording) -> None:
    write_recording(rec, inbox / name)
    v.files.append(name)


def _sidecar(v: Variant, inbox: Path, name: str, rec: Recording, fields: dict) -> None:
    _write(v, inbox, name, rec)
    (inbox / f"{Path(name).stem}.session.toml").write_text(
        "[session]\n" + "".join(f"{k} = {json.dumps(x, ensure_ascii=False)}\n" for k, x in fields.items()),
        encoding="utf-8")


def build(inbox: Path, work: Path, run) -> list[Variant]:
    """Write the 31 variants into ``inbox`` (``run``: calls the CLI, for the importers)."""
    from tests.pipeline._interop import rosbags_write, write_mcap_ros2
    inbox.mkdir(parents=True, exist_ok=True)
    work.mkdir(parents=True, exist_ok=True)
    out: list[Variant] = []

    def meta(i, what, needles, **m):
        v = Variant(f"v{i:02d}", what, needles)
        _write(v, inbox, f"v{i:02d}.mcap", _rec(i, **m))
        out.append(v)

    def side(i, what, needles, **fields):
        v = Variant(f"v{i:02d}", what, needles)
        _sidecar(v, inbox, f"v{i:02d}.mcap", _rec(i), fields)
        out.append(v)

    # names in any script, in protocol, condition and sidecar fields
    meta(1, "protocol = 'Łukasz Żółć'", ("Łukasz", "Żółć"), protocol="Łukasz Żółć")
    meta(2, "condition = 'Иван Петров'", ("Иван", "Петров"), condition="Иван Петров")
    side(3, "sidecar comment = '王小明'", ("王小明",), comment="王小明")
    meta(4, "protocol = 'JANE DOE'", ("jane doe",), protocol="JANE DOE")
    side(5, "sidecar comment = 'José Núñez' (allow-listed field)", ("José", "Núñez"), comment="José Núñez")
    # birth dates in common forms
    meta(6, "condition = '12-MAR-1951'", ("12-MAR-1951",), condition="12-MAR-1951")
    meta(7, "comment = 'born 12th March 1951' (allow-listed)", ("12th March", "1951"), comment="born 12th March 1951")
    side(8, "sidecar remark = '12/31/51'", ("12/31/51",), remark="12/31/51")
    meta(9, "protocol = 'walk 1953-04-15' (ISO date)", ("1953-04-15",), protocol="walk 1953-04-15")
    # numbers that look like phone, identity or record numbers
    meta(10, "contact = '+41791234567' (numeric)", ("41791234567",), contact="+41791234567")
    meta(11, "comment = 'MRN 00482913' (allow-listed)", ("00482913",), comment="MRN 00482913")
    meta(12, "x_id = '7561234567897' (13-digit national id)", ("7561234567897",), x_id="7561234567897")
    v = Variant("v13", "participant = 'MRN48291377'", ("48291377",))
    _write(v, inbox, "v13.mcap", replace(_rec(13), metadata={**_rec(13).metadata, "participant": "MRN48291377",
                                                              "session": "C13-s1"}))
    out.append(v)
    meta(14, "comment = 'Bahnhofstrasse 12, 8001 Zürich' (allow-listed)", ("Bahnhofstrasse",),
         comment="Bahnhofstrasse 12, 8001 Zürich")
    side(15, "sidecar contact = 'eva.roth@example.org'", ("eva.roth", "example.org"), contact="eva.roth@example.org")
    # unit suffixes earn no exemption
    meta(16, "note_s = 'fritz weber' (lower-case name, unit suffix)", ("fritz weber", "weber"), note_s="fritz weber")
    meta(17, "remark_hz = '0041442681234' (phone, unit suffix)", ("0041442681234", "41442681234"),
         remark_hz="0041442681234")
    # reference-event labels and payloads
    r = _rec(18)
    v = Variant("v18", "event label 'Hildegard Müller'", ("Hildegard", "Müller"))
    _write(v, inbox, "v18.mcap", replace(r, events=[dict(r.events[0], label="Hildegard Müller"), *r.events[1:]]))
    out.append(v)
    r = _rec(19)
    v = Variant("v19", "event 'note': birth date and phone", ("1948-07-21", "555 66 77"))
    _write(v, inbox, "v19.mcap", replace(r, events=[dict(r.events[0], note="born 1948-07-21, tel +41 79 555 66 77"),
                                                    *r.events[1:]]))
    out.append(v)
    # placements never taken from a topic or a device label
    r = _rec(20)
    v = Variant("v20", "IMU topic /imu/karl_huber (a name as placement)", ("karl_huber", "huber"))
    _write(v, inbox, "v20.mcap", replace(r, imu={"karl_huber": r.imu["foot_left"]}, reference_poses={}, events=[]))
    out.append(v)
    r = _rec(21)
    v = Variant("v21", "e-mail in a topic name (mcap_ros2 writer)", ("anna.keller", "keller", "clinic.ch"))
    write_mcap_ros2(inbox / "v21.mcap", r, topics={"/imu/foot_left": "/imu/anna.keller@clinic.ch"}, mag=False)
    v.files.append("v21.mcap")
    out.append(v)
    r = _rec(22)
    v = Variant("v22", "topic /Otto_Brandt/imu mapped by the manifest [topics] (mcap_ros2)", ("otto", "brandt"))
    write_mcap_ros2(inbox / "v22.mcap", replace(r, imu={"foot_left": r.imu["foot_left"]}),
                    topics={"/imu/foot_left": "/Otto_Brandt/imu"}, mag=False)
    v.files.append("v22.mcap")
    out.append(v)
    # file and folder names
    v = Variant("v23", "file name Jane_Doe_1951-03-12.mcap", ("jane_doe", "1951-03-12"))
    _write(v, inbox, "Jane_Doe_1951-03-12.mcap", _rec(23))
    out.append(v)
    v = Variant("v24", "rosbag2 folder hans_mueller_bag/ (rosbags writer)", ("hans_mueller", "mueller"))
    r = _rec(24)
    rosbags_write(inbox / "hans_mueller_bag", r, custom_data={f"session.{k}": str(x) for k, x in r.metadata.items()})
    v.files.append("hans_mueller_bag")
    out.append(v)
    v = Variant("v25", "refused file named Erika_Mustermann_1960-01-01.mcap", ("mustermann", "1960-01-01"))
    bad = {k: x for k, x in _rec(25).metadata.items() if k != "kind"}
    _write(v, inbox, "Erika_Mustermann_1960-01-01.mcap", replace(_rec(25), metadata=bad))
    out.append(v)
    out.append(_c3d_variant(inbox, work, run))
    out.append(_xio_variant(inbox, work, run))
    out.append(_apdm_variant(inbox, work, run))
    # identifiers
    v = Variant("v29", "participant = 'MAX_MUSTER'", ("max_muster",))
    _write(v, inbox, "v29.mcap", replace(_rec(29), metadata={**_rec(29).metadata, "participant": "MAX_MUSTER"}))
    out.append(v)
    meta(30, "session = 'c30-1950-11-30' (a birth date in the session id)", ("1950-11-30",), session="c30-1950-11-30")
    meta(31, "trial = 'Zoë-Weiß'", ("Weiß", "Zoë"), trial="Zoë-Weiß")
    return out


#: the variants of the earlier tests (test_personal_data.py, test_privacy.py): field, value, needles
EARLIER = [
    ("participant", "Jane.Doe", ("jane.doe",)), ("participant", "Doe_Jane_1950-03-02", ("doe_jane", "1950-03-02")),
    ("participant", "Jane", ("jane",)), ("participant", "P001\n", ()), ("session", "S01\n", ()),
    ("trial", "Doe-Jane", ("doe-jane",)), ("comment", "walked with Jane Doe", ("jane doe",)),
    ("comment", "born 02.03.1950, fine otherwise", ("02.03.1950",)),
    ("comment", "born 2 March 1950", ("2 march 1950",)),
    ("comment", "call back on +41 79 123 45 67", ("79 123 45 67",)),
    ("comment", "Jane Doe, born 1950-03-02, tel 079 123 45 67", ("1950-03-02", "079 123 45 67")),
    ("geburtsdatum", "02.03.1950", ("02.03.1950",)), ("tel", "0791234567", ("0791234567",)),
    ("contact", "jane.doe@hospital", ("jane.doe@hospital",)),
    ("contact", "jane.doe@hospital.example.org", ("hospital.example.org",)),
    ("participant_name", "Jane Doe", ("jane doe",)), ("session", "../../../etc/passwd", ("passwd",)),
    ("study", "x'; DROP TABLE recordings; --", ("drop table",)), ("site_id", "HOSP-12345", ("hosp-12345", "12345")),
]


def build_earlier(inbox: Path) -> list[Variant]:
    """The earlier tests' variants, each in its own recording (participants E01…)."""
    out = []
    for i, (k, x, needles) in enumerate(EARLIER, 1):
        r = small_recording(seconds=12, seed=100 + i, participant=f"E{i:02d}", session=f"E{i:02d}-s1",
                            trial="walk-1", study="corpus")
        meta = {**r.metadata, k: x}
        if k == "site_id":
            meta.pop("participant")
        v = Variant(f"e{i:02d}", f"earlier: {k} = {x!r}", needles)
        _write(v, inbox, f"e{i:02d}.mcap", replace(r, metadata=meta))
        out.append(v)
    return out


def _c3d_variant(inbox: Path, work: Path, run) -> Variant:
    from tests.pipeline.test_import_c3d import _cluster, _recording, write_c3d
    v = Variant("v26", "C3D file Maria_Rossi_1949-05-06.c3d imported onto a recording", ("maria_rossi", "rossi",
                                                                                        "1949-05-06"))
    rec = _recording(work / "Maria_Rossi_walk.mcap")
    xyz, _ = _cluster(300, 100.0)
    write_c3d(work / "Maria_Rossi_1949-05-06.c3d", ["LHEE", "LTOE", "LMT5"], xyz, 100.0)
    r = run("import", "c3d", work / "Maria_Rossi_1949-05-06.c3d", "--recording", rec, "--segment",
            "foot_left=LHEE,LTOE,LMT5", "--inbox", inbox, "--json")
    written = json.loads(r.stdout)["written"] if r.stdout.strip() else []
    v.files += [Path(p).name for p in written]
    v.import_refused, v.imported = not written, True
    return v


def _xio_variant(inbox: Path, work: Path, run) -> Variant:
    from tests.pipeline.test_import import _write_xio
    v = Variant("v27", "device export Peter_Meier_1955-02-03.csv (stridelab import xio)", ("meier", "1955-02-03"))
    _write_xio(work / "Peter_Meier_1955-02-03.csv")
    r = run("import", "xio", work / "Peter_Meier_1955-02-03.csv", "--study", "corpus", "--session",
            "participant=C27", "--inbox", inbox, "--json")
    written = json.loads(r.stdout)["written"] if r.stdout.strip() else []
    v.files += [Path(p).name for p in written]
    v.import_refused, v.imported = not written, True
    return v


def _apdm_variant(inbox: Path, work: Path, run) -> Variant:
    from tests.pipeline.test_import import write_apdm
    v = Variant("v28", "APDM monitor label 'Hans Zimmer' (stridelab import apdm)", ("zimmer",))
    write_apdm(work / "opals.h5", labels=("Hans Zimmer", "Lumbar"))
    r = run("import", "apdm", work / "opals.h5", "--study", "corpus", "--session", "participant=C28", "--inbox",
            inbox, "--json")
    written = json.loads(r.stdout)["written"] if r.stdout.strip() else []
    v.files += [Path(p).name for p in written]
    v.import_refused, v.imported = not written, True
    return v


# ---- where it looks ---------------------------------------------------------------------------

class _Text(html.parser.HTMLParser):
    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.parts: list[str] = []

    def handle_data(self, data):
        self.parts.append(data)

    def handle_starttag(self, tag, attrs):           # titles and alt texts are shown too
        self.parts += [x for k, x in attrs if k in ("title", "alt", "aria-label") and x]


def report_texts(home: Path) -> dict[str, str]:
    """Text of every participant report under the home: PDF by pypdf, HTML by html.parser."""
    from pypdf import PdfReader
    out = {}
    for p in sorted(home.rglob("*.pdf")):
        out[str(p.relative_to(home))] = "\n".join(pg.extract_text() or "" for pg in PdfReader(p).pages)
    for p in sorted(home.rglob("*.html")):
        t = _Text()
        t.feed(p.read_text(encoding="utf-8", errors="replace"))
        out[str(p.relative_to(home))] = " ".join(t.parts)
    return out


def catalog_texts(home: Path) -> dict[str, str]:
    """Every VARCHAR / JSON column of every table of every DuckDB file under the home (catalog, snapshots)."""
    import duckdb
    out = {}
    for db in sorted(p for p in home.rglob("*") if p.is_file() and p.suffix in (".duckdb", ".db")):
        try:
            con = duckdb.connect(str(db), read_only=True)
        except duckdb.Error:
            continue
        try:
            for t, c in con.execute("SELECT table_name, column_name FROM information_schema.columns WHERE "
                                    "table_schema = 'main' AND data_type IN ('VARCHAR', 'JSON')").fetchall():
                vals = con.execute(f'SELECT "{c}" FROM "{t}"').fetchall()
                out[f"{db.relative_to(home)}:{t}.{c}"] = "\n".join(str(x) for (x,) in vals if x is not None)
        finally:
            con.close()
    return out


def home_texts(home: Path, inputs=frozenset()) -> dict[str, str]:
    """Every path under the home, and the content of its small text files (logs, JSON, TOML); ``inputs``: the
    operator's own files in the inbox (named and written by the test, as a user would: not StrideLab's to
    rename), skipped; what ``stridelab import`` wrote into the inbox is audited."""
    paths = [p for p in sorted(home.rglob("*")) if not any(p == i or i in p.parents for i in inputs)]
    out = {"paths": "\n".join(str(p.relative_to(home)) for p in paths)}
    for p in paths:
        if p.is_file() and p.suffix in (".log", ".json", ".txt", ".toml", ".yaml", ".csv", ".md") \
                and p.stat().st_size < 5_000_000:
            out[f"file:{p.relative_to(home)}"] = p.read_text(encoding="utf-8", errors="replace")
    return out


_HASHES = re.compile(r"(?<![0-9a-z])(?:[0-9a-f]{8,}|[a-p]{10})(?![0-9a-z])")


def _found(needle: str, text: str) -> bool:
    """``needle`` in ``text`` case-insensitively; hex hashes and name tokens of the text skipped, a number
    not matched inside a longer number, a word not inside a longer word."""
    n = needle.casefold()
    t = _HASHES.sub(" ", text.casefold())
    pre = r"(?<!\d)" if n[0].isdigit() else r"(?<![^\W\d_])"
    post = r"(?!\d)" if n[-1].isdigit() else r"(?![^\W\d_])"
    return re.search(pre + re.escape(n) + post, t) is not None


def audit(home: Path, inbox: Path, variants: list[Variant]) -> list[dict]:
    """Per variant: stored (where), refused, dropped."""
    import duckdb
    try:
        from stridelab.pipeline.privacy import stored_name
    except ImportError:                     # a StrideLab that stores file names as given (to check the test fails)
        def stored_name(f):
            return f
    inputs = {inbox / f for v in variants if not v.imported for f in v.files}
    inputs |= {inbox / f"{Path(f).stem}.session.toml" for v in variants for f in v.files}
    texts = {**catalog_texts(home), **home_texts(home, frozenset(inputs)),
             **{f"report:{k}": x for k, x in report_texts(home).items()}}
    con = duckdb.connect(str(home / "warehouse" / "catalog.duckdb"), read_only=True)
    status = dict(con.execute("SELECT file_name, status FROM recordings").fetchall())
    con.close()
    rows = []
    for v in variants:
        where = sorted({k for k in texts for n in v.needles if _found(n, texts[k])})
        st = [status.get(stored_name(f), status.get(f)) for f in v.files]
        refused = v.import_refused or (bool(st) and all(s == "quarantined" for s in st))
        rows.append({"variant": v.id, "what": v.what, "stored": int(bool(where)), "where": where,
                     "refused": int(refused and not where), "dropped": int(not refused and not where),
                     "status": st})
    return rows


def run_corpus(root: Path, cli) -> tuple[Path, list[Variant]]:
    """Build the corpus under ``root`` and run it through ``stridelab run``; returns (home, variants)."""
    home, inbox, studies = root / "home", root / "home" / "inbox", root / "studies"
    (studies / "corpus").mkdir(parents=True, exist_ok=True)
    (studies / "corpus" / "study.toml").write_text(STUDY_TOML)
    env = {"STRIDELAB_HOME": str(home), "STRIDELAB_STUDIES": str(studies),
           "STRIDELAB_PSEUDONYM_KEY": str(root / "keys" / "pseudonym.key")}
    os.environ.update(env)                  # stored_name() in this process uses the same key as the CLI

    def run(*args):
        return cli(*args, env=env)
    variants = build(inbox, root / "work", run) + build_earlier(inbox)
    r = run("run", "--inbox", inbox, "--jobs", "2", "--json")
    assert r.returncode == 1, r.stderr[-2000:]          # 1: ran, some files quarantined
    return home, variants


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    from tests.pipeline.test_runner import cli
    root = tmp_path_factory.mktemp("privacy_corpus")
    key = root / "keys" / "pseudonym.key"
    from stridelab.pipeline.pseudonym import create_key
    create_key(key)
    old = {k: os.environ.get(k) for k in ("STRIDELAB_HOME", "STRIDELAB_STUDIES", "STRIDELAB_PSEUDONYM_KEY")}
    try:
        home, variants = run_corpus(root, cli)
        rows = audit(home, home / "inbox", variants)
        yield home, rows
    finally:
        for k, x in old.items():
            if x is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = x


def _table(rows) -> str:
    lines = [f"{'variant':8} {'stored':>6} {'refused':>7} {'dropped':>7}  what / where"]
    for r in rows:
        lines.append(f"{r['variant']:8} {r['stored']:6d} {r['refused']:7d} {r['dropped']:7d}  {r['what']}"
                     + (f"  FOUND IN {r['where'][:4]}" if r["where"] else ""))
    tot = {k: sum(r[k] for r in rows) for k in ("stored", "refused", "dropped")}
    lines.append(f"{'total':8} {tot['stored']:6d} {tot['refused']:7d} {tot['dropped']:7d}  ({len(rows)} variants)")
    return "\n".join(lines)


@pytest.mark.slow
def test_no_variant_of_the_corpus_is_stored_anywhere(corpus):
    home, rows = corpus
    print("\n" + _table(rows))
    assert len([r for r in rows if r["variant"].startswith("v")]) == 31 and len(rows) == 31 + len(EARLIER)
    # the audit looked somewhere: the catalog has rows, reports exist, the ingested variants are in the catalog
    assert report_texts(home), "no participant report was written"
    assert sum(r["dropped"] for r in rows) >= 5, _table(rows)
    stored = [r for r in rows if r["stored"]]
    assert not stored, _table(rows)


@pytest.mark.slow
def test_the_audit_finds_a_value_that_is_stored(corpus):
    """The search is not blind: values the corpus stores on purpose (pseudonyms, the allow-listed comment of a
    clean variant) are found where they are kept."""
    home, _ = corpus
    texts = {**catalog_texts(home), **home_texts(home), **report_texts(home)}      # inputs included
    assert any(_found("C16", t) for t in texts.values())          # the pseudonym of an ingested variant
    assert any(_found("foot_left", t) for t in texts.values())


if __name__ == "__main__":
    from tests.pipeline.test_runner import cli as _cli
    base = Path(sys.argv[1])
    from stridelab.pipeline.pseudonym import create_key
    if not (base / "keys" / "pseudonym.key").exists():
        create_key(base / "keys" / "pseudonym.key")
    h, vs = run_corpus(base, _cli)
    print(_table(audit(h, h / "inbox", vs)))
