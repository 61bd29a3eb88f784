"""``stridelab verify``: check a whole warehouse (catalog, snapshots, every series file) and repair what can be.

Every series file carries a CRC-32 per Parquet page (warehouse/store.py); :func:`verify` reads each file the
catalog refers to in full with the checksums verified, and compares its row count with the catalog's. A damaged
file is never served (every read verifies the pages it touches and raises
:class:`stridelab.warehouse.store.SeriesDamaged`); with ``repair``:

- a raw series (``sensors``) is recomputed from its recording when the file is found with the same SHA-256 (the
  catalog keeps only a keyed hash of the path, stridelab.pipeline.privacy: the recording is looked for in the folders given
  with ``search`` and the default inbox, by that hash, else by size and SHA-256): the recording is decoded again (with the ingest settings it was ingested with) into a
  scratch folder, the new file must give the recording's sample hash, and it replaces the damaged one;
- a stage output is dropped from the stage's state, so the next ``stridelab run`` recomputes it (the new file
  takes the same name).

What cannot be repaired is listed with the reason (docs/integrity.md).
"""
from __future__ import annotations

import json
import os
import shutil
import uuid
from dataclasses import dataclass, field
from pathlib import Path

import duckdb

from stridelab.warehouse.catalog import CATALOG, SNAPSHOT_DIR, first
from stridelab.warehouse.store import SeriesDamaged, damage_check, open_series


@dataclass
class VerifyReport:
    catalog: str = "ok"                               # "ok" or the one-line problem
    snapshots: list[dict] = field(default_factory=list)
    checked: int = 0
    damaged: list[dict] = field(default_factory=list)  # {path, table, detail, repair}
    repaired: list[str] = field(default_factory=list)
    scheduled: list[str] = field(default_factory=list)  # stage outputs the next run recomputes
    unrepaired: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.catalog == "ok" and not self.damaged and all(s["status"] == "ok" for s in self.snapshots)

    def as_dict(self) -> dict:
        return {"ok": self.ok, "catalog": self.catalog, "snapshots": self.snapshots, "checked": self.checked,
                "damaged": self.damaged, "repaired": self.repaired, "scheduled": self.scheduled,
                "unrepaired": self.unrepaired}


def check_series_file(root: Path, relpath: str, expected_rows: int | None = None) -> str | None:
    """None if every page of the file reads with a matching checksum (and the row count is as expected), else
    the problem in a few words."""
    try:
        with damage_check(relpath):
            f = open_series(root, relpath)
            n = f.metadata.num_rows
            for rg in range(f.num_row_groups):
                f.read_row_group(rg, use_threads=False)
    except SeriesDamaged as e:
        return e.detail
    if expected_rows is not None and n != expected_rows:
        return f"{n} rows where the catalog says {expected_rows}"
    return None


def _series_rows(con) -> list[tuple[str, str, str | None, int | None]]:
    """(table, series_path, session_id or content_hash, expected rows) of every series file the catalog names."""
    tables = [r[0] for r in con.execute(
        "SELECT DISTINCT table_name FROM information_schema.columns WHERE column_name = 'series_path' "
        "AND table_schema = 'main' ORDER BY 1").fetchall()]
    out = []
    for t in tables:
        if t == "sensors":
            rows = con.execute("SELECT series_path, content_hash, n_samples FROM sensors").fetchall()
        else:
            cols = {r[0] for r in con.execute("SELECT column_name FROM information_schema.columns "
                                              "WHERE table_name = ?", [t]).fetchall()}
            key = "session_id" if "session_id" in cols else "NULL"
            rows = [(p, k, None) for p, k in con.execute(f'SELECT series_path, {key} FROM "{t}"').fetchall()]
        out += [(t, p, k, n) for p, k, n in rows if p]
    return out


