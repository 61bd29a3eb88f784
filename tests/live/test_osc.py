"""x-io NGIMU OSC: packets parsed as the OSC 1.0 spec lays them out; a session fed over loopback UDP."""
from __future__ import annotations

import socket
import struct
import threading
import time

import numpy as np
import pytest

from stridelab.pipeline.live.osc import (OscError, ngimu_samples, ngimu_sensors_bundle, ns_to_timetag, parse_packet,
                               timetag_to_ns)


def test_sensors_message_bytes_as_the_osc_spec_lays_them_out():
    """A /sensors bundle built by hand (big-endian, 4-byte padding, NTP time tag): units converted."""
    args = [90.0, 0.0, -180.0, 0.0, 0.0, 1.0, 20.0, -5.0, 40.0, 1013.0]
    msg = b"/sensors\0\0\0\0" + b",ffffffffff\0" + b"".join(struct.pack(">f", a) for a in args)
    tt = ((3_980_000_000) << 32) | (1 << 31)                  # .5 s
    pkt = b"#bundle\0" + struct.pack(">Q", tt) + struct.pack(">i", len(msg)) + msg
    [(stamp, gyr, acc, mag)] = ngimu_samples(pkt)
    assert stamp == (3_980_000_000 - 2_208_988_800) * 1_000_000_000 + 500_000_000
    np.testing.assert_allclose(gyr, np.deg2rad([90.0, 0.0, -180.0]))
    np.testing.assert_allclose(acc, [0.0, 0.0, 9.80665], rtol=1e-7)
    np.testing.assert_allclose(mag, [20.0, -5.0, 40.0])
    assert ngimu_sensors_bundle(stamp, gyr, acc, mag, 1013.0) == pkt


def test_nested_bundles_other_addresses_and_bad_packets():
    inner = ngimu_sensors_bundle(10**18, np.zeros(3), [0, 0, 9.80665], np.zeros(3))
    quat = b"/quaternion\0" + b",ffff\0\0\0" + struct.pack(">4f", 1, 0, 0, 0)
    outer = b"#bundle\0" + struct.pack(">Q", 1) + b"".join(struct.pack(">i", len(e)) + e for e in (quat, inner))
    msgs = parse_packet(outer)
    assert [m[1] for m in msgs] == ["/quaternion", "/sensors"]
    assert len(ngimu_samples(outer)) == 1
    with pytest.raises(OscError):
        ngimu_samples(b"/sensors\0\0\0\0,ff\0" + struct.pack(">2f", 1, 2))       # too few arguments
    with pytest.raises(OscError):
        parse_packet(b"#bundle\0" + struct.pack(">Q", 1) + struct.pack(">i", 999) + b"xx")
    assert abs(timetag_to_ns(ns_to_timetag(1_765_000_000_123_456_789)) - 1_765_000_000_123_456_789) <= 1


@pytest.mark.slow
def test_ngimus_streaming_over_loopback_udp_are_seen_live(lab_streams, lab_calibration):
    """Seven NGIMUs (one UDP port each, their own clocks) send the hemiparetic walk as /sensors bundles over
    127.0.0.1; two packets are lost on purpose and one is garbage. The session sees every sample, counts the
    losses, skips the garbage and finds the gait events."""
    from stridelab.pipeline.live.engine import LEG_PLACEMENTS
    from stridelab.pipeline.live.session import LiveSession
    from stridelab.pipeline.live.sources import NgimuUdpSource
    pl = [p for p in LEG_PLACEMENTS if p in lab_streams.sensors]
    src = NgimuUdpSource({p: 0 for p in pl}, host="127.0.0.1", timeout_s=3.0)
    ports = src.bound_ports
    # a generous wait: on a loaded test machine a thread can sleep tens of ms; lost is lost, not merely late
    session = LiveSession(src, pl, sampling_rate_hz=lab_streams.sampling_rate_hz, calibration=lab_calibration,
                          clock="host", max_wait_ms=250.0)
    result = {}
    th = threading.Thread(target=lambda: result.update(session.run()), daemon=True)
    th.start()
    n = min(len(lab_streams.sensors[p].t_ns) for p in pl)
    n = min(n, 1800)
    lost = {("foot_right", 900), ("pelvis", 1000)}
    offsets = {p: 1_000_000_000 * (i + 1) * 37 for i, p in enumerate(pl)}     # independent device clocks
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        t_wall = time.perf_counter()
        for i in range(n):
            for p in pl:
                if (p, i) in lost:
                    continue
                s = lab_streams.sensors[p]
                pkt = ngimu_sensors_bundle(int(s.t_ns[i] - s.t_ns[0]) + offsets[p], s.gyr[i], s.acc[i], s.mag[i])
                tx.sendto(pkt, ("127.0.0.1", ports[p]))
            if i == 50:
                tx.sendto(b"not osc at all", ("127.0.0.1", ports["pelvis"]))
            # about 5x real time, paced so the loopback buffers never overflow
            ahead = (i + 1) / 500.0 - (time.perf_counter() - t_wall)
            if ahead > 0:
                time.sleep(ahead)
    finally:
        tx.close()
    th.join(60)
    assert not th.is_alive(), "the session did not stop after the source went quiet"
    assert src.bad_packets == 1
    assert result["samples_in"] == n * len(pl) - len(lost)
    assert result["samples_dropped"] == 0
    assert result["gaps"]["foot_right"] == 1 and result["gaps"]["pelvis"] == 1
    assert sum(result["gaps"].values()) == 2 and sum(result["late"].values()) == 0
    assert result["frames"] == n
    ev = list(session.hub.events)
    assert sum(e["type"] == "IC" for e in ev) >= 6 and {e["side"] for e in ev} == {"left", "right"}


