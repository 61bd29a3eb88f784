"""Orientation on a BROAD trial, against VQF
=============================================

Two orientation estimators from ``stridelab.estimators.orientation`` on one trial of the BROAD benchmark (Laidig et al.
2021: IMU + optical reference): StrideLab's default online filter ``dcf`` and VQF (Laidig & Seel 2023) with its
defaults. Arrays in (gyr rad/s, acc m/s², mag µT), quaternions ``[w, x, y, z]`` sensor → ENU out; the error is
the BROAD metric (``stridelab.estimators.orientation.evaluation``: the angle of ``q_est ⊗ q_ref*``, no alignment), RMS over
the trial's movement phases. ``dcf``'s defaults were chosen on the BROAD trials, so this trial is in-sample for
it; the held-out figures (leave-one-group-out) are in the accuracy table of the README and ``docs/orientation.md``.
"""
import matplotlib.pyplot as plt
import numpy as np

from _common import data, out, saved
from stridelab.estimators.orientation import dcf, vqf_orientation
from stridelab.estimators.orientation.evaluation import orientation_error_deg, orientation_rmse_deg
from stridelab.pipeline.formats.broad import load_broad

trial = load_broad(data("broad") / "24_disturbed_tapping_A.hdf5")[0]
fs = trial.sampling_rate_hz
results = {"dcf (StrideLab default)": dcf(trial.gyr, trial.acc, trial.mag, sampling_rate_hz=fs),
           "VQF (defaults)": vqf_orientation(trial.gyr, trial.acc, trial.mag, sampling_rate_hz=fs)}

t = np.arange(len(trial.gyr)) / fs
fig, ax = plt.subplots(figsize=(8, 3.5))
for name, r in results.items():
    total, _, _ = orientation_error_deg(r.quat, trial.quat_ref)
    rmse = orientation_rmse_deg(r.quat, trial.quat_ref, trial.movement)
    print(f"{name}: total RMSE {rmse.total_rmse_deg:.2f}° over the movement phases")
    ax.plot(t, total, lw=0.8, label=f"{name}: RMSE {rmse.total_rmse_deg:.2f}°")
ax.set_xlabel("time (s)")
ax.set_ylabel("orientation error (°)")
ax.set_title(f"BROAD {trial.name} ({fs:.0f} Hz)")
ax.legend(fontsize=8)
fig.tight_layout()
fig.savefig(out("orientation_broad.png"), dpi=80)
saved(out("orientation_broad.png"))