def check_catalog(root: Path) -> str:
    """"ok", or one line naming the catalog file and the problem."""
    path = Path(root) / CATALOG
    if not path.exists():
        return "ok"
    try:
        con = duckdb.connect(str(path), read_only=True)
    except duckdb.IOException as e:
        if "lock" in str(e).lower():
            return "ok"                                 # a run holds it: not damage
        return f"{path}: {str(e).splitlines()[0]}"
    except duckdb.Error as e:
        return f"{path}: {str(e).splitlines()[0]}"
    try:
        con.execute("SELECT count(*) FROM recordings").fetchall()
    except duckdb.Error as e:
        return f"{path}: {str(e).splitlines()[0]}"
    finally:
        con.close()
    return "ok"


def check_snapshots(root: Path) -> list[dict]:
    out = []
    for snap in sorted((Path(root) / SNAPSHOT_DIR).glob("catalog-*.duckdb")):
        try:
            with duckdb.connect(str(snap), read_only=True) as c:
                c.execute("SELECT count(*) FROM recordings").fetchall()
            out.append({"snapshot": snap.name, "status": "ok"})
        except duckdb.Error as e:
            out.append({"snapshot": snap.name, "status": str(e).splitlines()[0][:200]})
    return out


def verify(root: str | os.PathLike, *, repair: bool = False, search=(), on_progress=lambda msg: None) -> VerifyReport:
    """Check the warehouse at ``root``; with ``repair`` (holding the run lock) recompute what can be, finding
    recordings in the folders (or files) ``search`` and the default inbox."""
    root = Path(root)
    rep = VerifyReport()
    rep.catalog = check_catalog(root)
    rep.snapshots = check_snapshots(root)
    if rep.catalog != "ok" and not repair:
        return rep
    if repair:
        from stridelab.warehouse.catalog import Warehouse
        from stridelab.warehouse.lock import RunLock
        if rep.catalog != "ok":
            return rep                   # the catalog itself: `stridelab repair-catalog` (pipeline/recover.py)
        with RunLock(root, "verify --repair"), Warehouse.open(root) as wh:
            _check_all(root, wh.con, rep, on_progress)
            _repair(wh, rep, on_progress, [Path(x) for x in search])
        return rep
    con = _reader(root)
    if con is None:
        return rep
    try:
        _check_all(root, con, rep, on_progress)
    finally:
        con.close()
    return rep


def _reader(root: Path):
    """The catalog read-only, or the newest snapshot while a run holds the catalog."""
    try:
        return duckdb.connect(str(root / CATALOG), read_only=True)
    except duckdb.Error:
        from stridelab.warehouse.read import connect_snapshot
        return connect_snapshot(root)


def _check_all(root: Path, con, rep: VerifyReport, on_progress) -> None:
    for table, rel, key, n in _series_rows(con):
        rep.checked += 1
        problem = check_series_file(root, rel, n)
        if problem is not None:
            rep.damaged.append({"path": rel, "table": table, "key": key, "detail": problem})
            on_progress(f"damaged: {rel} ({problem})")


def _repair(wh, rep: VerifyReport, on_progress, search: list[Path]) -> None:
    from stridelab.pipeline.stages import registry
    owner = {t: s.name for s in registry() for t in s.tables}
    raw = {}
    for d in rep.damaged:
        if d["table"] == "sensors":
            raw.setdefault(d["key"], []).append(d)
        elif d["table"] in owner and d["key"]:
            with wh.transaction() as con:
                con.execute("DELETE FROM stage_state WHERE session_id = ? AND stage = ?", [d["key"], owner[d["table"]]])
            d["repair"] = f"the next `stridelab run` recomputes {owner[d['table']]} of session {d['key']}"
            rep.scheduled.append(d["path"])
        else:
            d["repair"] = "no producer known: cannot be recomputed"
            rep.unrepaired.append(d["path"])
    for content_hash, items in raw.items():
        why = _recompute_raw(wh, content_hash, [d["path"] for d in items], search)
        for d in items:
            if why is None:
                d["repair"] = "recomputed from the recording"
                rep.repaired.append(d["path"])
            else:
                d["repair"] = why
                rep.unrepaired.append(d["path"])
            on_progress(f"{d['path']}: {d['repair']}")
    if rep.repaired or rep.scheduled:
        wh.publish_snapshot()


