"""One shape for a stage (issue #45): typed frozen parameters, a context that hands the stage the inputs it
declares and takes the outputs it declares, the reference scoring as a separate step.

A stage in this shape is one small module::

    @dataclass(frozen=True)
    class MyParams:                       # units in the field names or the docstring
        min_bout_s: float = 10.0

    def compute(ctx: StageContext, p: MyParams) -> None:      # calls estimators, shapes table rows
        for rec, imu in ctx.imus():
            ...
            ctx.emit("my_table", rows)

    def score(ctx: StageContext, p: MyParams) -> None:        # optional: against the session's references,
        ...                                                   # with the one scorer of the quantity

    STAGE = shaped_stage("my_stage", "1", MyParams, compute, score=score, placements=("lower_back",),
                         tables=("my_table", "accuracy_metrics"), session_kinds=("lab",))

:func:`shaped_stage` adapts it onto the runner's :class:`pipeline.stages.Stage` (``compute(SessionInput, dict)
-> StageOutput``; parameters as a JSON dict so the stamp and the ledger are unchanged): the dict is turned into
the frozen parameter class (nested dataclasses included), a session without the declared placements is
``skipped`` with a note naming what it has, and a row for a table the stage did not declare is refused.
"""
from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from typing import Callable, Iterator

import numpy as np

from pipeline.stages import SessionInput, Stage, StageOutput

__all__ = ["ImuInput", "StageContext", "params_from_dict", "params_to_dict", "shaped_stage"]


def params_to_dict(p) -> dict:
    """Frozen parameter dataclass → JSON-able dict (tuples become lists; the runner hashes it)."""
    return json.loads(json.dumps(dataclasses.asdict(p), default=list))


def params_from_dict(cls, d: dict | None):
    """dict (as stored in the ledger / the study manifest) → ``cls``; nested dataclass fields rebuilt (their class
    is the class of the field's default, so a stage module need not import an estimator package to declare its
    parameters), lists to tuples, unknown keys refused with the field names the class has."""
    d = dict(d or {})
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(d) - set(fields))
    if unknown:
        raise ValueError(f"{cls.__name__}: unknown parameter(s) {', '.join(unknown)}; known: {', '.join(sorted(fields))}")
    out = {}
    for k, v in d.items():
        f = fields[k]
        proto = f.default if f.default is not dataclasses.MISSING else (
            f.default_factory() if f.default_factory is not dataclasses.MISSING else None)
        if dataclasses.is_dataclass(proto) and isinstance(v, dict):
            v = params_from_dict(type(proto), v)
        elif isinstance(v, list):
            v = tuple(v)
        out[k] = v
    return cls(**out)


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
    placements' samples), :meth:`events` (reference annotations with their payload fields), ``upstream`` (rows of the
    stages it needs). Outputs: :meth:`emit` (rows of a declared table), :meth:`note`, :attr:`outputs`."""
    inp: SessionInput
    tables: tuple[str, ...]
    placements: tuple[str, ...]
    rows: dict[str, list[dict]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    #: what ``compute`` found, handed to the ``score`` step (estimator results, never table rows)
    found: list = field(default_factory=list)

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

    def imus(self, read: bool = True) -> Iterator[ImuInput]:
        """Per recording the first declared placement it carries (in declaration order), samples read whole, or
        (``read=False``) only its description: read rows with :meth:`read_imu` (a week need not be held at once)."""
        from warehouse.read import series_rows
        for rec in self.recordings:
            for pl in self.placements:
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
        from warehouse.read import read_column_range
        root, path = self.inp.root, imu.series_path
        t = read_column_range(root, path, ("t_ns",), start, stop, dtype=np.int64)
        acc = read_column_range(root, path, ("acc_x", "acc_y", "acc_z"), start, stop)
        try:
            gyr = read_column_range(root, path, ("gyr_x", "gyr_y", "gyr_z"), start, stop)
        except (KeyError, ValueError):                # no gyroscope columns in the series
            gyr = None
        gyr = gyr if gyr is not None and len(gyr) and np.isfinite(gyr).any() else None
        return dataclasses.replace(imu, t_ns=t, acc=acc, gyr=gyr, n_samples=len(t))

    def read_times(self, imu: ImuInput) -> np.ndarray:
        from warehouse.read import read_column_range
        return read_column_range(self.inp.root, imu.series_path, ("t_ns",), dtype=np.int64)

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

    def output(self) -> StageOutput:
        return StageOutput(rows={t: self.rows.get(t, []) for t in self.tables}, note="; ".join(self.notes)[:500])


def shaped_stage(name: str, version: str, params_cls, compute: Callable[[StageContext, object], None], *,
                 placements: tuple[str, ...], tables: tuple[str, ...], session_kinds: tuple[str, ...],
                 score: Callable[[StageContext, object], None] | None = None, needs: tuple[str, ...] = (),
                 opt_in_kinds: tuple[str, ...] = ()) -> Stage:
    """The runner's :class:`Stage` for a stage written in this shape (see the module docstring)."""

    def run(inp: SessionInput, params: dict) -> StageOutput:
        p = params_from_dict(params_cls, params)
        ctx = StageContext(inp, tuple(tables), tuple(placements))
        if not ctx.has_input():
            have = sorted({pl for r in inp.recordings for pl in r["sensors"]})
            return StageOutput.skipped(f"{name} skipped: no {'/'.join(placements)} IMU (session has "
                                       f"{', '.join(have) or 'no IMU'})")
        compute(ctx, p)
        if score is not None:
            score(ctx, p)
        return ctx.output()

    return Stage(name=name, version=version, needs=tuple(needs), tables=tuple(tables),
                 session_kinds=tuple(session_kinds), compute=run,
                 default_params=lambda: params_to_dict(params_cls()), opt_in_kinds=tuple(opt_in_kinds))
