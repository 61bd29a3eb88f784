"""The live computation is causal and equals the same estimators run over the whole recording at once."""
from __future__ import annotations


import numpy as np
import pytest

from stridelab.pipeline.live.align import FrameAligner
from stridelab.pipeline.live.engine import LEG_PLACEMENTS, LOOKAHEAD_FRAMES, LiveEngine


def _run(streams, cal, n=None, drop=None, burst=1):
    """Feed the first ``n`` frames sample by sample (``burst`` frames per aligner.ready call); ``drop``:
    {placement: set of sample indices never delivered}."""
    pl = [p for p in LEG_PLACEMENTS if p in streams.sensors]
    fs = streams.sampling_rate_hz
    al = FrameAligner(pl, sampling_rate_hz=fs)
    eng = LiveEngine(pl, sampling_rate_hz=fs, calibration=cal)
    N = n or min(len(streams.sensors[p].t_ns) for p in pl)
    outs = []
    for i in range(N):
        for p in pl:
            if drop and i in drop.get(p, ()):
                continue
            s = streams.sensors[p]
            for b in al.add(p, int(s.t_ns[i]), int(s.log_ns[i]), 1, s.gyr[i], s.acc[i], s.mag[i], emit=False):
                outs.append(eng.process(b))
        if (i + 1) % burst == 0:
            outs += [eng.process(b) for b in al.ready()]
    outs += [eng.process(b) for b in al.flush()]
    return eng, al, outs


def _cat(outs, what, key):
    return np.concatenate([getattr(o, what)[key] for o in outs])


@pytest.mark.slow
def test_live_equals_the_online_estimators_run_over_the_whole_recording(lab_streams, lab_calibration):
    from stridelab.estimators.gait import detect_ic_tc, pitch_signal
    from stridelab.estimators.joints import joint_angles_deg, segment_orientations
    from stridelab.estimators.orientation import dcf
    eng, al, outs = _run(lab_streams, lab_calibration, burst=7)
    fs = lab_streams.sampling_rate_hz
    whole = {}
    for p in eng.placements:
        s = lab_streams.sensors[p]
        whole[p] = dcf(s.gyr, s.acc, s.mag, sampling_rate_hz=fs).quat
        np.testing.assert_array_equal(_cat(outs, "quat", p), whole[p])       # chunked = whole, bit for bit
    seg = segment_orientations(whole, lab_calibration)
    assert eng.offset is not None and eng.standing[1] <= eng.offset_frame
    for key, joint, side, pp, dd in eng.joints:
        ref = joint_angles_deg(seg[pp], seg[dd], joint=joint, side=side)
        # the offset: mean over the standing the engine found, from frames before it was applied
        off = ref[eng.standing[0]:eng.standing[1]].mean(axis=0)
        ref[eng.offset_frame:] -= off
        np.testing.assert_allclose(_cat(outs, "angles", key), ref, rtol=0, atol=1e-9)
    for side in ("left", "right"):
        s = pitch_signal(whole[f"foot_{side}"], eng.u_foot[side])
        ev = detect_ic_tc(s, sampling_rate_hz=fs)
        live = [e for o in outs for e in o.events if e["side"] == side]
        assert [e["k"] for e in live if e["type"] == "IC"] == ev.ic_idx.tolist()
        assert [e["k"] for e in live if e["type"] == "TC"] == ev.tc_idx.tolist()
        assert all(e["k_detect"] - e["k"] == LOOKAHEAD_FRAMES for e in live)
        assert len(ev.ic_idx) >= 8                      # a 30-s walk: the test has events to compare


@pytest.mark.slow
@pytest.mark.parametrize("cut", [700, 1501])
def test_truncated_input_leaves_every_earlier_output_unchanged(lab_streams, lab_calibration, cut):
    _, _, full = _run(lab_streams, lab_calibration)
    _, _, part = _run(lab_streams, lab_calibration, n=cut)
    for p in LEG_PLACEMENTS:
        np.testing.assert_array_equal(_cat(part, "quat", p), _cat(full, "quat", p)[:cut])
    for key in full[0].angles:
        np.testing.assert_array_equal(_cat(part, "angles", key), _cat(full, "angles", key)[:cut])
    ev_full = [e for o in full for e in o.events if e["k_detect"] < cut]
    ev_part = [e for o in part for e in o.events]
    assert ev_part == ev_full
    assert len(ev_full) > 0 or cut < 800                # the later cut falls in the walking


@pytest.mark.slow          # the live engine over the whole 30-s walk: 2.8 CPU-s
def test_lost_samples_are_counted_and_left_empty_not_filled(lab_streams, lab_calibration):
    lost = set(range(1200, 1210)) | {1500}
    eng, al, outs = _run(lab_streams, lab_calibration, drop={"shank_left": lost})
    assert al.counters()["shank_left"]["gaps"] == len(lost)
    assert al.counters()["pelvis"]["gaps"] == 0
    q = _cat(outs, "quat", "shank_left")
    k = _cat(outs, "angles", "knee_left")
    idx = sorted(lost)
    assert np.isnan(q[idx]).all() and np.isnan(k[idx]).all()
    assert np.isfinite(q[1199]).all() and np.isfinite(q[1210]).all()
    assert np.isfinite(_cat(outs, "angles", "knee_right")[idx]).all()


