"""Compare two warehouses built from the same inbox (issue #45 identity check of the stage shape):
every catalog table row for row (run-specific columns left out), every Parquet series a catalog row points to
value for value, and the stage stamps (equal stamps = a warehouse built before is not recomputed).

    python tests/pipeline/compare_warehouses.py WAREHOUSE_A WAREHOUSE_B

Exit 0 and one line per table when identical; 1 and the first differences otherwise."""
from __future__ import annotations

import sys
from pathlib import Path

import pyarrow.parquet as pq

from stridelab.warehouse.read import connect_snapshot

#: columns that differ between two runs of identical code (run ids, wall clock, CPU time, file stamps)
RUN_COLUMNS = {"run_id", "started_at", "finished_at", "created_at", "ingested_at", "applied_at", "cpu_s", "wall_s",
               "computed_at", "updated_at", "elapsed_s", "peak_rss_mb", "worker", "pid", "ingest_run_id"}
#: per table, further run-specific columns (a stage run's wall time)
RUN_COLUMNS_OF = {"stage_runs": {"duration_s"}}


def _tables(con) -> list[str]:
    return [r[0] for r in con.execute("SELECT table_name FROM information_schema.tables WHERE table_schema = 'main' "
                                      "AND table_type = 'BASE TABLE' ORDER BY 1").fetchall()]


def _rows(con, table: str) -> tuple[list[str], list[tuple]]:
    skip = RUN_COLUMNS | RUN_COLUMNS_OF.get(table, set())
    cols = [r[0] for r in con.execute(f"DESCRIBE {table}").fetchall() if r[0] not in skip]
    rows = con.execute(f"SELECT {', '.join(cols) or '1'} FROM {table}").fetchall() if cols else []
    return cols, sorted(rows, key=repr)


def compare(a: Path, b: Path) -> list[str]:
    ca, cb = connect_snapshot(a), connect_snapshot(b)
    problems, series = [], set()
    ta, tb = _tables(ca), _tables(cb)
    if ta != tb:
        problems.append(f"tables differ: {sorted(set(ta) ^ set(tb))}")
    for t in sorted(set(ta) & set(tb)):
        (cols_a, ra), (cols_b, rb) = _rows(ca, t), _rows(cb, t)
        if cols_a != cols_b:
            problems.append(f"{t}: columns differ {cols_a} vs {cols_b}")
            continue
        if ra != rb:
            only_a = [r for r in ra if r not in set(rb)][:3]
            only_b = [r for r in rb if r not in set(ra)][:3]
            problems.append(f"{t}: {len(ra)} vs {len(rb)} rows; only in A {only_a}; only in B {only_b}")
        else:
            print(f"{t}: {len(ra)} rows identical")
        for c in cols_a:
            if c == "series_path" or c.endswith("_series_path"):
                series |= {r[cols_a.index(c)] for r in ra if r[cols_a.index(c)]}
    n = 0
    for rel in sorted(series):
        fa = next((p for p in (a / rel, a / "series" / rel) if p.exists()), None)
        fb = next((p for p in (b / rel, b / "series" / rel) if p.exists()), None)
        if fa is None or fb is None:
            problems.append(f"series {rel}: missing in {'A' if fa is None else 'B'}")
            continue
        xa, xb = pq.read_table(fa), pq.read_table(fb)
        if xa.schema != xb.schema or not xa.to_pandas().equals(xb.to_pandas()):     # NaN == NaN here
            problems.append(f"series {rel}: values differ")
        n += 1
    print(f"{n} Parquet series compared")
    return problems


if __name__ == "__main__":
    probs = compare(Path(sys.argv[1]), Path(sys.argv[2]))
    for p in probs:
        print("DIFF", p[:2000])
    print("IDENTICAL" if not probs else f"{len(probs)} difference(s)")
    sys.exit(1 if probs else 0)
