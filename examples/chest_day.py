"""A chest day: postures, walking bouts and steps
==================================================

The activity stage turns a free-living chest accelerometer into a per-second timeline of postures (lying,
sitting, standing) and walking modality (level walking, stairs up and down), steps and posture transitions
(Nazarahari 2021, ch. 7; ``docs/activity.md``). Here the first chest day of the first participant of a
warehouse, read through ``stridelab.open``: the timeline as coloured bouts, and the walking bouts (consecutive
walking classes joined) with their duration and cadence.
"""
import matplotlib.pyplot as plt
import numpy as np

import stridelab
from _common import home, out, saved
from stridelab.warehouse.queries import walking_bouts

COLOURS = {"lying": "#4c72b0", "sitting": "#8c8c8c", "standing": "#dd8452", "level_walking": "#55a868",
           "stairs_up": "#c44e52", "stairs_down": "#8172b3", "non_wear": "#ffffff"}

with stridelab.open(home()) as wh:
    days = wh.sessions()
    day = days[days["kind"] == "free_living"].iloc[0]
    pid, sid = day["participant_id"], day["session_id"]
    bouts = wh.activity_bouts(session=sid)
    walks = walking_bouts(wh.con, pid)
walks = walks[walks["session_id"] == sid]
t0 = bouts["start_ns"].min()
hours = bouts.assign(h=(bouts["end_ns"] - bouts["start_ns"]) / 3.6e12).groupby("class")["h"].sum()
print(f"{pid} {sid}: " + ", ".join(f"{c} {h:.2f} h" for c, h in hours.items()))
print(f"{len(walks)} walking bouts, {int(np.nansum(walks['steps']))} steps, "
      f"median bout {walks['seconds'].median():.0f} s")

fig, (a, b) = plt.subplots(2, 1, figsize=(9, 4), gridspec_kw={"height_ratios": [1, 1.4]})
for c, g in bouts.groupby("class"):
    a.broken_barh([((s - t0) / 3.6e12, (e - s) / 3.6e12) for s, e in zip(g["start_ns"], g["end_ns"])], (0, 1),
                  color=COLOURS.get(c, "k"), label=c)
a.set_yticks([])
a.set_xlabel("hours from the start of the recording")
a.legend(ncol=6, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, 1.45), frameon=False)
b.scatter(walks["seconds"], walks["cadence_spm"], s=12)
b.set_xscale("log")
b.set_xlabel("walking bout duration (s)")
b.set_ylabel("cadence (steps/min)")
fig.tight_layout()
fig.savefig(out("chest_day.png"), dpi=80)
saved(out("chest_day.png"))
