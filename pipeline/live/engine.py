"""The causal per-frame computation of a live session: estimators only, no I/O.

Per frame k (one sample of every sensor, :mod:`stridelab.pipeline.live.align`):

1. orientation of every IMU by an online filter (``stridelab.estimators.orientation``, default ``DEFAULT_ONLINE``) fed
   only the samples that arrived (a lost sample is skipped, not filled);
2. anatomical frames ``q_AF = q_S ⊗ q_S←AF`` from the session calibration (thesis Eq. 17), hip, knee and
   ankle angles of both legs by the joint coordinate system (``stridelab.estimators.joints.joint_angles_deg``);
3. standing offsets (thesis ch. 8 step 4): every second during the first ``standing_search_s`` the frames
   so far are searched for the first quiet standing (``stridelab.estimators.calibration.first_quiet_standing``,
   which sees only frames < k); once that standing has ended or lasted ``target_standing_s``, its mean
   angle is the offset subtracted from every later frame (earlier frames are published without offset,
   ``offset_ready`` False);
4. gait events per foot by the streaming detector (``stridelab.estimators.gait.GaitEventDetector``, thesis Algorithm
   1) on s = −sin(foot pitch) (``pitch_signal``, anterior axis from the foot calibration, else sensor x):
   an event at extremum k−1 is known at k (look-ahead one sample, the thesis' documented latency);
5. strides: at each initial contact, stride time, stance (IC→TC of the same foot) and step time (the
   other foot's last IC → this IC); asymmetry of the last ``n_strides`` strides per side as the symmetry
   ratio larger/smaller mean (Patterson et al. 2010, as ``stridelab.estimators.gait.clinical`` C9), shown as
   ``100 (SR − 1)`` %.

Nothing looks ahead more than the one sample of step 4 (``LOOKAHEAD_FRAMES``); tests/live/test_causality.py
truncates the input and checks every earlier output unchanged, and checks the outputs equal the same
estimators run over the whole recording at once.
"""
from __future__ import annotations

import warnings
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from stridelab.estimators.calibration import CalibrationParams, first_quiet_standing
from stridelab.estimators.gait import GaitEventDetector, IcTcParams, pitch_signal
from stridelab.estimators.joints import JOINTS, calibrated_joint_angles_deg
from stridelab.estimators.orientation import DCFFilter, MadgwickFilter, MahonyFilter
from stridelab.pipeline.live.align import FrameBatch

#: gait events are known one frame after the extremum (thesis ch. 6); every other output at its own frame
LOOKAHEAD_FRAMES = 1
LEG_PLACEMENTS = ("pelvis", "thigh_left", "thigh_right", "shank_left", "shank_right", "foot_left", "foot_right")
#: online filters the live session can run (name -> OnlineFilter class with default parameters)
ONLINE_FILTERS = {"dcf": DCFFilter, "madgwick": MadgwickFilter, "mahony": MahonyFilter}
JOINT_KEYS = tuple(f"{j}_{s}" for j in JOINTS for s in ("left", "right"))


@dataclass(frozen=True)
class LiveParams:
    """Parameters of a live session.

    estimator: online orientation filter (``ONLINE_FILTERS``). use_magnetometer: feed the magnetometer when
    the sensor has one (the nightly orientation stage does too). standing_search_s: how long the first quiet
    standing is searched for (s). target_standing_s: a standing this long is used without waiting for it to
    end (s; thesis 3-5 s). n_strides: strides per side in the asymmetry (10, the issue's "last 10 strides").
    events: gait-event detector parameters (thesis values).
    """
    estimator: str = "dcf"
    use_magnetometer: bool = True
    standing_search_s: float = 15.0
    target_standing_s: float = 3.0
    n_strides: int = 10
    events: IcTcParams = IcTcParams()


@dataclass
class LiveOutput:
    """What one :meth:`LiveEngine.process` call published, frames ``k0 .. k0 + n − 1``.

    quat: placement -> (n, 4) sensor → ENU (NaN where the sample was lost). angles: "hip_left" … -> (n, 3)
    [FE, AA, IE] deg (offset removed once ``offset_ready``). pitch: side -> (n,) s = −sin(pitch).
    events: dicts {side, type IC|TC, k (event frame), k_detect, t_ns}. strides: dicts per completed stride.
    metrics: the latest asymmetry figures. offset_ready: (n,) bool.
    """
    k0: int
    n: int
    t_ns: np.ndarray
    arrival_ns: np.ndarray
    quat: dict
    angles: dict
    pitch: dict
    offset_ready: np.ndarray
    events: list = field(default_factory=list)
    strides: list = field(default_factory=list)
    metrics: dict = field(default_factory=dict)


