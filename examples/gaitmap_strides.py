"""Foot trajectory and strides of the gaitmap example walk
==========================================================

``stridelab.estimators.gait.foot_kinematics`` on one foot IMU (gyr rad/s, acc m/s², any mounting): an error-state Kalman
filter with zero-velocity updates and a smoother integrates the foot's trajectory, the pitch signal gives initial
and terminal contacts (Nazarahari 2021, ch. 6), strides run mid-stance to mid-stance. The gaitmap example walk
(Küderle et al. 2022; two NilsPod IMUs on the shoes, 204.8 Hz) comes with Qualisys markers: the figure shows
the foot's path seen from above and each stride's length against the heel marker's.
"""
import matplotlib.pyplot as plt
import numpy as np

from _common import data, out, saved
from stridelab.estimators.gait import foot_kinematics
from stridelab.pipeline.formats.gaitmap import load_gaitmap_example

walk = load_gaitmap_example(data("gaitmap_example"))
fs = walk.sampling_rate_hz
foot = walk.left
fk = foot_kinematics(foot.gyr, foot.acc, sampling_rate_hz=fs)
st = fk.strides
length = st.column("stride_length_m")
print(f"left foot: {len(st)} strides, {len(fk.events.ic_idx)} initial contacts, status {fk.status}; "
      f"median stride length {np.nanmedian(length):.2f} m, stride time {np.nanmedian(st.column('stride_time_s')):.2f} s")

# reference: the heel marker's horizontal displacement between the same stride borders (mocap at 100 Hz)
heel = foot.markers["FCC"]
def heel_xy(i):                                   # IMU sample -> heel marker position (m), nearest mocap frame
    k = min(int(round(i / fs * walk.mocap_rate_hz)), len(heel) - 1)
    return heel[k, :2]
ref = np.array([np.linalg.norm(heel_xy(e) - heel_xy(s)) for s, e in st.idx[:, :2]])
ok = np.isfinite(ref) & np.isfinite(length)
print(f"stride length vs heel marker: MAE {100 * np.mean(np.abs(length[ok] - ref[ok])):.1f} cm over {ok.sum()} strides")

fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.6), gridspec_kw={"width_ratios": [1.6, 1]})
p = fk.trajectory.pos
a.plot(p[:, 0], p[:, 1], lw=0.8)
a.plot(p[st.idx[:, 0], 0], p[st.idx[:, 0], 1], "o", ms=3, label="stride starts (mid-stance)")
a.set_aspect("equal")
a.set_xlabel("x (m)")
a.set_ylabel("y (m)")
a.set_title("left foot trajectory (ENU, from above)")
a.legend(fontsize=8)
b.plot(ref[ok], length[ok], "o", ms=4)
lim = [np.nanmin(ref[ok]) - 0.05, np.nanmax(ref[ok]) + 0.05]
b.plot(lim, lim, "k--", lw=0.8)
b.set_xlabel("heel marker (m)")
b.set_ylabel("IMU stride length (m)")
b.set_title("stride length")
fig.tight_layout()
fig.savefig(out("gaitmap_strides.png"), dpi=80)
saved(out("gaitmap_strides.png"))
