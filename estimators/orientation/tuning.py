"""Gain selection with leave-trials-out cross-validation (spec thesis_orientation.md §7 C11, §8 A13).

Few gains, one value for all trials: a candidate grid is scored on every trial once (mean total RMSE,
A13), then for each fold the candidate with the lowest mean error on the *training* trials is scored on
the held-out trials. The cross-validated error is the honest figure; the shipped default is the
candidate chosen most often (ties: lowest error on all trials). ``tuned_gains.json`` in this folder
records the result and how it was obtained.

For more than one or two gains use the thesis' particle swarm (§4.8, §9.4 P3), vectorised over the swarm:
:mod:`stridelab.estimators.orientation.pso`, re-exported here (``tune_pso``, ``pso_leave_trials_out``, ``SwitchingSpace``,
``SwarmData``, ``pso_minimize``); with one gain a grid is exhaustive and cheaper.
"""
from __future__ import annotations

import dataclasses
from collections import Counter
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from stridelab.estimators.orientation.evaluation import orientation_rmse_deg
from stridelab.estimators.orientation.pso import (SwarmData, SwitchingSpace, pso_leave_trials_out, pso_minimize,
                                        swarm_errors, tune_pso)

__all__ = ["CVResult", "score_grid", "leave_trials_out", "leave_groups_out", "trial_groups", "BROAD_GROUPS", "SwarmData", "SwitchingSpace", "pso_leave_trials_out",
           "pso_minimize", "swarm_errors", "tune_pso"]


@dataclass(frozen=True)
class CVResult:
    """errors: (n_candidates, n_trials) total RMSE, degrees; chosen_per_fold: candidate index per fold;
    cv_error_deg: mean held-out error; default_index: the shipped candidate; heldout_per_trial: each trial's
    error with the candidate chosen without it."""
    candidates: tuple
    errors: np.ndarray
    folds: tuple[tuple[int, ...], ...]
    chosen_per_fold: tuple[int, ...]
    cv_error_deg: float
    default_index: int
    heldout_per_trial: np.ndarray | None = None


def score_grid(estimate: Callable, candidates: Sequence, trials: Sequence) -> np.ndarray:
    """(n_candidates, n_trials) mean-total-RMSE matrix. ``estimate(params, gyr, acc, mag, fs) -> quat``;
    trials need ``gyr, acc, mag, quat_ref, movement, sampling_rate_hz`` attributes."""
    err = np.empty((len(candidates), len(trials)))
    for i, p in enumerate(candidates):
        for j, t in enumerate(trials):
            q = estimate(p, t.gyr, t.acc, t.mag, t.sampling_rate_hz)
            err[i, j] = orientation_rmse_deg(q, t.quat_ref, t.movement).total_rmse_deg
    return err


def leave_trials_out(errors: np.ndarray, candidates: Sequence, n_folds: int = 3) -> CVResult:
    """Cross-validate the choice of candidate over trial folds (trial k goes to fold k mod n_folds)."""
    n = errors.shape[1]
    if n < n_folds:
        raise ValueError(f"need at least n_folds={n_folds} trials, got {n}")
    folds = tuple(tuple(range(k, n, n_folds)) for k in range(n_folds))
    return _cv(errors, candidates, folds)


#: the BROAD trial groups of ``trials.json`` used as cross-validation folds (issue 16): every public trial
#: belongs to exactly one of them
BROAD_GROUPS = ("rotation", "translation", "disturbed")


def trial_groups(trials: Sequence, groups: Sequence[str] = BROAD_GROUPS) -> tuple[str, ...]:
    """The fold label of every trial: the first of ``groups`` in its ``groups`` attribute. Raises ValueError
    for a trial in none of them (its fold would be undefined)."""
    out = []
    for t in trials:
        g = [x for x in groups if x in tuple(getattr(t, "groups", ()))]
        if not g:
            raise ValueError(f"trial {getattr(t, 'name', t)!r} is in none of the groups {', '.join(groups)}; "
                             "cannot assign a cross-validation fold (trials.json beside the data lists them)")
        out.append(g[0])
    return tuple(out)


def leave_groups_out(errors: np.ndarray, candidates: Sequence, labels: Sequence[str]) -> CVResult:
    """Cross-validate the choice of candidate with one fold per group (leave-one-group-out): for each group the
    candidate with the lowest mean error on the *other* groups' trials is scored on that group's trials.
    ``cv_error_deg`` is the mean over all trials of their held-out errors; the shipped default is the candidate
    chosen most often (ties: lowest mean error over all trials, an in-sample tie-break)."""
    labels = list(labels)
    if len(labels) != errors.shape[1]:
        raise ValueError(f"{len(labels)} group labels for {errors.shape[1]} trials")
    names = list(dict.fromkeys(labels))
    if len(names) < 2:
        raise ValueError("leave-one-group-out needs at least two groups")
    folds = tuple(tuple(i for i, g in enumerate(labels) if g == name) for name in names)
    return _cv(errors, candidates, folds)


def _cv(errors: np.ndarray, candidates: Sequence, folds) -> CVResult:
    n = errors.shape[1]
    chosen, held = [], np.full(n, np.nan)
    for f in folds:
        train = [i for i in range(n) if i not in f]
        best = int(np.argmin(errors[:, train].mean(axis=1)))
        chosen.append(best)
        held[list(f)] = errors[best, list(f)]
    counts = Counter(chosen)
    top = max(counts.values())
    tied = [c for c in counts if counts[c] == top]
    default = min(tied, key=lambda c: errors[c].mean())
    return CVResult(tuple(dataclasses.asdict(c) if dataclasses.is_dataclass(c) else c for c in candidates),
                    errors, tuple(folds), tuple(chosen), float(np.nanmean(held)), int(default), held)
