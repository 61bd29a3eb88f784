"""Seeded, deterministic synthetic gait study (DESIGN.md "studies/", platform issue item 3).

Public API
----------
``simulate_study(manifest, *, seed=None, participants=None)``
    Iterator of ``stridelab.validation.simulator.Recording`` (field for field the recording layout the format writers read), one at a time (never more than one 24 h day in
    memory): per participant and visit of the programme (``[study] visits``) the lab session (calibration
    trial, then the walking trials), then the free-living chest day after it.
``simulate_lab_session(manifest, participant, index, *, seed=None, sensor_model=None)``
    Iterator of ``(Recording, LabTrialTruth)`` for one lab session (truth: segment poses, mounting
    rotations, joint angles, gait events, foot points, error-free signals; see ``LabTrialTruth``).
``simulate_chest_day(manifest, participant, index, *, seed=None, sensor_model=None, keep_true=False)``
    ``(Recording, ChestDayTruth)`` for one free-living day.
``study_participants(manifest, n=None, seed=None)``
    The participant list, extended deterministically when ``n`` exceeds the manifest's list.

Conventions: ENU world (z up, walking starts heading north = +y), quaternions [w x y z] sensor (or
segment) -> ENU, ISB segment frames (x anterior, y up, z right), nominal sensor axes = segment axes
(no mounting permutation needed) rotated by the true mounting misalignment. Time int64 UTC ns.

Dates: participant i (0-based) has the lab session on ``first_lab_date + i`` days starting at
``lab_start_local`` (calibration, then each walking trial 60 s after the previous one ends); the
free-living recording starts at ``free_living.start_local`` (default 00:00) local time on the next
day and lasts ``free_living.hours`` (default 24 h: one whole calendar day). A programme (``[study] visits``
> 1) repeats lab session and free-living day every ``visit_interval_days``, visit k simulating
``ParticipantSpec.at_visit(k)`` (the ``follow_up_*`` values at the last visit).

Recording names: ``P001_lab1_calibration``, ``P001_lab1_walk-1``, ``P001_free1_day-1`` (visit 2: ``lab2``, ``free2``).
"""
from __future__ import annotations

from dataclasses import replace
from typing import Iterator

import numpy as np

from ._records import Recording
from stridelab.studies.manifest import ParticipantSpec, StudyManifest, load_manifest

from ._chest_day import ChestDayTruth, simulate_chest_day
from ._lab import LabTrialTruth, simulate_lab_session
from .violations import SCENARIOS, Violations

__all__ = ["simulate_study", "simulate_lab_session", "simulate_chest_day", "study_participants",
           "LabTrialTruth", "ChestDayTruth"]


def study_participants(manifest: StudyManifest, n: int | None = None, seed: int | None = None) -> list[ParticipantSpec]:
    """First ``n`` participants; beyond the manifest's list, new ones (P005, P006, ...) cycle through the
    manifest's templates with anthropometry and gait varied deterministically from the seed."""
    base = list(manifest.participants)
    if n is None:
        return base
    if n < 1:
        raise ValueError(f"participants must be >= 1, got {n}")
    if n <= len(base):
        return base[:n]
    seed = manifest.seed if seed is None else int(seed)
    out = list(base)
    width = max(3, len(str(n)))
    used = {p.id for p in base}
    k = len(base)
    while len(out) < n:
        k += 1
        tpl = base[(k - 1) % len(base)]
        rng = np.random.default_rng(np.random.SeedSequence([seed, 7, k]))
        f = float(np.clip(rng.normal(1.0, 0.05), 0.88, 1.12))
        pid = f"P{k:0{width}d}"
        while pid in used:
            k += 1
            pid = f"P{k:0{width}d}"
        used.add(pid)
        sev = float(np.clip(tpl.severity + rng.normal(0, 0.1), 0.3, 1.0)) if tpl.hemiparetic else 0.0
        out.append(replace(tpl, id=pid, height_m=float(np.clip(tpl.height_m * f, 1.45, 2.05)),
                           thigh_m=tpl.thigh_m * f, shank_m=tpl.shank_m * f,
                           speed_m_s=float(np.clip(tpl.speed_m_s * rng.normal(1.0, 0.07), 0.4, 1.6)),
                           cadence_steps_min=float(np.clip(tpl.cadence_steps_min * rng.normal(1.0, 0.04), 70, 125)),
                           severity=sev, paretic_side=(tpl.paretic_side if not tpl.hemiparetic or rng.random() < 0.5
                                                       else {"left": "right", "right": "left"}[tpl.paretic_side])))
    return out


def simulate_study(manifest: StudyManifest | str | None = None, *, seed: int | None = None,
                   participants: int | None = None) -> Iterator[Recording]:
    """Yield every recording of the study, one at a time (lab trials, then the free-living day, per
    participant). ``seed`` overrides the manifest seed; ``participants`` the participant count."""
    if not isinstance(manifest, StudyManifest):
        manifest = load_manifest(manifest)
    seed = manifest.seed if seed is None else int(seed)
    for i, p in enumerate(study_participants(manifest, participants, seed)):
        for visit in range(1, manifest.visits + 1):
            for rec, _truth in simulate_lab_session(manifest, p, i, seed=seed, session=visit):
                yield rec
            rec, _ = simulate_chest_day(manifest, p, i, seed=seed, session=visit)
            yield rec
            del rec