def _candidates(search: list[Path]):
    """Recording files and bag folders in (or given as) ``search`` and the default inbox."""
    from stridelab.pipeline.config import default_inbox
    from stridelab.pipeline.formats.rosbag2 import is_bag
    for d in [*search, default_inbox()]:
        if d.is_file() or is_bag(d):
            yield d
        elif d.is_dir():
            for p in sorted(d.rglob("*")):
                if (p.is_file() and not p.is_symlink() and p.suffix.lower() in (".mcap", ".db3")) or is_bag(p):
                    yield p


def find_recording(wh, content_hash: str, search: list[Path]) -> Path | None:
    """Where the recording with ``content_hash`` is now: the catalog keeps only a keyed hash of its path and its
    size (stridelab.pipeline.privacy), so a candidate matches by that hash, else (moved or renamed) by size and SHA-256."""
    from stridelab.pipeline import ingest
    from stridelab.pipeline.privacy import stored_path
    r = first(wh.con.execute("SELECT source_path, size_bytes FROM recordings WHERE content_hash = ?", [content_hash]))
    source, size = (r or (None, None))
    cands = list(dict.fromkeys(_candidates(search)))
    for p in cands:
        if stored_path(p) == source and ingest.content_hash(p) == content_hash:
            return p
    for p in cands:
        if (p.is_dir() or size is None or p.stat().st_size == size) and ingest.content_hash(p) == content_hash:
            return p
    return None


def _recompute_raw(wh, content_hash: str, paths: list[str], search: list[Path] = ()) -> str | None:
    """Decode the recording again and put the damaged files back; None on success, else why not."""
    from stridelab.pipeline import ingest
    r = first(wh.con.execute("SELECT source_path, sample_hash, status FROM recordings WHERE content_hash = ?",
                             [content_hash]))
    if r is None or r[2] != "ingested":
        return "its recording is not ingested"
    _, sample_hash, _ = r
    src = find_recording(wh, content_hash, list(search))
    if src is None:
        from stridelab.pipeline.privacy import stored_path
        moved = [p for p in _candidates(list(search)) if stored_path(p) == r[0]]
        if moved:
            return f"cannot be recomputed: the file at {moved[0]} changed since it was ingested"
        return ("cannot be recomputed: the recording is no longer at its path nor in the folders searched (the "
                "inbox" + "".join(f", {p}" for p in search) + "); pass its folder with --search DIR, or ingest it "
                "again with --replace")
    options = _stored_options(wh, content_hash)
    scratch = wh.root / f".repair-{uuid.uuid4().hex[:8]}"
    try:
        p = ingest.prepare(src, wh.root, options, series_root=scratch)
        if p.status != "ingested":
            return f"cannot be recomputed: decoding the recording again failed ({p.reason})"
        if sample_hash and p.sample_hash != sample_hash:
            return "cannot be recomputed: the recording decodes to other samples than were stored"
        for rel in paths:
            new = scratch / rel
            if not new.exists():
                return "cannot be recomputed: the recording no longer gives this series"
            if check_series_file(scratch, rel) is not None:
                return "cannot be recomputed: the recomputed file does not verify"
            os.replace(new, wh.root / rel)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return None


def _stored_options(wh, content_hash: str) -> dict:
    if not wh.has_column("recordings", "ingest_settings"):
        return {}
    r = first(wh.con.execute("SELECT ingest_settings FROM recordings WHERE content_hash = ?", [content_hash]))
    s = json.loads(r[0]) if r and r[0] else {}
    return {k: s[k] for k in ("session", "topic_map", "skip_topics") if k in s}
