"""StrideLab from Python: open a warehouse read-only, get its tables as pandas DataFrames, read a recording.

```python
import stridelab

wh = stridelab.open("stridelab-home")            # a home folder or its warehouse/ directory
strides = wh.strides(participant="P003")          # one row per stride, SI units in the column names
wh.sessions().groupby("kind").size()

rec = stridelab.read_recording("inbox/P003_lab1_walk-1.mcap")
rec.imu["foot_left"].gyr                          # (N, 3) rad/s
```

Everything here reads the warehouse's newest published snapshot (the file the dashboard reads), never the
live catalog, so it never waits for, nor blocks, a nightly run, and it cannot change anything. A
`Warehouse` keeps the snapshot it opened: reopen it (``stridelab.open`` again) to see a newer night.
Importing this module has no side effects (no environment variables, no warning filters, no heavy imports:
DuckDB and pandas are imported on first use).
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:                                    # pragma: no cover - typing only
    import duckdb
    import pandas as pd

    from stridelab.estimators.recording import Recording

__all__ = ["Warehouse", "TableMissing", "open", "read_recording", "resolve_warehouse"]

_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
#: topic prefix of each kind of series in the recording format (DESIGN.md "Recording format")
_PREFIX = {"imu": "/imu/", "mag": "/mag/", "range": "/range/", "reference_pose": "/reference/pose/"}


class TableMissing(LookupError):
    """The snapshot has no such table: the stage (or the migration) that makes it has not run on this warehouse."""


def resolve_warehouse(path: str | Path) -> Path:
    """The warehouse directory for ``path``: a warehouse (it holds ``snapshots/``) or a StrideLab home folder
    (its ``warehouse/`` subfolder). Raises FileNotFoundError with what to do otherwise."""
    from stridelab.warehouse.catalog import SNAPSHOT_DIR
    p = Path(path).expanduser()
    for cand in (p, p / "warehouse"):
        if (cand / SNAPSHOT_DIR).is_dir():
            return cand
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such folder; pass a StrideLab home (e.g. stridelab-home) or its "
                                f"warehouse/ directory")
    raise FileNotFoundError(f"{p}: not a StrideLab warehouse (no snapshots/ inside it or in {p / 'warehouse'}); "
                            f"run `stridelab run` (or `stridelab demo --no-serve`) first")


def open(home_or_warehouse: str | Path) -> Warehouse:  # noqa: A001 - the public name is stridelab.open
    """Open the newest published snapshot of a warehouse, read-only.

    Args:
        home_or_warehouse: a StrideLab home folder (``$STRIDELAB_HOME``, ``./stridelab-home`` after
            ``make demo``) or the warehouse directory inside it.

    Returns:
        A `Warehouse`; use it as a context manager, or call `Warehouse.close`.

    Raises:
        FileNotFoundError: the folder is not a warehouse, or nothing was published yet.
    """
    return Warehouse(resolve_warehouse(home_or_warehouse))


class Warehouse:
    """Read-only view of one snapshot of a StrideLab warehouse (see `open`).

    Tables come back as `pandas.DataFrame` with the warehouse's column names: times are int64
    nanoseconds since the Unix epoch, UTC (``*_ns``), other quantities carry their unit in the column name
    (``stride_length_m``, ``speed_m_s``, ``stance_pct``). Filters are passed to SQL as parameters, never as text.
    """

    def __init__(self, root: Path):
        from stridelab.warehouse.read import latest_snapshot
        self.root = Path(root)
        snap = latest_snapshot(self.root)
        if snap is None:
            raise FileNotFoundError(f"{self.root}: the warehouse has published no snapshot yet; "
                                    f"run `stridelab run` first")
        self.snapshot: Path = snap
        self._con: duckdb.DuckDBPyConnection | None = None

    # ---- plumbing ------------------------------------------------------------------------------
    @property
    def con(self) -> duckdb.DuckDBPyConnection:
        """The read-only DuckDB connection to the snapshot (opened on first use)."""
        if self._con is None:
            import duckdb
            self._con = duckdb.connect(str(self.snapshot), read_only=True)
        return self._con

    def close(self) -> None:
        """Close the connection (the object can be used again: it reopens the same snapshot)."""
        if self._con is not None:
            self._con.close()
            self._con = None

    def __enter__(self) -> Warehouse:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Warehouse({str(self.root)!r}, snapshot={self.snapshot.name!r})"

    def tables(self) -> list[str]:
        """Names of the tables in this snapshot."""
        return [r[0] for r in self.con.execute(
            "SELECT table_name FROM information_schema.tables WHERE table_schema = 'main' ORDER BY 1").fetchall()]

    def has_table(self, name: str) -> bool:
        """Whether the snapshot holds table ``name``."""
        return name in self.tables()

    def sql(self, query: str, params: list | None = None) -> pd.DataFrame:
        """Run a read-only SQL query (DuckDB dialect) on the snapshot; ``?`` placeholders take ``params``."""
        return self.con.execute(query, params or []).df()

    def table(self, name: str) -> pd.DataFrame:
        """A whole table as a DataFrame (any table of `tables`)."""
        self._need(name)
        return self.sql(f'SELECT * FROM "{name}"')

    def arrow(self, name: str):
        """A whole table as a `pyarrow.Table`."""
        self._need(name)
        return self.con.sql(f'SELECT * FROM "{name}"').to_arrow_table()

    def _need(self, name: str) -> None:
        if not _IDENT.match(name) or not self.has_table(name):
            raise TableMissing(f"no table '{name}' in {self.snapshot.name} of {self.root}; tables: "
                               f"{', '.join(self.tables())}")

    def _filtered(self, table: str, *, participant: str | None, study: str | None, session: str | None = None,
                  extra: str = "", order: str = "s.start_ns, t.session_id", produced_by: str = "") -> pd.DataFrame:
        if not self.has_table(table):
            raise TableMissing(f"no table '{table}' in this warehouse ({self.root}): it is written by "
                               f"{produced_by or 'a stage that has not run here'}; run `stridelab run` with a "
                               f"StrideLab version that has it")
        return self.sql(f"""
            SELECT s.study, s.participant_id, t.* FROM "{table}" t JOIN sessions s USING (session_id)
            WHERE (? IS NULL OR s.participant_id = ?) AND (? IS NULL OR s.study = ?)
              AND (? IS NULL OR t.session_id = ?) {extra}
            ORDER BY {order}""", [participant, participant, study, study, session, session])

    # ---- the tables a researcher asks for -----------------------------------------------------
    def participants(self, study: str | None = None) -> pd.DataFrame:
        """One row per participant (pseudonym): study, participant_id, sessions, recordings, last_data."""
        from stridelab.warehouse.queries import participants
        return participants(self.con, study)

    def sessions(self, participant: str | None = None, study: str | None = None) -> pd.DataFrame:
        """One row per session: study, participant_id, session_id, kind (lab | free_living | calibration),
        protocol, timezone, start, end (UTC timestamps), hours, recordings, trials."""
        from stridelab.warehouse.queries import sessions
        return sessions(self.con, participant, study)

    def recordings(self, participant: str | None = None, study: str | None = None) -> pd.DataFrame:
        """Ingested recordings: session_id, trial, content_hash, start_ns, end_ns, n_samples (no file paths)."""
        return self.sql("""
            SELECT s.study, s.participant_id, r.session_id, r.trial, r.content_hash, r.start_ns, r.end_ns,
                   r.n_samples
            FROM recordings r JOIN sessions s USING (session_id)
            WHERE r.status = 'ingested' AND (? IS NULL OR s.participant_id = ?) AND (? IS NULL OR s.study = ?)
            ORDER BY r.start_ns""", [participant, participant, study, study])

    def strides(self, participant: str | None = None, session: str | None = None,
                study: str | None = None) -> pd.DataFrame:
        """Strides from the foot IMUs (gait stage): side, ic_ns/tc_ns, stride_time_s, stance_pct, swing_pct,
        stride_length_m, speed_m_s, clearance_m, turning_deg (+ to the left), stride_length_ref_m (optical,
        where recorded). Borders are mid-stance to mid-stance (``docs/gait.md``)."""
        return self._filtered("strides", participant=participant, study=study, session=session,
                              order="s.start_ns, t.session_id, t.start_ns", produced_by="the gait stage")

    def gait_events(self, participant: str | None = None, session: str | None = None,
                    study: str | None = None) -> pd.DataFrame:
        """Initial (IC) and terminal (TC) contacts per foot: side, type, t_ns."""
        return self._filtered("gait_events", participant=participant, study=study, session=session,
                              order="s.start_ns, t.session_id, t.t_ns", produced_by="the gait stage")

    def clinical_measures(self, participant: str | None = None, study: str | None = None) -> pd.DataFrame:
        """Clinical gait measures per lab session and visit (``docs/clinical_measures.md``): measure, unit, value,
        sem, mdc95, left/right values, paretic and symmetry ratios."""
        from stridelab.warehouse.queries import clinical_visits
        out = clinical_visits(self.con, study, participant)
        if out is None:
            raise TableMissing(f"no clinical_measures table in {self.root}: written by the clinical stage")
        return out

    def walking_bouts(self, participant: str | None = None, session: str | None = None,
                      study: str | None = None) -> pd.DataFrame:
        """Walking bouts at home from one trunk sensor (lower back or chest; ``docs/walking_at_home.md``).

        Raises:
            TableMissing: the warehouse has no ``walking_bouts`` table (written by the walking-at-home stage;
                a warehouse made by an older StrideLab gains it with its next ``stridelab run``).
        """
        return self._filtered("walking_bouts", participant=participant, study=study, session=session,
                              order="s.start_ns, t.session_id, 3", produced_by="the walking-at-home stage")

    def daily_gait_outcomes(self, participant: str | None = None, study: str | None = None) -> pd.DataFrame:
        """Per participant and day: walking outcomes of the walking-at-home stage (raises TableMissing without it)."""
        return self._filtered("daily_gait_outcomes", participant=participant, study=study,
                              produced_by="the walking-at-home stage")

    def activity_bouts(self, participant: str | None = None, session: str | None = None,
                       study: str | None = None) -> pd.DataFrame:
        """Runs of one posture or activity class from the chest sensor: start_ns, end_ns, class (lying,
        sitting, standing, level_walking, stairs_up, stairs_down, non_wear), steps."""
        return self._filtered("activity_bouts", participant=participant, study=study, session=session,
                              order="s.start_ns, t.start_ns", produced_by="the activity stage")

    def daily_activity(self, participant: str | None = None, study: str | None = None) -> pd.DataFrame:
        """One row per local calendar day and class (activity stage): date, recorded_s, wear_s, class, seconds,
        steps, n_transitions, n_bouts, bout_s_median, bout_s_max."""
        return self._filtered("activity_daily", participant=participant, study=study,
                              order="s.participant_id, t.date, t.class", produced_by="the activity stage")

    def accuracy(self, stage: str | None = None, participant: str | None = None,
                 study: str | None = None) -> pd.DataFrame:
        """Accuracy of each stage against the reference recorded with the data (optical poses, reference
        contacts, activity labels): stage, estimator, placement, metric, value, unit; one row per session."""
        extra = "AND (? IS NULL OR t.stage = ?)"
        if not self.has_table("accuracy_metrics"):
            raise TableMissing(f"no accuracy_metrics table in {self.root}")
        return self.sql(f"""
            SELECT s.study, s.participant_id, t.* FROM accuracy_metrics t JOIN sessions s USING (session_id)
            WHERE (? IS NULL OR s.participant_id = ?) AND (? IS NULL OR s.study = ?) {extra}
            ORDER BY t.stage, t.metric, s.start_ns""", [participant, participant, study, study, stage, stage])

    # ---- series ------------------------------------------------------------------------------
    def imu(self, session: str, placement: str, trial: str | None = None):
        """Stored samples of one IMU (`stridelab.warehouse.read.ImuSeries`: t_ns, acc m/s², gyr rad/s, mag µT or
        None, sampling_rate_hz) of a session's recording (its ``trial``, or the first one)."""
        from stridelab.warehouse.read import read_imu
        rows = self.con.execute("""
            SELECT r.content_hash FROM recordings r JOIN sensors x USING (content_hash)
            WHERE r.session_id = ? AND r.status = 'ingested' AND x.placement = ? AND x.kind = 'imu'
              AND (? IS NULL OR r.trial = ?) ORDER BY r.start_ns""", [session, placement, trial, trial]).fetchall()
        if not rows:
            raise LookupError(f"no '{placement}' IMU in session {session}"
                              + (f", trial {trial}" if trial else "") + "; see Warehouse.recordings()")
        return read_imu(self.con, self.root, rows[0][0], placement)

    def orientation(self, session: str, placement: str, trial: str | None = None):
        """(t_ns (N,), quat (N, 4) [w, x, y, z] sensor → ENU) of the orientation stage, for one IMU."""
        from stridelab.warehouse.read import read_orientation
        rows = self.con.execute("""
            SELECT r.content_hash FROM recordings r JOIN orientation o USING (content_hash)
            WHERE r.session_id = ? AND o.placement = ? AND (? IS NULL OR r.trial = ?)
            ORDER BY r.start_ns""", [session, placement, trial, trial]).fetchall()
        if not rows:
            raise LookupError(f"no orientation of '{placement}' in session {session}")
        return read_orientation(self.con, self.root, rows[0][0], placement)


