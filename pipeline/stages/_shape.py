"""One shape for a stage (issue #45): typed frozen parameters, a context that hands the stage the inputs it
declares and takes the outputs it declares, the reference scoring as a separate step.

A stage in this shape is one small module::

    @dataclass(frozen=True)
    class MyParams:                       # units in the field names or the docstring
        min_bout_s: float = 10.0

    def compute(ctx: StageContext, p: MyParams) -> None:      # calls estimators, shapes table rows
        for imu in ctx.imus():
            ...
            ctx.emit("my_table", rows)
            ctx.found.append(...)                             # what the score step needs

    def score(ctx: StageContext, p: MyParams) -> None:        # optional: against the session's references,
        ...                                                   # with the one scorer of the quantity

    STAGE = shaped_stage("my_stage", "1", MyParams, compute, score=score, placements=("lower_back",),
                         tables=("my_table", "accuracy_metrics"), session_kinds=("lab",))

:func:`shaped_stage` adapts it onto the runner's :class:`stridelab.pipeline.stages.Stage` (``compute(SessionInput, dict)
-> StageOutput``; parameters as a JSON dict so the stamp and the ledger are unchanged): the dict is turned into
the frozen parameter class (nested dataclasses included; an unknown key refused naming its place), a session
without the declared placements is ``skipped`` with a note naming what it has (a stage without declared
placements decides itself: ``ctx.skip(why)``), and a row for a table the stage did not declare is refused. Every
stage of :func:`stridelab.pipeline.stages.registry` is written this way (docs/architecture.md).
"""
from __future__ import annotations

import dataclasses
import json
from typing import Callable

from stridelab.pipeline.stages import SessionInput, Stage, StageOutput
from stridelab.pipeline.stages._context import ImuInput, StageContext

__all__ = ["ImuInput", "StageContext", "params_from_dict", "params_to_dict", "shaped_stage"]


def params_to_dict(p) -> dict:
    """Frozen parameter dataclass → JSON-able dict (tuples become lists; the runner hashes it)."""
    return json.loads(json.dumps(dataclasses.asdict(p), default=list))


def params_from_dict(cls, d: dict | None, where: str = "", base=None):
    """dict (as stored in the ledger / the study manifest) → ``cls``; nested dataclass fields rebuilt (their class
    is the class of the field's default, so a stage module need not import an estimator package to declare its
    parameters), lists to tuples, unknown keys refused naming where they are and the field names the class has.
    A nested table keeps the keys it does not give at the enclosing default's value (``base``), not at its class's
    defaults: ``foot.trajectory_zupt = {window_s = 0.03}`` keeps ``TRAJECTORY_ZUPT``'s minimum stance, and
    ``foot.trajectory.zupt`` the gait's ``GAIT_ZUPT``."""
    d = dict(d or {})
    where = where or cls.__name__
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(d) - set(fields))
    if unknown:
        raise ValueError(f"{where}: unknown parameter(s) {', '.join(unknown)}; known: {', '.join(sorted(fields))} "
                         f"(check the study manifest's [stages.<stage>] table)")
    out = {}
    for k, v in d.items():
        f = fields[k]
        proto = getattr(base, k) if base is not None else None
        if not dataclasses.is_dataclass(proto):
            proto = f.default if f.default is not dataclasses.MISSING else (
                f.default_factory() if f.default_factory is not dataclasses.MISSING else None)
        if dataclasses.is_dataclass(proto) and isinstance(v, dict):
            v = params_from_dict(type(proto), v, f"{where}.{k}", proto)
        elif isinstance(v, list):
            v = tuple(v)
        out[k] = v
    return dataclasses.replace(base, **out) if base is not None else cls(**out)


def shaped_stage(name: str, version: str, params_cls, compute: Callable[[StageContext, object], None], *,
                 tables: tuple[str, ...], session_kinds: tuple[str, ...], placements: tuple[str, ...] = (),
                 score: Callable[[StageContext, object], None] | None = None,
                 finish: Callable[[StageContext, object], None] | None = None, needs: tuple[str, ...] = (),
                 opt_in_kinds: tuple[str, ...] = (), applies: Callable | None = None,
                 reads: tuple[str, ...] = ()) -> Stage:
    """The runner's :class:`Stage` for a stage written in this shape (see the module docstring). With
    ``placements`` a session none of whose recordings has an IMU there is skipped before ``compute``; without,
    the stage decides (:meth:`StageContext.skip`). ``score`` runs after ``compute`` unless that skipped, then
    ``finish`` (rows of the whole session that carry the notes of both steps, e.g. the gait summary).
    ``applies`` / ``reads``: as :class:`stridelab.pipeline.stages.Stage` (sessions the stage is about; ingest tables it reads)."""

    def run(inp: SessionInput, params: dict) -> StageOutput:
        p = params_from_dict(params_cls, params)
        ctx = StageContext(inp, tuple(tables), tuple(placements), raw_params=dict(params or {}))
        if placements and not ctx.has_input():
            have = sorted({pl for r in inp.recordings for pl in r["sensors"]})
            return StageOutput.skipped(f"{name} skipped: no {'/'.join(placements)} IMU (session has "
                                       f"{', '.join(have) or 'no IMU'})")
        compute(ctx, p)
        if score is not None and ctx.skipped is None:
            score(ctx, p)
        if finish is not None and ctx.skipped is None:
            finish(ctx, p)
        return ctx.output()

    return Stage(name=name, version=version, needs=tuple(needs), tables=tuple(tables),
                 session_kinds=tuple(session_kinds), compute=run,
                 default_params=lambda: params_to_dict(params_cls()), opt_in_kinds=tuple(opt_in_kinds),
                 applies=applies, reads=tuple(reads), params_cls=params_cls)
