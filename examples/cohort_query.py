"""Query the warehouse across a cohort
======================================

``stridelab.open`` gives read-only pandas access to the newest snapshot of a warehouse: participants, sessions,
strides, clinical measures, daily activity, accuracy. Here: gait speed of every participant at every lab visit
(the clinical stage's session value with its MDC95) and the distribution of stride lengths per participant, in
a few lines of pandas. ``wh.sql(...)`` runs any read-only DuckDB query on the same snapshot.
"""
import matplotlib.pyplot as plt

import stridelab
from _common import home, out, saved

with stridelab.open(home()) as wh:
    print(wh)
    print(wh.participants()[["participant_id", "sessions", "recordings"]].to_string(index=False))
    visits = wh.clinical_measures()
    strides = wh.strides()
    per_kind = wh.sql("SELECT kind, count(*) AS sessions FROM sessions GROUP BY kind ORDER BY kind")
print(per_kind.to_string(index=False))
speed = visits[visits["measure"] == "gait_speed_m_s"].pivot(index="participant_id", columns="visit", values="value")
print("gait speed (m/s) per visit:")
print(speed.round(2).to_string())

fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.4))
for pid, g in visits[visits["measure"] == "gait_speed_m_s"].groupby("participant_id"):
    a.errorbar(g["visit"], g["value"], yerr=g["mdc95"] / 2, marker="o", capsize=3, label=pid)
a.set_xlabel("visit")
a.set_ylabel("gait speed (m/s)")
a.set_title("gait speed per visit (bars: ± MDC95 / 2)", fontsize=9)
a.legend(fontsize=8)
groups = [(pid, g["stride_length_m"].dropna()) for pid, g in strides.groupby("participant_id")]
b.boxplot([g for _, g in groups], tick_labels=[p for p, _ in groups])
b.set_ylabel("stride length (m)")
b.set_title("strides of every lab walk", fontsize=9)
fig.tight_layout()
fig.savefig(out("cohort_query.png"), dpi=80)
saved(out("cohort_query.png"))
