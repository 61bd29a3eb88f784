"""``stridelab export table NAME OUT.{csv,parquet}``: one warehouse table, as stored, from the newest snapshot."""
from __future__ import annotations

import os
import re
from pathlib import Path

from stridelab.pipeline.temp_names import temporary_name

FORMATS = (".csv", ".parquet")
_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
#: columns that could carry what a shared file should not: where a participant's file came from on disk
PRIVATE_COLUMNS = {"recordings": ("source_path",), "inbox_seen": ("source_path",)}


def table_names(con) -> list[str]:
    return [r[0] for r in con.execute("SELECT table_name FROM information_schema.tables "
                                      "WHERE table_schema = 'main' ORDER BY 1").fetchall()]


def export_table(warehouse: str | Path, name: str, out: str | Path) -> dict:
    """Write table ``name`` of the newest snapshot of ``warehouse`` to ``out`` (``.csv`` or ``.parquet`` by its
    suffix), atomically (a temporary file, then rename). Returns ``{"table", "rows", "columns", "path"}``.

    Raises ValueError (one line: what is wrong, what to do) for an unknown table or suffix."""
    from stridelab.warehouse.read import connect_snapshot
    out = Path(out)
    if out.suffix.lower() not in FORMATS:
        raise ValueError(f"{out}: unknown output format '{out.suffix}'; name the file .csv or .parquet")
    con = connect_snapshot(warehouse)
    if con is None:
        raise ValueError(f"{warehouse}: no published snapshot (not a warehouse, or nothing ran yet); "
                         f"run `stridelab run` first")
    try:
        names = table_names(con)
        if not _IDENT.match(name) or name not in names:
            raise ValueError(f"no table '{name}' in {warehouse}; tables: {', '.join(names)}")
        cols = [r[0] for r in con.execute("SELECT column_name FROM information_schema.columns WHERE "
                                          "table_schema = 'main' AND table_name = ? ORDER BY ordinal_position",
                                          [name]).fetchall()]
        keep = [c for c in cols if c not in PRIVATE_COLUMNS.get(name, ())]
        sel = ", ".join('"' + c.replace('"', '""') + '"' for c in keep)
        table = con.sql(f'SELECT {sel} FROM "{name}"').to_arrow_table()
    finally:
        con.close()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = temporary_name(out)
    try:
        if out.suffix.lower() == ".parquet":
            import pyarrow.parquet as pq
            pq.write_table(table, tmp, compression="zstd")
        else:
            import pyarrow.csv as pcsv
            pcsv.write_csv(_csv_safe(table), tmp)
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
    return {"table": name, "rows": table.num_rows, "columns": keep, "path": str(out),
            "left_out": [c for c in cols if c not in keep]}


def _csv_safe(table):
    """JSON and other nested columns as text (CSV has no nested types)."""
    import pyarrow as pa
    import pyarrow.compute as pc
    cols = []
    for f, col in zip(table.schema, table.columns):
        if pa.types.is_nested(f.type) or pa.types.is_dictionary(f.type):
            col = pc.cast(col, pa.string()) if pa.types.is_dictionary(f.type) else \
                pa.array([None if v is None else str(v) for v in col.to_pylist()], pa.string())
        cols.append(col)
    return pa.table(cols, names=table.column_names)