def read_recording(path: str | Path) -> Recording:
    """Read one recording-format MCAP file into arrays with units, through the same reader as ingest
    (every CRC checked; a corrupt file raises ``ValueError`` with a one-line reason).

    Returns:
        `stridelab.estimators.recording.Recording`: ``metadata`` (the ``session`` record), ``imu[placement]``
        (``t_ns`` int64 ns, ``acc`` (N, 3) m/s², ``gyr`` (N, 3) rad/s, ``mag`` (N, 3) µT or None),
        ``reference_poses[placement]`` (``pos`` m, ``quat`` [w, x, y, z] segment → ENU), ``ranges`` (m) and
        ``events`` (dicts with ``t_ns``, ``type``, ``side``/``label``...). ``mag`` is on the IMU's stamps
        (interpolated when the magnetometer was sampled on its own clock).
    """
    import numpy as np

    from stridelab.estimators.recording import ImuData, PoseData, RangeData, Recording
    from stridelab.pipeline.formats.mcap_read import ReadResult, iter_blocks, read_metadata

    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{p}: no such file (an MCAP recording; a rosbag2 folder: use its .mcap file)")
    res = ReadResult()
    series: dict[tuple[str, str], list] = {}
    events: list[dict[str, Any]] = []
    for b in iter_blocks(p, res):
        if b.kind == "events":
            events += [dict(e) for e in b.values]
            continue
        series.setdefault((b.kind, b.topic), []).append(b)

    def cat(kind, topic):
        bl = series[(kind, topic)]
        t = np.concatenate([x.t_ns for x in bl])
        v = np.concatenate([np.asarray(x.values) for x in bl])
        order = np.argsort(t, kind="stable")
        return t[order], v[order]

    meta = (read_metadata(p) or res.metadata).get("session", {})
    rec = Recording(metadata=dict(meta), name=p.stem)
    mags = {}
    for kind, topic in series:
        prefix = _PREFIX.get(kind, "/")
        placement = topic[len(prefix):] if topic.startswith(prefix) else topic.strip("/")
        t, v = cat(kind, topic)
        if kind == "imu":
            rec.imu[placement] = ImuData(t_ns=t, acc=v[:, 3:6].copy(), gyr=v[:, 0:3].copy())
        elif kind == "mag":
            mags[placement] = (t, v[:, 0:3] * 1e6)                       # tesla on the wire -> µT
        elif kind == "reference_pose":
            rec.reference_poses[placement] = PoseData(t_ns=t, pos=v[:, 0:3].copy(), quat=v[:, 3:7].copy())
        elif kind == "range":
            rec.ranges[placement] = RangeData(t_ns=t, range_m=v[:, 3].copy(), min_range_m=float(v[0, 1]),
                                              max_range_m=float(v[0, 2]))
    for placement, (t, m) in mags.items():
        imu = rec.imu.get(placement)
        if imu is None:
            continue
        if len(t) == len(imu.t_ns) and np.array_equal(t, imu.t_ns):
            imu.mag = m
        elif len(t) >= 2:                                                 # onto the IMU stamps
            imu.mag = np.column_stack([np.interp(imu.t_ns, t, m[:, k]) for k in range(3)])
    rec.events = sorted(events, key=lambda e: int(e.get("t_ns", 0)))
    return rec
