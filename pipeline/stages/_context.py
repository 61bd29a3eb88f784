"""What a stage in the shape of :mod:`stridelab.pipeline.stages._shape` sees and produces on one session: the inputs it
declares (recordings, IMU samples of its placements, reference annotations, upstream rows, the warehouse series it
reads) and the outputs it declares (rows of its tables, series files, notes). A stage's warehouse reading and
writing goes through here, so the stage module itself only calls estimators and shapes rows."""
from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from typing import Iterator

import numpy as np

from stridelab.pipeline.stages import SessionInput, StageOutput, canonical_json, params_hash

__all__ = ["ImuInput", "StageContext"]


@dataclass(frozen=True)
class ImuInput:
    """One IMU of one recording as the context hands it out: ``t_ns`` (N,) int64, ``acc`` (N, 3) m/s², ``gyr``
    (N, 3) rad/s or None, ``fs_hz``; ``placement``; ``recording`` the runner's recording dict (content_hash, trial,
    start_ns, end_ns, metadata)."""
    placement: str
    recording: dict
    t_ns: np.ndarray
    acc: np.ndarray
    gyr: np.ndarray | None
    fs_hz: float
    series_path: str = ""
    n_samples: int = 0


@dataclass
class StageContext:
    """What one run of a shaped stage on one session sees and produces.

    Inputs: ``session`` (the catalog row), ``recordings`` (the runner's dicts), :meth:`imus` (the declared
    placements' samples), :meth:`read_imu_files` / :meth:`read_table` / :meth:`reference_orientation` (any series
    of the session), :meth:`events` (reference annotations with their payload fields), ``upstream`` (rows of the
    stages it needs). Outputs: :meth:`emit` (rows of a declared table), :meth:`write_series` (a Parquet series
    keyed by the recording and :attr:`params_key`), :meth:`note` / :meth:`set_note`, :meth:`skip`."""
    inp: SessionInput
    tables: tuple[str, ...]
    placements: tuple[str, ...]
    #: the parameters as the runner stamped them (JSON dict): series keys and stored ``params`` columns use these
    raw_params: dict = field(default_factory=dict)
    rows: dict[str, list[dict]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    #: what ``compute`` found, handed to the ``score`` / ``finish`` steps: estimator results, and the emitted rows a
    #: score step fills a reference column of (``strides.stride_length_ref_m``, ``clinical_steps.step_length_ref_m``)
    found: list = field(default_factory=list)
    final_note: str | None = None
    skipped: str | None = None

    @property
    def params_key(self) -> str:
        """sha256 of the stamped parameters (a prefix names the series files a stage writes)."""
        return params_hash(self.raw_params)

    @property
    def params_json(self) -> str:
        return canonical_json(self.raw_params)

    @property
    def session(self) -> dict:
        return self.inp.session

    @property
    def session_id(self) -> str:
        return self.inp.session["session_id"]

    @property
    def recordings(self) -> list[dict]:
        return self.inp.recordings

    @property
    def upstream(self) -> dict[str, list[dict]]:
        return self.inp.upstream

    def has_input(self) -> bool:
        return any(pl in r["sensors"] and "imu" in r["sensors"][pl] for r in self.recordings for pl in self.placements)

    def imus(self, read: bool = True, placements: tuple[str, ...] | None = None,
             recordings: list[dict] | None = None) -> Iterator[ImuInput]:
        """Per recording the first declared placement it carries (in declaration order; ``placements`` overrides
        the declaration, ``recordings`` the session's), samples read whole, or (``read=False``) only its
        description: read rows with :meth:`read_imu` (a week need not be held at once)."""
        from stridelab.warehouse.read import series_rows
        for rec in self.recordings if recordings is None else recordings:
            for pl in self.placements if placements is None else placements:
                imu = rec["sensors"].get(pl, {}).get("imu")
                if imu is None:
                    continue
                fs, path = float(imu["sampling_rate_hz"]), imu["series_path"]
                n = int(imu.get("n_samples") or series_rows(self.inp.root, path))
                empty = ImuInput(pl, rec, np.zeros(0, np.int64), np.zeros((0, 3)), None, fs, path, n)
                yield self.read_imu(empty) if read else empty
                break

    def read_imu(self, imu: ImuInput, start: int = 0, stop: int | None = None) -> ImuInput:
        """Rows [start, stop) of ``imu`` (t_ns, acc, gyr; gyr None for an accelerometer-only sensor)."""
        from stridelab.warehouse.read import read_column_range
        root, path = self.inp.root, imu.series_path
        t = read_column_range(root, path, ("t_ns",), start, stop, dtype=np.int64)
        acc = read_column_range(root, path, ("acc_x", "acc_y", "acc_z"), start, stop)
        try:
            gyr = read_column_range(root, path, ("gyr_x", "gyr_y", "gyr_z"), start, stop)
        except (KeyError, ValueError):                # no gyroscope columns in the series
            gyr = None
        gyr = gyr if gyr is not None and len(gyr) and np.isfinite(gyr).any() else None
        return dataclasses.replace(imu, t_ns=t, acc=acc, gyr=gyr, n_samples=len(t))

    def read_imu_files(self, rec: dict, placement: str, with_mag: bool = False):
        """:class:`stridelab.warehouse.read.ImuSeries` of ``placement`` in ``rec`` (magnetometer on the IMU stamps when asked
        for and recorded), or None when it has no IMU."""
        from stridelab.warehouse.read import read_imu_files
        kinds = rec["sensors"].get(placement, {})
        imu = kinds.get("imu")
        if imu is None:
            return None
        mag = kinds.get("mag") if with_mag else None
        return read_imu_files(self.inp.root, imu["series_path"], mag["series_path"] if mag else None,
                              imu["sampling_rate_hz"])

    def read_table(self, path: str, columns: list[str] | None = None):
        """A series file of the warehouse (pyarrow table), checksums verified."""
        from stridelab.warehouse.store import read_table
        return read_table(self.inp.root, path, columns=columns)

    def reference_pose(self, rec: dict, placement: str, columns: tuple[str, ...]):
        """(t_ns (M,), values (M, k)) of the optical reference pose of ``placement`` in ``rec``, or None."""
        ref = rec["sensors"].get(placement, {}).get("reference_pose")
        if ref is None:
            return None
        t = self.read_table(ref["series_path"], ["t_ns", *columns])
        return t.column("t_ns").to_numpy(), np.column_stack([t.column(c).to_numpy() for c in columns])

    def reference_orientation(self, rec: dict, placement: str, t_ns: np.ndarray) -> np.ndarray | None:
        """Optical segment orientation of ``placement`` at the stamps ``t_ns`` (NaN where none), or None."""
        from stridelab.warehouse.read import reference_orientation_on
        ref = rec["sensors"].get(placement, {}).get("reference_pose")
        return None if ref is None else reference_orientation_on(self.inp.root, ref["series_path"], t_ns)

    def write_series(self, placement: str, name: str, table) -> str:
        """Write ``table`` (pyarrow) as the series ``name`` of ``placement`` in this session; its relative path."""
        from stridelab.warehouse.store import series_relpath, write_table
        s = self.session
        rel = series_relpath(s["study"], s["participant_id"], s["session_id"], placement, name)
        write_table(self.inp.root, rel, table)
        return rel

    def read_times(self, imu: ImuInput, start: int = 0, stop: int | None = None) -> np.ndarray:
        """int64 ns stamps of rows [start, stop) of ``imu``."""
        from stridelab.warehouse.read import read_column_range
        return read_column_range(self.inp.root, imu.series_path, ("t_ns",), start, stop, dtype=np.int64)

    def read_acc(self, imu: ImuInput, start: int = 0, stop: int | None = None) -> np.ndarray:
        """(n, 3) m/s² accelerometer rows [start, stop) of ``imu`` (the gyroscope not read)."""
        from stridelab.warehouse.read import read_column_range
        return read_column_range(self.inp.root, imu.series_path, ("acc_x", "acc_y", "acc_z"), start, stop)

    def events(self, type: str | None = None, label: str | None = None, rec: dict | None = None) -> list[dict]:
        """Reference annotations (payload fields merged in), filtered by type, label (e.g. the reference system)
        and the recording's time span."""
        out = []
        for e in self.inp.events:
            if type is not None and e.get("type") != type:
                continue
            if label is not None and e.get("label") != label:
                continue
            if rec is not None and not (rec["start_ns"] <= e["t_ns"] <= rec["end_ns"]):
                continue
            full = dict(e)
            if e.get("payload"):
                try:
                    full = {**json.loads(e["payload"]), **{k: v for k, v in e.items() if v is not None}}
                except ValueError:
                    pass
            full.pop("payload", None)
            out.append(full)
        return out

    def emit(self, table: str, rows: list[dict]) -> None:
        if table not in self.tables:
            raise RuntimeError(f"stage wrote table '{table}' it does not declare (declared: {', '.join(self.tables)})")
        self.rows.setdefault(table, []).extend(rows)

    def note(self, text: str) -> None:
        if text and text not in self.notes:
            self.notes.append(text)

    def set_note(self, text: str) -> None:
        """The run's note verbatim (instead of the :meth:`note` lines joined)."""
        self.final_note = text

    def skip(self, why: str) -> None:
        """Nothing to compute on this session (status ``skipped``, no rows); ``why`` names what is missing."""
        self.skipped = why

    def output(self) -> StageOutput:
        if self.skipped is not None:
            return StageOutput.skipped(self.skipped)
        note = self.final_note if self.final_note is not None else "; ".join(self.notes)[:500]
        return StageOutput(rows={t: self.rows.get(t, []) for t in self.tables}, note=note)