def test_sensors_on_independent_clocks_meet_on_one_frame_grid():
    """Host clock mode: each sensor's own stamps (arbitrary offsets) placed by its first arrival."""
    fs = 100.0
    al = FrameAligner(["a", "b"], sampling_rate_hz=fs, clock="host")
    frames = []
    now = 10**12                                        # arrivals and "now" on the test's clock, not the machine's:
    for i in range(50):                                 # a loaded machine must not make frames wait too long
        host = 1_000_000_000 + i * 10_000_000
        if i != 20:                                     # b loses one sample
            frames += al.add("b", 777_000_000_000 + i * 10_000_000, host + 2_000_000, now, np.zeros(3), np.ones(3),
                             emit=False)
        frames += al.add("a", 5_000 + i * 10_000_000, host, now, np.zeros(3), np.ones(3), emit=False)
        frames += al.ready(now_ns=now)
    frames += al.flush()
    valid_a = np.concatenate([f.valid["a"] for f in frames])
    valid_b = np.concatenate([f.valid["b"] for f in frames])
    assert len(valid_a) == 50 and valid_a.all()
    assert np.flatnonzero(~valid_b).tolist() == [20]
    assert al.counters()["b"] == {"received": 49, "gaps": 1, "late": 0, "duplicate": 0, "drift_ppm": 0.0}


def test_a_stalled_sensor_holds_the_others_only_max_wait_ms():
    al = FrameAligner(["a", "b"], sampling_rate_hz=100.0, max_wait_ms=40.0)
    t0 = 1_000_000_000_000
    out = []
    for i in range(30):                                 # arrivals 10 ms apart (real time); b stops after 10
        arr = t0 + i * 10_000_000
        out += al.add("a", i * 10_000_000, 0, arr, np.zeros(3), np.ones(3), emit=False)
        if i < 10:
            out += al.add("b", i * 10_000_000, 0, arr, np.zeros(3), np.ones(3), emit=False)
        out += al.ready(now_ns=arr)
    # frames 0-9 complete at once; later ones leave 40 ms after their first sample: up to frame 29 - 4
    assert sum(b.n for b in out) == 26
    assert al.counters()["b"]["gaps"] == 16
    # a packet of b still in flight for frame 12 is late: counted, not used
    assert al.add("b", 12 * 10_000_000, 0, t0 + 10**9, np.zeros(3), np.ones(3)) == []
    assert al.counters()["b"]["late"] == 1
    # a sensor that sends in bursts is not lost: b's samples of frames 30-32 arrive together, 35 ms after a's first
    for i in range(30, 33):
        out += al.add("a", i * 10_000_000, 0, t0 + i * 10_000_000, np.zeros(3), np.ones(3), emit=False)
    burst = al.ready(now_ns=t0 + 330_000_000)
    for i in range(30, 33):
        al.add("b", i * 10_000_000, 0, t0 + 335_000_000, np.zeros(3), np.ones(3), emit=False)
    burst += al.ready(now_ns=t0 + 335_000_000)
    late_frames = np.concatenate([b.valid["b"][b.k0 + np.arange(b.n) >= 30] for b in burst])
    assert late_frames.all() and len(late_frames) == 3


def test_inline_and_queued_sessions_publish_the_same(lab_streams, lab_calibration):
    """The source's thread computing (default) and a queue to run()'s thread: same frames, events, metrics."""
    from stridelab.pipeline.live.session import LiveSession
    from stridelab.pipeline.live.sources import ReplaySource
    pl = [p for p in LEG_PLACEMENTS if p in lab_streams.sensors]
    res = {}
    for inline in (True, False):
        s = LiveSession(ReplaySource(lab_streams, pl, speed=None), pl, sampling_rate_hz=lab_streams.sampling_rate_hz,
                        calibration=lab_calibration, inline=inline)
        summary = s.run()
        res[inline] = (summary["frames"], summary["metrics"], [(e["side"], e["type"], e["k"]) for e in s.hub.events],
                       [f[3] for f in s.hub.frames])
    assert res[True][0] == res[False][0] == min(len(lab_streams.sensors[p].t_ns) for p in pl)
    assert res[True][1] == res[False][1] and res[True][2] == res[False][2] and res[True][3] == res[False][3]
    assert len(res[True][2]) > 10


def test_stride_times_and_asymmetry_by_hand():
    """Hand-computed strides: left IC 100 -> 220 (TC 170, right IC 160 between), right IC 160 -> 290 (TC 240,
    left IC 220 between), 100 Hz."""
    eng = LiveEngine(["foot_left", "foot_right"], sampling_rate_hz=100.0)
    ev = [("left", "IC", 100), ("right", "TC", 120), ("right", "IC", 160), ("left", "TC", 170),
          ("left", "IC", 220), ("right", "TC", 240), ("right", "IC", 290)]
    strides = eng._strides_from([{"side": s, "type": t, "k": k, "k_detect": k + 1} for s, t, k in ev])
    left, right = strides
    assert (left["side"], left["stride_time_s"], left["stance_time_s"], left["step_time_s"]) == ("left", 1.2, 0.7, 0.6)
    assert (right["side"], right["stride_time_s"], right["stance_time_s"], right["step_time_s"]) == \
        ("right", 1.3, 0.8, 0.7)
    m = eng.metrics
    assert m["step_time_asymmetry_pct"] == pytest.approx(100 * (0.7 / 0.6 - 1))
    assert m["stance_asymmetry_pct"] == pytest.approx(100 * ((0.8 / 1.3) / (0.7 / 1.2) - 1))
