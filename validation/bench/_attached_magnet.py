"""A stress group for ``stridelab bench orientation``: BROAD's undisturbed trials with a magnet attached to the sensor.

BROAD's development trials hold an attached magnet at two distances only (trials 32 and 34). On the segment where the
magnet is on, their magnetometer is the undisturbed field plus a constant offset in the sensor frame (hard iron): a
least-squares sphere fit |m − b| = R over that segment leaves a residual of 0.84 / 0.82 µT (the sensor noise), with
|b| = 58.5 µT at 1 cm and 14.0 µT at 3 cm. The held-back trials include other distances (2 cm, 5 cm) and a vibrating
phone (its motor is a small magnet). This module builds such trials from the real undisturbed ones: the offset
``magnitude_ut`` · d (d a random unit vector, fixed seed) is added to the magnetometer over the middle 60 % of the
movement (the magnet is put on and taken off while moving), for 4, 10, 25 and 40 µT. Optical reference, gyro and
accelerometer stay real. The model is this module's own (it shares no code or threshold with the estimators), and the
group is reported apart from the real trials; the only thing it is used for is the choice among the magnetic
disturbance options in :func:`disturbance_cv` (the leave-one-group-out with this group as a fourth group).
"""
from __future__ import annotations

import dataclasses

import numpy as np

#: offsets of the synthetic attached magnets, µT (between and around the fitted 14.0 µT at 3 cm and 58.5 µT at 1 cm)
MAGNITUDES_UT = (4.0, 10.0, 25.0, 40.0)
SEED = 3
GROUP = "attached_magnet_synthetic"


def attached_magnet_trials(trials, magnitudes_ut=MAGNITUDES_UT, seed: int = SEED) -> list:
    """Synthetic attached-magnet trials from the undisturbed trials of ``trials`` (BroadTrial-like objects with a
    ``disturbed`` property; see the module docstring). Names are ``<trial>+<µT>uT``."""
    rng = np.random.default_rng(seed)
    out = []
    for t in trials:
        if t.disturbed or not t.movement.any():
            continue
        mv = np.flatnonzero(t.movement)
        a, b = mv[0], mv[-1]
        s0, s1 = int(a + 0.2 * (b - a)), int(a + 0.8 * (b - a))
        for m in magnitudes_ut:
            d = rng.normal(size=3)
            d /= np.linalg.norm(d)
            mag = t.mag.copy()
            mag[s0:s1] += m * d
            out.append(dataclasses.replace(t, name=f"{t.name}+{m:g}uT", mag=mag, groups=(GROUP,)))
    return out


#: dcf's magnetic-disturbance options offered to the choice (the defaults before issue 43 first; preference order on
#: ties): the online hard-iron fit on/off and its minimum offset, the settling time after a rejected sample
DCF_OPTIONS = tuple([{"hard_iron": False, "mag_settle_s": 0.0}]
                    + [{"hard_iron": True, "hard_iron_min_ut": m, "mag_settle_s": s}
                       for m in (3.0, 5.0) for s in (0.0, 0.5, 1.0)]
                    + [{"hard_iron": False, "mag_settle_s": s} for s in (0.5, 1.0)])
#: VQF's counterparts with the same budget: its settling time (magMinUndisturbedTime, default 0.5 s), how long it
#: rejects before it uses a disturbed field again (magMaxRejectionTime, default 60 s) and new-field acceptance time
VQF_OPTIONS = tuple({"magMinUndisturbedTime": s, "magMaxRejectionTime": r, "magNewTime": n}
                    for s in (0.5, 0.0, 1.0) for r in (60.0, 1e9) for n in (20.0, 1e9))


def disturbance_cv(trials, synthetic, labels: list[str], progress=None) -> dict:
    """Leave-one-group-out over the BROAD groups plus the synthetic group, for dcf's and VQF's magnetic-disturbance
    options (:data:`DCF_OPTIONS`, :data:`VQF_OPTIONS`). The objective is the mean over the training groups of each
    group's mean total RMSE (each group weighs the same, whatever its number of trials). Returns, per method, the
    choice per fold, the held-out error per group, the option chosen most often and the table of all options."""
    from stridelab.estimators.orientation import DCFParams, dcf, vqf_orientation
    from stridelab.estimators.orientation.evaluation import orientation_rmse_deg

    allt = list(trials) + list(synthetic)
    groups = np.array(list(labels) + [GROUP] * len(synthetic))
    methods = {
        "dcf": (DCF_OPTIONS, lambda o, t: dcf(t.gyr, t.acc, t.mag, sampling_rate_hz=t.sampling_rate_hz,
                                                params=DCFParams(**o)).quat),
        "vqf": (VQF_OPTIONS, lambda o, t: vqf_orientation(t.gyr, t.acc, t.mag, sampling_rate_hz=t.sampling_rate_hz,
                                                          params=o).quat),
    }
    out = {"groups": sorted(set(groups)), "objective": "mean over the training groups of the group mean total RMSE"}
    for name, (options, run) in methods.items():
        err = np.empty((len(options), len(allt)))
        for i, o in enumerate(options):
            for j, t in enumerate(allt):
                err[i, j] = orientation_rmse_deg(run(o, t), t.quat_ref, t.movement).total_rmse_deg
                if progress is not None:
                    progress()

        def gmean(i, mask):
            return float(np.mean([err[i][(groups == g) & mask].mean() for g in np.unique(groups[mask])]))

        folds, chosen = {}, []
        for g in sorted(set(groups)):
            train = groups != g
            k = int(np.argmin([gmean(i, train) for i in range(len(options))]))
            chosen.append(k)
            folds[g] = {"chosen": options[k], "heldout_deg": float(err[k][groups == g].mean())}
        ship = max(set(chosen), key=lambda k: (chosen.count(k), -gmean(k, groups == groups)))
        real = groups != GROUP
        out[name] = {"folds": folds, "shipped": options[ship], "chosen_in_folds": chosen.count(ship),
                     "heldout_real_deg": float(np.mean([folds[g]["heldout_deg"] for g in folds if g != GROUP])),
                     "options": [{"option": o, "real_mean_deg": float(err[i][real].mean()),
                                  "synthetic_mean_deg": float(err[i][~real].mean())} for i, o in enumerate(options)]}
    return out


def stress_scores(synthetic, names: list[str]) -> dict:
    """Mean total RMSE of each estimator (default parameters) on the synthetic group, overall and per magnitude."""
    from stridelab.estimators.orientation import ESTIMATORS
    from stridelab.estimators.orientation.evaluation import orientation_rmse_deg
    out = {}
    for name in names:
        est = ESTIMATORS[name]
        errs = np.array([orientation_rmse_deg(est(t.gyr, t.acc, t.mag, sampling_rate_hz=t.sampling_rate_hz).quat,
                                              t.quat_ref, t.movement).total_rmse_deg for t in synthetic])
        mags = np.array([float(t.name.rsplit("+", 1)[1][:-2]) for t in synthetic])
        out[name] = {"mean_total_rmse_deg": float(errs.mean()),
                     "by_offset_ut": {f"{m:g}": float(errs[mags == m].mean()) for m in sorted(set(mags))}}
    return out
