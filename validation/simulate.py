"""``stridelab simulate``: the simulator of ``studies/`` writes its recordings as MCAP files.

Participants are independent (each draws from its own seed sequence), so ``jobs > 1`` simulates them in
parallel worker processes; the files are byte-identical to a serial run.
"""
from __future__ import annotations

import multiprocessing as mp
import os
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Callable

from stridelab.pipeline.formats.mcap_write import write_recording


def _load(manifest, hours, visits=None):
    from dataclasses import replace
    from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
    m = load_manifest(manifest or DEFAULT_MANIFEST)
    m = replace(m, visits=int(visits)) if visits is not None else m
    return m.with_free_living_hours(hours) if hours is not None else m


def _participant_files(manifest, participant, index: int, seed: int, directory: Path) -> list[Path]:
    """Simulate and write one participant's recordings: per visit of the programme (``[study] visits``) the lab
    trials, then the free-living day after it."""
    from stridelab.validation.simulator import simulate_chest_day, simulate_lab_session
    out = []
    for visit in range(1, manifest.visits + 1):
        for rec, _truth in simulate_lab_session(manifest, participant, index, seed=seed, session=visit):
            out.append(write_recording(rec, directory / f"{rec.name}.mcap"))
        rec, _ = simulate_chest_day(manifest, participant, index, seed=seed, session=visit)
        out.append(write_recording(rec, directory / f"{rec.name}.mcap"))
    return out


def _worker(manifest, hours, seed: int, participants, index: int, directory: Path, visits=None) -> list[Path]:
    """In a worker process: the manifest is reloaded (it is not picklable), participant ``index`` simulated."""
    from stridelab.validation.simulator import study_participants
    m = _load(manifest, hours, visits)
    return _participant_files(m, study_participants(m, participants, seed)[index], index, seed, directory)


def simulate_to_dir(directory: Path, *, manifest=None, seed: int | None = None, participants: int | None = None,
                    hours: float | None = None, jobs: int = 1, visits: int | None = None, nice: int = 0,
                    on_file: Callable[[Path], None] = lambda p: None) -> list[Path]:
    """Simulate a study (default: the demo manifest) into ``directory``; returns the files written, in
    participant order. ``jobs`` worker processes simulate participants in parallel (same bytes as serial).
    ``visits`` overrides the manifest's number of lab visits per participant (``[study] visits``).
    ``nice``: the workers' niceness increment (``stridelab demo`` lets its concurrent kernel warm-up go first:
    the pipeline waits for both, and the warm-up is the one process that cannot be split)."""
    from stridelab.validation.simulator import study_participants
    m = _load(manifest, hours, visits)
    seed = m.seed if seed is None else int(seed)
    people = study_participants(m, participants, seed)
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    out: list[Path] = []
    if jobs <= 1 or len(people) == 1:
        for i, p in enumerate(people):
            for f in _participant_files(m, p, i, seed, directory):
                on_file(f)
                out.append(f)
        return out
    with ProcessPoolExecutor(min(jobs, len(people)), mp_context=mp.get_context("spawn"),
                             initializer=os.nice if nice else None, initargs=(nice,) if nice else ()) as pool:
        futs = [pool.submit(_worker, manifest, hours, seed, participants, i, directory, visits)
                for i in range(len(people))]
        for fut in futs:                       # in participant order; workers run ahead
            for f in fut.result():
                on_file(f)
                out.append(f)
    return out
