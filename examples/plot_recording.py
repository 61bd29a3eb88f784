"""Read an MCAP recording and plot it
======================================

``stridelab.read_recording`` reads one recording-format MCAP file (the same reader as ingest, every CRC checked)
into arrays with units: acc in m/s², gyr in rad/s, magnetometer in µT, time in int64 nanoseconds. Here: the
first walking trial of the demo study, the left foot's angular velocity about its medio-lateral axis, with the
reference initial and terminal contacts recorded in the file.
"""
import matplotlib.pyplot as plt
import numpy as np

import stridelab
from _common import home, out, saved

walk = sorted((home() / "inbox").rglob("*walk-1*.mcap"))[0]
rec = stridelab.read_recording(walk)
foot = rec.imu["foot_left"]
t = (foot.t_ns - foot.t_ns[0]) / 1e9                      # s from the first sample
print(rec.metadata["participant"], rec.metadata["session"], f"{len(t)} samples,",
      f"{1 / np.median(np.diff(t)):.0f} Hz, IMUs: {sorted(rec.imu)}")

fig, (a, b) = plt.subplots(2, 1, sharex=True, figsize=(8, 4.5))
a.plot(t, foot.gyr, lw=0.8)
a.set_ylabel("gyr (rad/s)")
a.legend(["x", "y", "z"], loc="upper right", ncol=3, fontsize=8)
b.plot(t, np.linalg.norm(foot.acc, axis=1), lw=0.8, color="k")
b.set_ylabel("|acc| (m/s²)")
b.set_xlabel("time (s)")
for e in rec.events:
    if e.get("side") == "left" and e["type"] in ("IC", "TC"):
        x = (int(e["t_ns"]) - foot.t_ns[0]) / 1e9
        for ax in (a, b):
            ax.axvline(x, color="tab:red" if e["type"] == "IC" else "tab:blue", lw=0.6, alpha=0.6)
a.set_title(f"{walk.name}: left foot (red: initial contacts, blue: terminal contacts)")
fig.tight_layout()
fig.savefig(out("plot_recording.png"), dpi=80)
saved(out("plot_recording.png"))
