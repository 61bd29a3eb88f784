"""The DuckDB catalog: open + migrate, transactional writes, snapshots for readers, garbage collection.

Only ``pipeline`` writes (through :class:`Warehouse`, under :class:`warehouse.lock.RunLock`).
After every committed step the writer publishes an immutable copy of the catalog file under
``snapshots/``; readers (dashboard, reports, a notebook) open the newest copy read-only and never
block, or get blocked by, a run. Bulk series live in Parquet (:mod:`stridelab.warehouse.store`).
"""
from __future__ import annotations

import hashlib
import os
import re
import shutil
from contextlib import contextmanager
from importlib import resources
from pathlib import Path
from typing import Iterator

import duckdb
import pyarrow as pa

from stridelab.warehouse.store import TMP_PREFIX

CATALOG = "catalog.duckdb"
SNAPSHOT_DIR = "snapshots"
LATEST = "LATEST"
KEEP_SNAPSHOTS = 3


def migrations() -> list[tuple[int, str, str]]:
    """All numbered migrations shipped with the package: (version, name, sql), ascending."""
    out = []
    for f in resources.files("stridelab.warehouse.migrations").iterdir():
        m = re.match(r"^(\d{3})_(.+)\.sql$", f.name)
        if m:
            out.append((int(m.group(1)), m.group(2), f.read_text()))
    return sorted(out)


def apply_migrations(con: duckdb.DuckDBPyConnection, upto: int | None = None) -> list[int]:
    """Apply pending migrations in order, each in its own transaction; returns the versions applied."""
    con.execute("CREATE TABLE IF NOT EXISTS schema_migrations (version INTEGER PRIMARY KEY, name VARCHAR, "
                "applied_at TIMESTAMP DEFAULT current_timestamp)")
    done = {r[0] for r in con.execute("SELECT version FROM schema_migrations").fetchall()}
    applied = []
    for version, name, sql in migrations():
        if version in done or (upto is not None and version > upto):
            continue
        con.execute("BEGIN TRANSACTION")
        try:
            con.execute(sql)
            con.execute("INSERT INTO schema_migrations (version, name) VALUES (?, ?)", [version, name])
            con.execute("COMMIT")
        except Exception:
            con.execute("ROLLBACK")
            raise
        applied.append(version)
    return applied


def catalog_damaged(e: Exception) -> bool:
    """Whether DuckDB's error opening the catalog says the file is damaged (not a lock, a full disk or
    permissions)."""
    text = str(e)
    return any(m in text for m in ("not a valid DuckDB database", "checksum", "Corrupt", "corrupt",
                                   "Serialization", "Failed to read", "INTERNAL Error"))


def damaged_message(root: Path, e: Exception) -> str:
    first_line = str(e).splitlines()[0][:160] if str(e) else type(e).__name__
    return (f"cannot open the warehouse catalog {Path(root) / CATALOG}: it is damaged ({first_line}); rebuild it "
            f"from the newest good snapshot with `stridelab repair-catalog --warehouse {root}`, then "
            f"`stridelab run` ingests again what the inbox holds (docs/integrity.md)")


