"""Walking outcomes from a lower-back sensor
===========================================

``stridelab.estimators.trunk_gait`` finds walking bouts, initial contacts with their side, cadence, stride length and speed
in one trunk sensor's signals (lower back at L4/L5 or chest; any mounting: the body frame is detected), and
``daily_outcomes`` summarises the bouts as Mobilise-D-style digital mobility outcomes (``docs/trunk_gait.md``).
Here the simulated-daily-living test (Test 11) of the one Mobilise-D lab participant in the public data
(``stridelab.pipeline.formats.mobilised``), against the INDIP reference system's walking bouts recorded with it. This
participant's three trials were part of the data the trunk-gait defaults were chosen on (the stride-length factor
on them alone): an illustration, not an accuracy figure; those are in ``stridelab bench trunk-gait`` and
``validation/provenance.toml``.
"""
import matplotlib.pyplot as plt
import numpy as np

from _common import data, out, saved
from stridelab.estimators.trunk_gait import analyse_trunk_gait, daily_outcomes
from stridelab.pipeline.formats.mobilised import read_mobilised

trial = next(t for t in read_mobilised(data("mobilised_lab") / "HA" / "001") if t.test == "Test11")
res = analyse_trunk_gait(trial.acc, trial.gyr, trial.fs_hz, placement="lower_back", height_m=trial.info.height_m)
b = res.bouts
print(f"{trial.test} {trial.trial}: {len(trial.acc) / trial.fs_hz:.0f} s at {trial.fs_hz:.0f} Hz, "
      f"{len(b.start_s)} walking bouts, {len(res.initial_contacts_s)} initial contacts")
day = daily_outcomes(b.start_s, b.end_s - b.start_s, b.cadence_spm, b.stride_length_m, b.walking_speed_m_s,
                     res.strides.speed_m_s, stride_bout=res.strides.bout)
print(f"walking time {day.walking_time_s:.0f} s, bouts > 10 s: {day.n_bouts_over_10s}, "
      f"median cadence {day.cadence_median_spm:.0f} steps/min, median speed {day.speed_median_m_s:.2f} m/s")
ref = next(r for r in trial.references if r.system == "INDIP" and r.kind == "MicroWB")
print(f"INDIP reference: {len(ref.start_s)} bouts, median cadence {np.nanmedian(ref.cadence_spm):.0f} steps/min, "
      f"median speed {np.nanmedian(ref.walking_speed_m_s):.2f} m/s")

t = np.arange(len(trial.acc)) / trial.fs_hz
fig, (a, c) = plt.subplots(2, 1, figsize=(9, 4.2), sharex=True, gridspec_kw={"height_ratios": [1.4, 1]})
a.plot(t, np.linalg.norm(trial.acc, axis=1), lw=0.5, color="k")
a.set_ylabel("|acc| (m/s²)")
a.set_title(f"lower back, Mobilise-D {trial.test}: bouts found (blue) and INDIP reference (orange)", fontsize=9)
for s, e in zip(b.start_s, b.end_s):
    a.axvspan(s, e, ymin=0.5, ymax=1, color="tab:blue", alpha=0.25)
for s, e in zip(ref.start_s, ref.end_s):
    a.axvspan(s, e, ymin=0, ymax=0.5, color="tab:orange", alpha=0.25)
mid = 0.5 * (b.start_s + b.end_s)
c.plot(mid, b.walking_speed_m_s, "o", color="tab:blue", label="StrideLab")
c.plot(0.5 * (ref.start_s + ref.end_s), ref.walking_speed_m_s, "s", color="tab:orange", label="INDIP")
c.set_ylabel("bout speed (m/s)")
c.set_xlabel("time (s)")
c.legend(fontsize=8)
fig.tight_layout()
fig.savefig(out("lower_back_walking.png"), dpi=80)
saved(out("lower_back_walking.png"))