@pytest.mark.slow
def test_a_drifting_ngimu_clock_is_corrected_over_loopback_udp():
    """Two NGIMUs send the same samples at the same instants over 127.0.0.1 in real time; one device clock is
    exact, the other runs 2000 ppm fast (exaggerated: what 50 ppm does in 40 s of session it does here in 1 s).
    Taken at face value its stamps slide past the other's by a frame every 0.5 s; with the drift correction the
    two meet on the same frame once the rate is known (3 s), and the estimate is the simulated rate."""
    from stridelab.pipeline.live.align import FrameAligner
    from stridelab.pipeline.live.sources import NgimuUdpSource
    fs, n, drift = 100.0, 800, 2000e-6
    pl = ("pelvis", "foot_left")
    src = NgimuUdpSource({p: 0 for p in pl}, host="127.0.0.1", timeout_s=2.0)
    ports = src.bound_ports
    on = FrameAligner(pl, sampling_rate_hz=fs, clock="host", max_wait_ms=1e6, max_wait_frames=400)
    off = FrameAligner(pl, sampling_rate_hz=fs, clock="host", max_wait_ms=1e6, max_wait_frames=400,
                       drift_correction=False)
    frames = {"on": [], "off": []}

    def sink(samples):
        for name, al in (("on", on), ("off", off)):
            for s in samples:
                frames[name] += al.add(*s)
        return True

    src.start(sink)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        start_wall, start_host = time.perf_counter(), time.time_ns()
        for i in range(n):
            ahead = i / fs - (time.perf_counter() - start_wall)
            if ahead > 0:
                time.sleep(ahead)
            due = i * 1e9 / fs                           # when the sample is taken, host clock
            gyr = np.deg2rad([float(i), 0.0, 0.0])       # the sample carries its own index
            for p, stamp in (("pelvis", start_host + due), ("foot_left", 5_000_000_000 + due * (1 + drift))):
                tx.sendto(ngimu_sensors_bundle(int(stamp), gyr, [0.0, 0.0, 9.81], [20.0, 0.0, -40.0]),
                          ("127.0.0.1", ports[p]))
    finally:
        tx.close()
    src.join(30)
    assert src.done.is_set() and src.bad_packets == 0
    for name, al in (("on", on), ("off", off)):
        frames[name] += al.flush()

    def mismatch(batches, k_from):
        """Frames from k_from where both sensors have a sample: how many hold different samples."""
        bad = total = 0
        for b in batches:
            ks = np.arange(b.k0, b.k0 + b.n)
            both = b.valid["pelvis"] & b.valid["foot_left"] & (ks >= k_from)
            ia = np.rint(np.rad2deg(b.gyr["pelvis"][both, 0]))
            ib = np.rint(np.rad2deg(b.gyr["foot_left"][both, 0]))
            bad += int((ia != ib).sum())
            total += int(both.sum())
        return bad, total

    bad_on, total_on = mismatch(frames["on"], 400)
    bad_off, total_off = mismatch(frames["off"], 400)
    print(f"\nframes off: corrected {bad_on}/{total_on}, at face value {bad_off}/{total_off}; "
          f"estimate {on.counters()['foot_left']['drift_ppm']} ppm")
    assert total_on > 300 and total_off > 300
    assert bad_off > 0.9 * total_off                 # at face value: 8-16 ms apart in the last 4 s
    assert bad_on <= 0.02 * total_on, (bad_on, total_on)
    est = on.counters()["foot_left"]["drift_ppm"]
    assert abs(est - (-drift / (1 + drift)) * 1e6) < 200, est    # host runs slower than this device clock
    assert abs(on.counters()["pelvis"]["drift_ppm"]) < 200
