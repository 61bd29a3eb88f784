"""Pipeline stages: thin adapters (warehouse -> estimators -> warehouse), registered in DAG order.

A stage declares what it needs, which catalog tables it owns (rows keyed by ``session_id``) and a
``compute`` function that runs in a worker process on one session: it reads series files, calls
estimators, writes immutable Parquet files and returns catalog rows. The runner commits those rows
in one transaction with the stage stamp (stage name + version + parameters + input hashes) and
reruns a stage only when the stamp changes (STYLE.md §4).

A stage runs on a session only when something consumes its output there: ``session_kinds`` are the
kinds it can run on; on the kinds in ``opt_in_kinds`` (outputs no stage, page or report reads by
default, e.g. the chest orientation of a free-living day) it runs only when a stage that runs there
needs it or the study asks for it in its manifest (``[compute.<stage>] <kind> = true``).
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np


@dataclass(frozen=True)
class SessionInput:
    """Everything a stage's compute function may read for one session (plain data, picklable).

    ``recordings``: list of dicts (content_hash, trial, start_ns, end_ns, sensors: {placement: {kind:
    {"series_path", "sampling_rate_hz", "n_samples"}}}). ``upstream``: table name -> rows of this
    session in the tables of the stages it needs. ``events``: reference annotations of the session.
    """
    root: str
    session: dict
    recordings: list[dict]
    upstream: dict[str, list[dict]] = field(default_factory=dict)
    events: list[dict] = field(default_factory=list)


#: stage_runs.status of a stage that ran: ``ok``, or ``skipped`` when the session does not hold what the stage needs
#: (feet only, chest only, a hand-held sensor, no gyroscope...; ``note`` says what is missing). Both are final:
#: the runner reruns neither until an input, the parameters or the code change. ``failed`` = it raised.
RUN_STATUSES = ("ok", "skipped", "failed")


@dataclass
class StageOutput:
    rows: dict[str, list[dict]] = field(default_factory=dict)
    note: str = ""
    status: str = "ok"          # "ok" | "skipped" (RUN_STATUSES)

    @classmethod
    def skipped(cls, note: str) -> "StageOutput":
        """Nothing to compute on this session: no rows, status ``skipped``, ``note`` = why."""
        return cls(note=note, status="skipped")


@dataclass(frozen=True)
class Stage:
    name: str
    version: str
    needs: tuple[str, ...]
    tables: tuple[str, ...]
    session_kinds: tuple[str, ...]
    compute: Callable[[SessionInput, dict], StageOutput]
    default_params: Callable[[], dict]
    opt_in_kinds: tuple[str, ...] = ()
    #: (catalog connection, session id) -> whether the session holds what the stage is about (None: every
    #: session of its kinds). A stage about a rare kind of recording (a live session's) runs only where one is.
    applies: Callable | None = None
    #: catalog tables written by the ingest (not by a stage) whose rows of the session the stage reads (upstream)
    reads: tuple[str, ...] = ()
    #: the frozen parameter class of a stage in the shape of :mod:`stridelab.pipeline.stages._shape` (None for a bare Stage)
    params_cls: type | None = None


def canonical_json(obj) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)


def params_hash(params: dict) -> str:
    return hashlib.sha256(canonical_json(params).encode()).hexdigest()


def stamp(stage: Stage, params: dict, input_hash: str) -> str:
    return hashlib.sha256(canonical_json({"stage": stage.name, "version": stage.version,
                                          "params": params_hash(params), "input": input_hash}).encode()).hexdigest()


def scored_mask(events: list[dict], rec: dict, placement: str, t_ns: np.ndarray) -> np.ndarray:
    """(N,) bool (``t_ns`` sorted): samples inside the reference's ``score`` spans for this placement and recording (BROAD's
    ``movement`` mask, DESIGN "Recording format" annotations); all True when the reference marks none."""
    spans = [(int(e["t_ns"]), int(e["end_ns"])) for e in events
             if e.get("type") == "score" and e.get("end_ns") is not None and e.get("placement") in (None, placement)
             and rec["start_ns"] <= e["t_ns"] <= rec["end_ns"]]
    if not spans:
        return np.ones(len(t_ns), bool)
    m = np.zeros(len(t_ns), bool)
    for a, b in spans:
        m[np.searchsorted(t_ns, a):np.searchsorted(t_ns, b, side="right")] = True
    return m


def registry() -> list[Stage]:
    """All stages in topological order."""
    from stridelab.pipeline.stages import (activity, calibration, clinical, gait, joint_angles, live_agreement, orientation,
                                 trunk_gait)
    stages = [orientation.STAGE, gait.STAGE, clinical.STAGE, calibration.STAGE, joint_angles.STAGE, activity.STAGE,
              trunk_gait.STAGE, live_agreement.STAGE]
    names = set()
    for s in stages:
        missing = [n for n in s.needs if n not in names]
        if missing:
            raise RuntimeError(f"stage {s.name} needs {missing}, registered later or not at all")
        names.add(s.name)
    return stages


def resolve_root(inp: SessionInput) -> Path:
    return Path(inp.root)
