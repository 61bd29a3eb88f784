"""``stridelab bench checksums``: what the series files' page checksums cost (docs/integrity.md).

An IMU series of ``--rows`` rows (the ingest schema: stamps 100 Hz, six float columns of 4-decimal values, like a
device's scaled counts) is written through :class:`stridelab.warehouse.store.SeriesWriter` in slices of 2^19 rows, with and
without ``write_page_checksum``, and read back one row group at a time on one thread (as the stages read) with and
without ``page_checksum_verification``; ``--repeat`` times each, alternating, the median CPU seconds of this
process reported. Nothing else differs between the two (same writer options, same file)."""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

import click
import numpy as np


def _measure(rows: int, repeat: int, workdir: Path) -> dict:
    import pyarrow as pa
    import pyarrow.parquet as pq

    import stridelab.warehouse.store as store
    from stridelab.pipeline.ingest.series import SCHEMAS
    rng = np.random.default_rng(0)
    t = (1_772_438_400_000_000_000 + np.arange(rows) * 10_000_000).astype(np.int64)
    cols = [pa.array(t), pa.array(t + 1_000_000)] + [pa.array(np.round(rng.normal(0, 1, rows), 4)) for _ in range(6)]
    tab = pa.Table.from_arrays(cols, schema=SCHEMAS["imu"])
    real_init = pq.ParquetWriter.__init__
    out = {False: ([], []), True: ([], [])}
    try:
        for k in range(repeat):
            for checksum in (False, True):
                def init(self, *a, _c=checksum, **kw):
                    kw["write_page_checksum"] = _c
                    return real_init(self, *a, **kw)
                pq.ParquetWriter.__init__ = init
                rel = f"series/bench-{k}-{int(checksum)}.parquet"
                c0 = time.process_time()
                w = store.SeriesWriter(workdir, rel, tab.schema)
                for i in range(0, rows, 1 << 19):
                    w.write(tab.slice(i, 1 << 19))
                w.commit()
                out[checksum][0].append(time.process_time() - c0)
                pq.ParquetWriter.__init__ = real_init
                c0 = time.process_time()
                f = pq.ParquetFile(workdir / rel, page_checksum_verification=checksum)
                for rg in range(f.num_row_groups):
                    f.read_row_group(rg, use_threads=False)
                out[checksum][1].append(time.process_time() - c0)
                size = (workdir / rel).stat().st_size
                (workdir / rel).unlink()
    finally:
        pq.ParquetWriter.__init__ = real_init
    med = lambda v: round(float(np.median(v)), 3)                      # noqa: E731
    return {"rows": rows, "file_mb": round(size / 1e6, 1), "repeat": repeat,
            "write_cpu_s": med(out[False][0]), "write_cpu_s_checksums": med(out[True][0]),
            "read_cpu_s": med(out[False][1]), "read_cpu_s_checksums": med(out[True][1])}


@click.command("checksums")
@click.option("--rows", type=click.IntRange(1 << 16, 1 << 26), default=4_000_000, show_default=True)
@click.option("--repeat", type=click.IntRange(1, 20), default=3, show_default=True)
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
def command(rows, repeat, as_json) -> None:
    """CPU cost of the series files' page checksums: writing and reading with and without them.

    \b
    Examples:
      stridelab bench checksums --json
      stridelab bench checksums --rows 8640000 --repeat 5
    """
    from stridelab.pipeline.console import emit_json, err_console
    with tempfile.TemporaryDirectory() as d:
        res = _measure(rows, repeat, Path(d))
    if as_json:
        emit_json(res)
    else:
        err_console.print(f"{res['rows']:,} rows ({res['file_mb']} MB): write {res['write_cpu_s']} -> "
                          f"{res['write_cpu_s_checksums']} CPU-s, read {res['read_cpu_s']} -> "
                          f"{res['read_cpu_s_checksums']} CPU-s (median of {res['repeat']})")
