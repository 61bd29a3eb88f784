"""Share recordings as Motion-BIDS
==================================

``stridelab export bids WAREHOUSE OUT/`` (here through ``stridelab.pipeline.export.bids.export_bids``) writes the recordings
with their events as a BIDS 1.9 Motion dataset: ``*_motion.tsv`` (samples), ``*_channels.tsv`` (name, type,
placement, units), ``*_motion.json``, ``*_events.tsv`` (reference and estimated contacts), ``participants.tsv``
and ``dataset_description.json``, pseudonymised (subjects renumbered, no dates, no file names). Any BIDS tool can
read it back: here plain pandas reads one walking trial and its events.
"""
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from _common import home, out, saved
from stridelab.pipeline.export.bids import export_bids

with tempfile.TemporaryDirectory() as tmp:
    ds = Path(tmp) / "bids"
    s = export_bids(home() / "warehouse", ds, kinds=("lab",))
    print(f"{s.subjects} subjects, {s.sessions} sessions, {s.recordings} recordings, {s.events} events")
    print(sorted(p.name for p in ds.iterdir()))
    motion = sorted(ds.rglob("*task-walk_tracksys-IMU_run-1_motion.tsv"))[0]
    channels = pd.read_csv(str(motion).replace("_motion.tsv", "_channels.tsv"), sep="\t")
    samples = pd.read_csv(motion, sep="\t", header=None, names=list(channels["name"]))
    events = pd.read_csv(motion.parent / motion.name.replace("_tracksys-IMU", "").replace("_motion.tsv", "_events.tsv"),
                         sep="\t")
    fs = pd.read_json(str(motion).replace(".tsv", ".json"), typ="series")["SamplingFrequency"]
    print(motion.relative_to(ds))
    print(channels.head(6).to_string(index=False))

t = np.arange(len(samples)) / fs
fig, ax = plt.subplots(figsize=(8, 3))
ax.plot(t, samples[["foot_left_gyr_x", "foot_left_gyr_y", "foot_left_gyr_z"]], lw=0.7)
for _, e in events[(events["side"] == "left") & (events["trial_type"] == "IC")].iterrows():
    ax.axvline(e["onset"], color="tab:red" if e["source"] == "reference" else "k", lw=0.6,
               ls="-" if e["source"] == "reference" else "--")
ax.set_xlabel("onset (s)")
ax.set_ylabel("gyr (rad/s)")
ax.set_title(f"{motion.name}: left foot; initial contacts (red: reference, dashed: StrideLab)", fontsize=8)
fig.tight_layout()
fig.savefig(out("export_bids.png"), dpi=80)
saved(out("export_bids.png"))