class Warehouse:
    """Writer handle on a warehouse directory (catalog + Parquet store + snapshots)."""

    def __init__(self, root: Path, con: duckdb.DuckDBPyConnection):
        self.root = Path(root)
        self.con = con
        self._columns: set[tuple[str, str]] | None = None

    def has_column(self, table: str, column: str) -> bool:
        """Whether ``table`` has ``column``: read once from ``information_schema`` per handle (the schema changes
        only by migrations, which :meth:`open` applies before it returns). A query per call cost a night's
        coordinator ~2 s: the runner asks for every table of every committed stage."""
        if self._columns is None:
            self._columns = {(t, c) for t, c in self.con.execute(
                "SELECT table_name, column_name FROM information_schema.columns WHERE table_schema = 'main'").fetchall()}
        return (table, column) in self._columns

    @classmethod
    def open(cls, root: str | os.PathLike, *, migrate_upto: int | None = None) -> "Warehouse":
        """Open (creating if needed) and upgrade the catalog in place."""
        root = Path(root)
        root.mkdir(parents=True, exist_ok=True)
        (root / SNAPSHOT_DIR).mkdir(exist_ok=True)
        try:
            con = duckdb.connect(str(root / CATALOG))
        except duckdb.IOException as e:
            if catalog_damaged(e):
                raise RuntimeError(damaged_message(root, e)) from None
            raise RuntimeError(f"cannot open the warehouse catalog {root / CATALOG} for writing: "
                               f"{str(e).splitlines()[0]}") from None
        except duckdb.Error as e:
            raise RuntimeError(damaged_message(root, e)) from None
        try:
            apply_migrations(con, migrate_upto)
        except duckdb.Error as e:
            con.close()
            if isinstance(e, duckdb.IOException) and not catalog_damaged(e):
                raise
            raise RuntimeError(damaged_message(root, e)) from None
        return cls(root, con)

    def close(self) -> None:
        self.con.close()

    def __enter__(self) -> "Warehouse":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @contextmanager
    def transaction(self) -> Iterator[duckdb.DuckDBPyConnection]:
        self.con.execute("BEGIN TRANSACTION")
        try:
            yield self.con
        except BaseException:
            self.con.execute("ROLLBACK")
            raise
        self.con.execute("COMMIT")

    def insert(self, table: str, rows: pa.Table | list[dict]) -> None:
        """Insert rows by column name (missing columns get NULL/defaults)."""
        if isinstance(rows, list):
            if not rows:
                return
            rows = pa.Table.from_pylist(rows)
        if rows.num_rows == 0:
            return
        cols = ", ".join(f'"{c}"' for c in rows.column_names)
        # DuckDB finds the Arrow table by its variable's name in this frame (a replacement scan; a catalog table
        # of that name would win, hence the unlikely name): 0.6-1.0 instead of 1.2-1.6 ms per insert with
        # register/unregister around it, ~900 inserts in a 20-participant night
        _stridelab_insert_rows = rows  # noqa: F841 - read by the statement below
        self.con.execute(f'INSERT INTO "{table}" ({cols}) SELECT {cols} FROM _stridelab_insert_rows')

    # ---- snapshots ------------------------------------------------------------------------
    def publish_snapshot(self) -> Path:
        """Checkpoint and publish an immutable copy of the catalog for readers; prune old copies."""
        self.con.execute("CHECKPOINT")
        snap_dir = self.root / SNAPSHOT_DIR
        existing = sorted(snap_dir.glob("catalog-*.duckdb"))
        seq = int(existing[-1].stem.split("-")[1]) + 1 if existing else 1
        final = snap_dir / f"catalog-{seq:08d}.duckdb"
        tmp = snap_dir / f"{TMP_PREFIX}{final.name}"
        try:
            shutil.copyfile(self.root / CATALOG, tmp)
            with open(tmp, "rb") as f:
                os.fsync(f.fileno())
            os.replace(tmp, final)
        except BaseException:
            tmp.unlink(missing_ok=True)    # the previous snapshot stays the newest
            raise
        latest_tmp = snap_dir / f"{TMP_PREFIX}{LATEST}"
        latest_tmp.write_text(final.name)
        os.replace(latest_tmp, snap_dir / LATEST)
        for old in existing[: max(0, len(existing) + 1 - KEEP_SNAPSHOTS)]:
            old.unlink(missing_ok=True)   # readers that still hold it open keep their inode
        return final

    # ---- garbage collection ---------------------------------------------------------------
    def referenced_paths(self) -> set[str]:
        """Series paths referenced by the catalog or by any retained snapshot."""
        refs = set(_series_paths(self.con))
        for snap in (self.root / SNAPSHOT_DIR).glob("catalog-*.duckdb"):
            try:
                with duckdb.connect(str(snap), read_only=True) as c:
                    refs |= set(_series_paths(c))
            except duckdb.Error:
                continue
        return refs

    def gc(self) -> int:
        """Delete temporary files of interrupted runs and Parquet files nobody refers to."""
        refs = self.referenced_paths()
        removed = 0
        series = self.root / "series"
        if series.is_dir():
            for p in series.rglob("*"):
                if not p.is_file():
                    continue
                rel = p.relative_to(self.root).as_posix()
                if p.name.startswith(TMP_PREFIX) or rel not in refs:
                    p.unlink(missing_ok=True)
                    removed += 1
        for p in (self.root / SNAPSHOT_DIR).glob(f"{TMP_PREFIX}*"):
            p.unlink(missing_ok=True)
        return removed

    # ---- comparison (tests, backfill checks) ---------------------------------------------
    def fingerprint(self) -> dict[str, str]:
        return fingerprint(self.con, self.root)


def _series_paths(con: duckdb.DuckDBPyConnection) -> list[str]:
    tables = [r[0] for r in con.execute(
        "SELECT table_name FROM information_schema.columns WHERE column_name = 'series_path'").fetchall()]
    out: list[str] = []
    for t in tables:
        out += [r[0] for r in con.execute(f'SELECT series_path FROM "{t}"').fetchall() if r[0]]
    return out


#: ledger tables and wall-clock columns excluded from the content fingerprint
LEDGER_TABLES = {"pipeline_runs", "stage_runs", "schema_migrations", "reports", "ingest_topics"}
VOLATILE_COLUMNS = {"ingested_at", "source_path"}


def fingerprint(con: duckdb.DuckDBPyConnection, root: Path) -> dict[str, str]:
    """Content hash per catalog table (sorted rows) and per series file (decoded data).

    Two warehouses with equal fingerprints hold the same results, whatever the run history.
    """
    import pyarrow.parquet as pq
    out = {}
    tables = [r[0] for r in con.execute(
        "SELECT table_name FROM information_schema.tables WHERE table_schema = 'main' ORDER BY 1").fetchall()]
    for t in tables:
        if t in LEDGER_TABLES:
            continue
        cols = [r[0] for r in con.execute(
            "SELECT column_name FROM information_schema.columns WHERE table_name = ? ORDER BY ordinal_position",
            [t]).fetchall() if r[0] not in VOLATILE_COLUMNS]
        sel = ", ".join(f'CAST("{c}" AS VARCHAR)' for c in cols)
        rows = con.execute(f'SELECT {sel} FROM "{t}" ORDER BY ALL').fetchall()
        out[f"table:{t}"] = hashlib.sha256(repr(rows).encode()).hexdigest()
    for p in sorted(set(_series_paths(con))):
        tbl = pq.read_table(Path(root) / p)
        h = hashlib.sha256()
        for col in tbl.columns:
            for chunk in col.chunks:
                for buf in chunk.buffers():
                    if buf is not None:
                        h.update(buf)
        out[f"series:{p}"] = h.hexdigest()
    return out


def first(cursor) -> tuple | None:
    """First row of a query result or None, consuming the whole result (DuckDB ≥ 2 refuses new work on a
    connection while a result is only partly fetched)."""
    rows = cursor.fetchall()
    return rows[0] if rows else None
