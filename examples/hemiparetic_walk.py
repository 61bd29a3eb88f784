"""Events and clinical measures of a hemiparetic walk
=====================================================

A simulated walk of a person after stroke (``stridelab.validation.simulator.hemiparetic_gait``: moderate severity, its own
kinematic model, sharing no code with the estimators) gives two foot IMUs and the true contact times. Each foot
goes through ``stridelab.estimators.gait.foot_kinematics``; ``stridelab.estimators.gait.clinical`` turns the strides and events into
what a clinician reads: step, swing and stance times per side, their paretic and symmetry ratios (Patterson et
al. 2010) and the minimal detectable change (``docs/clinical_measures.md``). Step length needs both feet in one
frame (the clinical stage does it) and is left out here.
"""
import matplotlib.pyplot as plt
import numpy as np

from _common import out, saved
from stridelab.estimators.gait import foot_kinematics
from stridelab.estimators.gait.clinical import FootEvents, FootStrides, clinical_summary, step_phases
from stridelab.validation.simulator.hemiparetic_gait import simulate_hemiparetic_trial

trial = simulate_hemiparetic_trial("moderate", 3, strides=14)
fs = trial.rate_hz
print(f"simulated: paretic side {trial.paretic_side}, speed {trial.params['speed_m_s']:.2f} m/s, "
      f"cadence {trial.params['cadence']:.0f} steps/min")

fks = {side: foot_kinematics(f.gyr, f.acc, sampling_rate_hz=fs) for side, f in trial.feet.items()}
inputs = {}
for side, fk in fks.items():
    st = fk.strides
    s = lambda col: st.column(col) / fs                                     # sample index -> s
    pre = np.where(st.column("pre_ic") >= 0, s("pre_ic"), np.nan)
    inputs[side] = (FootStrides(pre_ic_s=pre, tc_s=s("tc"), ic_s=s("ic"),
                                stride_length_m=st.column("stride_length_m"),
                                turning_deg=np.nan_to_num(st.column("turning_angle_deg"))),
                    FootEvents(ic_s=np.sort(fk.events.ic_idx / fs), tc_s=np.sort(fk.events.tc_idx / fs)))
phases = {side: step_phases(inputs[side][0], inputs["right" if side == "left" else "left"][1])
          for side in inputs}
summary = clinical_summary(phases["left"], phases["right"], paretic_side=trial.paretic_side)
for name in ("step_time_s", "swing_time_s", "stance_time_s", "single_support_s"):
    m = summary.measures[name]
    print(f"{name:18s} left {m.left:.3f}  right {m.right:.3f}  paretic ratio {m.paretic_ratio:.2f}  "
          f"symmetry ratio {m.symmetry_ratio:.2f}  (MDC95 {m.mdc95_symmetry_ratio:.2f})")
print(f"gait speed {summary.measures['gait_speed_m_s'].value:.2f} m/s, "
      f"cadence {summary.measures['cadence_steps_min'].value:.0f} steps/min")

# detected initial contacts against the simulator's truth
fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.4), gridspec_kw={"width_ratios": [1.7, 1]})
for k, (side, f) in enumerate(trial.feet.items()):
    det = fks[side].events.ic_idx / fs
    err = [1000 * (det[np.argmin(np.abs(det - t))] - t) for t in f.ic_s if len(det)]
    print(f"{side}: {len(det)} ICs detected for {len(f.ic_s)} true, median |error| {np.median(np.abs(err)):.0f} ms")
    t = np.arange(len(f.gyr)) / fs
    a.plot(t, np.linalg.norm(f.gyr, axis=1) + 9 * k, lw=0.7, label=f"{side}{' (paretic)' if f.paretic else ''}")
    a.plot(f.ic_s, np.full(len(f.ic_s), 9 * k + 6.5), "kv", ms=4)
    a.plot(det, np.full(len(det), 9 * k + 7.5), "r^", ms=4)
a.set_xlabel("time (s)")
a.set_yticks([])
a.set_title("|gyr| of each foot; true (▼) and detected (▲) initial contacts", fontsize=9)
a.legend(fontsize=8, loc="lower right")
names = ["step_time_s", "swing_time_s", "stance_time_s", "single_support_s"]
b.bar(range(len(names)), [summary.measures[n].paretic_ratio for n in names], color="tab:purple")
b.axhline(1, color="k", lw=0.8)
b.set_xticks(range(len(names)), ["step", "swing", "stance", "single support"], rotation=30, fontsize=8)
b.set_title("paretic / non-paretic", fontsize=9)
fig.tight_layout()
fig.savefig(out("hemiparetic_walk.png"), dpi=80)
saved(out("hemiparetic_walk.png"))