def symmetry_pct(a: float, b: float) -> float:
    """``100 (SR − 1)`` with SR = larger / smaller of two positive means (Patterson et al. 2010); NaN if undefined."""
    if not (np.isfinite(a) and np.isfinite(b)) or min(a, b) <= 0:
        return float("nan")
    return 100.0 * (max(a, b) / min(a, b) - 1.0)


class LiveEngine:
    """Causal per-frame processing of one live session (see the module docstring).

    placements: the IMUs present; calibration: :class:`stridelab.estimators.calibration.SessionCalibration` or None
    (no joint angles then; events use sensor x as the foot's anterior axis).
    """

    def __init__(self, placements, *, sampling_rate_hz: float, calibration=None, params: LiveParams = LiveParams()):
        if params.estimator not in ONLINE_FILTERS:
            raise ValueError(f"unknown online estimator {params.estimator!r}; choose one of {sorted(ONLINE_FILTERS)}")
        self.params = params
        self.fs = float(sampling_rate_hz)
        self.placements = tuple(placements)
        self.calibration = calibration
        self.filters = {p: ONLINE_FILTERS[params.estimator](sampling_rate_hz=self.fs) for p in self.placements}
        self._q_af = {}
        if calibration is not None:
            for p in self.placements:
                c = calibration.imus.get(p)
                if c is not None and c.valid:
                    self._q_af[p] = c.quat_sensor_af
        self.joints = []
        for joint, (prox, dist) in JOINTS.items():
            for side in ("left", "right"):
                pp = prox if prox == "pelvis" else f"{prox}_{side}"
                dd = f"{dist}_{side}"
                if pp in self._q_af and dd in self._q_af:
                    self.joints.append((f"{joint}_{side}", joint, side, pp, dd))
        self.detectors, self.u_foot = {}, {}
        for side in ("left", "right"):
            p = f"foot_{side}"
            if p in self.placements:
                self.detectors[side] = GaitEventDetector(sampling_rate_hz=self.fs, params=params.events)
                c = calibration.imus.get(p) if calibration is not None else None
                self.u_foot[side] = np.asarray(c.R_sensor_af[:, 0], float) if c is not None and c.valid else \
                    np.array([1.0, 0.0, 0.0])
        # standing offsets: frames of the first standing_search_s kept for the search, then released
        self._n_search = int(round(params.standing_search_s * self.fs))
        self._buf_acc = {p: np.full((self._n_search, 3), np.nan) for p in self.placements}
        self._buf_gyr = {p: np.full((self._n_search, 3), np.nan) for p in self.placements}
        self._buf_ang = {k[0]: np.full((self._n_search, 3), np.nan) for k in self.joints}
        self._next_check = int(round(self.fs))
        self._cal_params = calibration.params if calibration is not None else CalibrationParams()
        self.offset = None                  # joint key -> (3,) deg once found
        self.offset_frame = None            # first frame with the offset applied
        self.standing = None                # [start, end) frames of the standing used
        self.k = 0                          # next frame expected
        # strides
        self._ic = {s: deque(maxlen=2) for s in ("left", "right")}
        self._tc = {s: deque(maxlen=4) for s in ("left", "right")}
        self._strides = {s: deque(maxlen=params.n_strides) for s in ("left", "right")}
        self.metrics = {}

    # ---- one batch -------------------------------------------------------------------------------------
    def process(self, b: FrameBatch) -> LiveOutput:
        if b.k0 != self.k:
            raise ValueError(f"frames must be consecutive: expected frame {self.k}, got {b.k0}")
        n = b.n
        quat = {}
        for p in self.placements:
            q = np.full((n, 4), np.nan)
            v = b.valid[p]
            if v.any():
                mag = b.mag[p][v] if (self.params.use_magnetometer and b.has_mag.get(p)) else None
                q[v] = self.filters[p].update_batch(b.gyr[p][v], b.acc[p][v], mag).quat
            quat[p] = q
        angles = {}
        for key, joint, side, pp, dd in self.joints:
            angles[key] = calibrated_joint_angles_deg(quat[pp], quat[dd], self._q_af[pp], self._q_af[dd],
                                                      joint=joint, side=side)
        ready = self._standing_offsets(b, angles)
        pitch, events = {}, []
        for side, det in self.detectors.items():
            s = pitch_signal(quat[f"foot_{side}"], self.u_foot[side])
            pitch[side] = s
            for i in range(n):
                r = det.push(s[i])
                if r is None:
                    continue
                for typ, k_det, k_ev in (r if isinstance(r, list) else [r]):
                    ev = {"side": side, "type": typ, "k": int(k_ev), "k_detect": int(k_det),
                          "t_ns": int(b.t_ns[0] + (k_ev - b.k0) * 1e9 / self.fs)}
                    events.append(ev)
        # in time order (detection frame, then event frame), both feet interleaved: strides pair the feet's ICs
        events.sort(key=lambda e: (e["k_detect"], e["k"], e["side"]))
        strides = self._strides_from(events)
        self.k += n
        return LiveOutput(b.k0, n, b.t_ns, b.arrival_ns, quat, angles, pitch, ready, events, strides,
                          dict(self.metrics))

    # ---- standing offsets (causal) ---------------------------------------------------------------------
    def _standing_offsets(self, b: FrameBatch, angles: dict) -> np.ndarray:
        n, k0 = b.n, b.k0
        ready = np.zeros(n, dtype=bool)
        if self.offset is None and k0 < self._n_search and self.joints:
            m = min(n, self._n_search - k0)
            for p in self.placements:
                self._buf_acc[p][k0:k0 + m] = b.acc[p][:m]
                self._buf_gyr[p][k0:k0 + m] = b.gyr[p][:m]
            for key in self._buf_ang:
                self._buf_ang[key][k0:k0 + m] = angles[key][:m]
            # checks at whole seconds, each on the frames before it only
            while self.offset is None and self._next_check <= min(k0 + n, self._n_search):
                c = self._next_check
                self._next_check += int(round(self.fs))
                self._try_standing(c)
                if self.offset is not None:
                    self.offset_frame = c
        if self.offset is not None:
            a = max(0, (self.offset_frame or 0) - k0)
            ready[a:] = True
            for key, v in angles.items():
                v[a:] -= self.offset[key]
        if self.offset is not None or k0 + n >= self._n_search:
            self._buf_acc = self._buf_gyr = self._buf_ang = {}
        return ready

    def _try_standing(self, c: int) -> None:
        """The first quiet standing among frames [0, c), used once ended or ``target_standing_s`` long."""
        cp = self._cal_params
        acc = {p: v[:c] for p, v in self._buf_acc.items()}
        gyr = {p: v[:c] for p, v in self._buf_gyr.items()}
        st = first_quiet_standing(acc, gyr, sampling_rate_hz=self.fs, params=cp)
        if st is None:
            return
        ended = st[1] <= c - int(round(0.25 * self.fs))
        if not ended and st[1] - st[0] < self.params.target_standing_s * self.fs:
            return
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)      # an all-NaN joint (lost sensor): NaN offset
            self.offset = {k: np.nanmean(v[st[0]:st[1]], axis=0) for k, v in self._buf_ang.items()}
        self.standing = (int(st[0]), int(st[1]))

    # ---- strides and asymmetry -------------------------------------------------------------------------
    def _strides_from(self, events: list) -> list:
        out = []
        fs = self.fs
        for ev in events:
            side = ev["side"]
            if ev["type"] == "TC":
                self._tc[side].append(ev["k"])
                continue
            ic_prev = self._ic[side][-1] if self._ic[side] else None
            other = "right" if side == "left" else "left"
            ic_other = self._ic[other][-1] if self._ic[other] else None
            self._ic[side].append(ev["k"])
            if ic_prev is None:
                continue
            stride_s = (ev["k"] - ic_prev) / fs
            tcs = [t for t in self._tc[side] if ic_prev < t < ev["k"]]
            stance_s = (tcs[0] - ic_prev) / fs if tcs else float("nan")
            step_s = (ev["k"] - ic_other) / fs if ic_other is not None and ic_prev < ic_other < ev["k"] \
                else float("nan")
            st = {"side": side, "k_start": int(ic_prev), "k_end": int(ev["k"]), "stride_time_s": stride_s,
                  "stance_time_s": stance_s, "stance_pct": 100.0 * stance_s / stride_s, "step_time_s": step_s}
            self._strides[side].append(st)
            out.append(st)
        if out:
            self.metrics = self._asymmetry()
        return out

    def _asymmetry(self) -> dict:
        def mean(side, key):
            v = np.array([s[key] for s in self._strides[side]], float)
            v = v[np.isfinite(v)]
            return float(v.mean()) if len(v) else float("nan")
        m = {f"{key}_{side}": mean(side, key) for side in ("left", "right")
             for key in ("step_time_s", "stance_pct", "stride_time_s")}
        m["step_time_asymmetry_pct"] = symmetry_pct(m["step_time_s_left"], m["step_time_s_right"])
        m["stance_asymmetry_pct"] = symmetry_pct(m["stance_pct_left"], m["stance_pct_right"])
        m["n_strides_left"] = len(self._strides["left"])
        m["n_strides_right"] = len(self._strides["right"])
        return m

