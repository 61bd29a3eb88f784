"""Read API over the newest published snapshot (never blocks, never blocked by a run)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import duckdb
import numpy as np

from stridelab.warehouse.catalog import first, LATEST, SNAPSHOT_DIR
from stridelab.warehouse.direct_io import open_for_read
from stridelab.warehouse.store import UNCACHE_BYTES, damage_check, open_series, read_table


def _pointed(root: Path) -> Path | None:
    """The snapshot the LATEST pointer names (or the newest file on disk when the pointer moved on)."""
    pointer = root / SNAPSHOT_DIR / LATEST
    try:
        name = pointer.read_text().strip()
    except FileNotFoundError:
        return None
    path = root / SNAPSHOT_DIR / name
    if path.exists():
        return path
    # the pointer moved on between our read and now: take the newest file on disk
    snaps = sorted((root / SNAPSHOT_DIR).glob("catalog-*.duckdb"))
    return snaps[-1] if snaps else None


#: (path, size, mtime_ns) -> None when the snapshot opens and reads, else the problem (snapshots never change)
_CHECKED: dict[tuple[str, int, int], str | None] = {}


def snapshot_problem(path: Path) -> str | None:
    """None when the snapshot file opens read-only and its catalog reads, else the problem in one line."""
    try:
        st = path.stat()
    except FileNotFoundError:
        return None                          # pruned meanwhile: not damage
    key = (str(path), st.st_size, st.st_mtime_ns)
    if key not in _CHECKED:
        try:
            with duckdb.connect(str(path), read_only=True) as c:
                c.execute("SELECT count(*) FROM schema_migrations").fetchall()
            _CHECKED[key] = None
        except duckdb.Error as e:
            if not path.exists():
                return None
            _CHECKED[key] = (str(e).splitlines()[0] if str(e) else type(e).__name__)[:200]
    return _CHECKED[key]


def snapshot_status(root: str | Path) -> tuple[Path | None, str | None]:
    """(the newest snapshot that opens, a message when it is not the newest published one): a damaged newest
    snapshot falls back to the previous one, and the message says so and what to do."""
    root = Path(root)
    newest = _pointed(root)
    if newest is None:
        return None, None
    problem = snapshot_problem(newest)
    if problem is None:
        return newest, None
    for older in sorted((root / SNAPSHOT_DIR).glob("catalog-*.duckdb"), reverse=True):
        if older.name < newest.name and snapshot_problem(older) is None:
            return older, (f"the newest snapshot {newest.name} is damaged ({problem}); showing the previous one, "
                           f"{older.name}. The next `stridelab run` publishes a new one; `stridelab verify` "
                           f"checks the warehouse (docs/integrity.md)")
    return None, (f"every snapshot of {root} is damaged (newest: {newest.name}: {problem}); rebuild with "
                  f"`stridelab repair-catalog` (docs/integrity.md)")


def latest_snapshot(root: str | Path) -> Path | None:
    """Path of the newest published catalog snapshot that opens (a damaged newest one falls back to the
    previous one: :func:`snapshot_status` says so), or None if the warehouse has none yet."""
    return snapshot_status(root)[0]


def connect_snapshot(root: str | Path) -> duckdb.DuckDBPyConnection | None:
    """Read-only connection to the newest snapshot (None when nothing was published yet)."""
    for _ in range(3):   # the newest file may be pruned between lookup and open
        snap = latest_snapshot(root)
        if snap is None:
            return None
        try:
            return duckdb.connect(str(snap), read_only=True)
        except duckdb.IOException:
            continue
    return None


@dataclass(frozen=True)
class ImuSeries:
    """Samples of one IMU of one recording: t_ns (N,), acc (N,3) m/s², gyr (N,3) rad/s,
    mag (N,3) µT or None, sampling_rate_hz."""
    t_ns: np.ndarray
    acc: np.ndarray
    gyr: np.ndarray
    mag: np.ndarray | None
    sampling_rate_hz: float


def _read_columns(root, relpath: str, groups: dict[str, tuple[str, ...]]) -> dict[str, np.ndarray]:
    """Read named column groups of a series file into preallocated arrays, one row group at a time, so the
    peak memory is the arrays themselves plus one row group (not a whole Arrow table beside them)."""
    with damage_check(relpath):
        return _read_columns_checked(root, relpath, groups)


def _read_columns_checked(root, relpath: str, groups: dict[str, tuple[str, ...]]) -> dict[str, np.ndarray]:
    f = open_series(root, relpath)
    n = f.metadata.num_rows
    out = {g: (np.empty(n, dtype=np.int64) if len(cols) == 1 else np.empty((n, len(cols))))
           for g, cols in groups.items()}
    names = [c for cols in groups.values() for c in cols]
    i = 0
    for rg in range(f.num_row_groups):
        b = f.read_row_group(rg, columns=names, use_threads=False)
        k = b.num_rows
        for g, cols in groups.items():
            for j, c in enumerate(cols):
                v = b.column(c).to_numpy()
                if out[g].ndim == 1:
                    out[g][i:i + k] = v
                else:
                    out[g][i:i + k, j] = v
        i += k
        del b
    return out


def series_rows(root, relpath: str) -> int:
    return open_series(root, relpath).metadata.num_rows


def read_column_range(root, relpath: str, columns: tuple[str, ...], start: int = 0, stop: int | None = None,
                      dtype=np.float64) -> np.ndarray:
    """Rows [start, stop) of ``columns`` of a series file as ``dtype`` ((n,) for one column, else (n, k)),
    reading only the row groups that overlap, so a slice of a week-long series costs the slice, not the week."""
    with damage_check(relpath):
        src = open_for_read(Path(root) / relpath, UNCACHE_BYTES)
    try:
        # pre_buffer: a row group's column chunks in one coalesced read instead of one read each (the
        # accelerometer of a 24 h chest day from the disk: 0.20-0.23 s and 0.10-0.12 CPU-s instead of 0.26-0.43 s
        # and 0.13-0.28 CPU-s); still one row group at a time
        with damage_check(relpath):
            return _read_column_range(open_series(root, relpath, src, pre_buffer=True), columns, start, stop, dtype)
    finally:
        if not isinstance(src, Path):
            src.close()


def _read_column_range(f, columns, start, stop, dtype) -> np.ndarray:
    n = f.metadata.num_rows
    stop = n if stop is None else min(int(stop), n)
    start = max(0, int(start))
    m = max(0, stop - start)
    out = np.empty(m, dtype=dtype) if len(columns) == 1 else np.empty((m, len(columns)), dtype=dtype)
    i0 = 0
    for rg in range(f.num_row_groups):
        k = f.metadata.row_group(rg).num_rows
        a, b = max(start, i0), min(stop, i0 + k)
        if a < b:
            t = f.read_row_group(rg, columns=list(columns), use_threads=False)
            for j, c in enumerate(columns):
                v = t.column(c).to_numpy()[a - i0:b - i0]
                if out.ndim == 1:
                    out[a - start:b - start] = v
                else:
                    out[a - start:b - start, j] = v
            del t
        i0 += k
        if i0 >= stop:
            break
    return out


def read_imu_files(root: str | Path, imu_path: str, mag_path: str | None, sampling_rate_hz: float) -> ImuSeries:
    """Load an IMU series (and its magnetometer, resampled onto the IMU stamps if they differ)."""
    d = _read_columns(root, imu_path, {"t_ns": ("t_ns",), "acc": ("acc_x", "acc_y", "acc_z"),
                                       "gyr": ("gyr_x", "gyr_y", "gyr_z")})
    t_ns, acc, gyr = d["t_ns"], d["acc"], d["gyr"]
    mag = None
    if mag_path:
        m = _read_columns(root, mag_path, {"t_ns": ("t_ns",), "mag": ("mag_x", "mag_y", "mag_z")})
        mt, mv = m["t_ns"], m["mag"]
        if len(mt) == len(t_ns) and np.array_equal(mt, t_ns):
            mag = mv
        elif len(mt) >= 2:
            mag = np.column_stack([np.interp(t_ns, mt, mv[:, k]) for k in range(3)])
    return ImuSeries(t_ns, acc, gyr, mag, sampling_rate_hz)


def reference_orientation_on(root: str | Path, series_path: str, t_ns: np.ndarray) -> np.ndarray:
    """Optical segment orientation ([w x y z], segment→lab) of a ``reference_pose`` series at the stamps
    ``t_ns``: the nearest reference sample within half a reference period, NaN elsewhere (occlusions,
    before/after the capture)."""
    t = read_table(root, series_path, columns=["t_ns", "qw", "qx", "qy", "qz"])
    rt = t.column("t_ns").to_numpy()
    rq = np.column_stack([t.column(c).to_numpy() for c in ("qw", "qx", "qy", "qz")])
    t_ns = np.asarray(t_ns, np.int64)
    out = np.full((len(t_ns), 4), np.nan)
    if len(rt) < 2:
        return out
    half = 0.5 * float(np.median(np.diff(rt)))
    j = np.clip(np.searchsorted(rt, t_ns), 1, len(rt) - 1)
    j -= (t_ns - rt[j - 1]) < (rt[j] - t_ns)
    ok = np.abs(rt[j] - t_ns) <= half
    out[ok] = rq[j[ok]]
    return out


def read_imu(con: duckdb.DuckDBPyConnection, root: str | Path, content_hash: str, placement: str) -> ImuSeries | None:
    """IMU samples of one recording and placement, or None if that sensor is absent."""
    rows = dict(con.execute(
        "SELECT kind, series_path FROM sensors WHERE content_hash = ? AND placement = ? AND kind IN ('imu', 'mag')",
        [content_hash, placement]).fetchall())
    if "imu" not in rows:
        return None
    rate = first(con.execute("SELECT sampling_rate_hz FROM sensors WHERE content_hash = ? AND placement = ? AND kind = 'imu'",
                       [content_hash, placement]))[0]
    return read_imu_files(root, rows["imu"], rows.get("mag"), rate)


def read_orientation(con: duckdb.DuckDBPyConnection, root: str | Path, content_hash: str, placement: str):
    """(t_ns (N,), quat (N,4) [w x y z] sensor->ENU) or None."""
    r = first(con.execute("SELECT series_path FROM orientation WHERE content_hash = ? AND placement = ?",
                    [content_hash, placement]))
    if r is None:
        return None
    t = read_table(root, r[0])
    return t.column("t_ns").to_numpy(), np.column_stack([t.column(c).to_numpy() for c in ("qw", "qx", "qy", "qz")])
