"""Where a live session's samples come from: a replayed recording or x-io NGIMUs over UDP (OSC).

A source runs in its own thread and hands lists of samples ``(placement, t_ns, host_ns, arrival_ns, gyr, acc,
mag)`` to ``sink``; ``sink`` returns False when the session's input queue is full, and the source counts those
samples as dropped (a device cannot be paused; neither is a replay at a fixed speed). ``arrival_ns`` is
``time.perf_counter_ns()`` when the packet was read (UDP) or the time it was due (replay at a fixed speed);
latency is measured from it.
"""
from __future__ import annotations

import socket
import threading
import time
from pathlib import Path

import numpy as np

from stridelab.pipeline.live.osc import OscError, ngimu_samples
from stridelab.pipeline.live.streams import Streams, read_streams


class _ThreadedSource:
    """What every source shares: ``_run(sink)`` runs in a daemon thread named ``thread_name``; ``stop`` asks it
    to end (``_stop``), ``join`` waits; ``done`` is set when it has ended."""
    thread_name = "live-source"

    def __init__(self):
        self.dropped = 0
        self.done = threading.Event()
        self._stop = threading.Event()
        self._thread = None

    def start(self, sink) -> None:
        self._thread = threading.Thread(target=self._run, args=(sink,), name=self.thread_name, daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()

    def join(self, timeout=None) -> None:
        if self._thread is not None:
            self._thread.join(timeout)

    def _run(self, sink) -> None:
        raise NotImplementedError


class ReplaySource(_ThreadedSource):
    """Replay a recording at ``speed`` × real time (``None`` = as fast as the session takes it: then the
    source waits for queue room instead of dropping). ``minutes``: loop the recording (stamps continuing)
    until that much recording time was replayed. Sensor stamps and host times are the file's."""
    thread_name = "live-replay"

    def __init__(self, streams: Streams | str | Path, placements, *, speed: float | None = 1.0,
                 minutes: float | None = None, frames_per_put: int | None = None):
        super().__init__()
        self.streams = streams if isinstance(streams, Streams) else read_streams(streams)
        self.placements = [p for p in placements if p in self.streams.sensors]
        if not self.placements:
            raise ValueError(f"the recording has none of the placements {list(placements)}")
        self.speed = speed
        self.minutes = minutes
        n = min(len(self.streams.sensors[p].t_ns) for p in self.placements)
        self.n = n
        self.fs = self.streams.sampling_rate_hz
        self.frames_per_put = frames_per_put or (1 if speed is not None else 20)
        self.sent = 0
        from stridelab.pipeline.live.session import LatencyStats
        self.wake_late = LatencyStats()     # how late this thread woke for a due frame: the scheduler's share

    def _run(self, sink) -> None:
        try:
            S = self.streams.sensors
            pl = self.placements
            span = int(S[pl[0]].t_ns[self.n - 1] - S[pl[0]].t_ns[0]) + int(round(1e9 / self.fs))
            total = self.n if not self.minutes else int(round(self.minutes * 60 * self.fs))
            t0 = int(S[pl[0]].t_ns[0])
            wall0 = time.perf_counter_ns()
            i = 0

            def due(f):             # when frame f is due (the device would deliver it), perf_counter ns
                j, lap = f % self.n, f // self.n
                return wall0 + (int(S[pl[0]].t_ns[j]) + lap * span - t0) / self.speed

            while i < total and not self._stop.is_set():
                if self.speed is None:
                    m = min(self.frames_per_put, total - i)
                    now = time.perf_counter_ns()
                    arrivals = [now] * m
                else:
                    wait = (due(i) - time.perf_counter_ns()) / 1e9
                    if wait > 0:
                        time.sleep(wait)
                    # every frame due by now goes at once (a late wake-up of this thread, like one of a
                    # receiving thread, releases what queued meanwhile); each "arrived" when it was due, so the
                    # wake-up delay counts in the latency
                    now = time.perf_counter_ns()
                    self.wake_late.add(np.array([max(0, now - int(due(i)))]))
                    m = 1
                    while i + m < total and m < 200 and due(i + m) <= now:
                        m += 1
                    arrivals = [int(due(f)) for f in range(i, i + m)]
                batch = []
                for f, arrival in zip(range(i, i + m), arrivals):
                    j, lap = f % self.n, f // self.n
                    off = lap * span
                    for p in pl:
                        s = S[p]
                        batch.append((p, int(s.t_ns[j]) + off, int(s.log_ns[j]) + off, arrival, s.gyr[j], s.acc[j],
                                      None if s.mag is None else s.mag[j]))
                if self.speed is None:
                    while not sink(batch):
                        if self._stop.is_set():
                            return
                        time.sleep(0.001)
                    self.sent += len(batch)
                elif sink(batch):
                    self.sent += len(batch)
                else:
                    self.dropped += len(batch)
                i += m
        finally:
            self.done.set()


class NgimuUdpSource(_ThreadedSource):
    """x-io NGIMUs sending OSC over UDP, one receive port per sensor (``ports``: placement -> port), bound to
    ``host`` (loopback by default; give the LAN address the NGIMUs send to). Each ``/sensors`` message is one
    sample, stamped with its bundle's time tag (the device clock; host receive time when it has none).
    Malformed packets are counted (``bad_packets``) and skipped."""
    thread_name = "live-osc"

    def __init__(self, ports: dict[str, int], *, host: str = "127.0.0.1", timeout_s: float | None = None):
        super().__init__()
        self.ports = dict(ports)
        self.host = host
        self.timeout_s = timeout_s          # stop after this long without any packet (None: never)
        self.bad_packets = 0
        self.received = 0
        self._socks = {}
        for p, port in self.ports.items():
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
            try:
                s.bind((host, int(port)))
            except OSError as e:
                self.close()
                raise ValueError(f"cannot listen on UDP {host}:{port} for {p}: {e.strerror}; choose another port") \
                    from None
            s.setblocking(False)
            self._socks[p] = s

    @property
    def bound_ports(self) -> dict[str, int]:
        return {p: s.getsockname()[1] for p, s in self._socks.items()}

    def close(self) -> None:
        for s in self._socks.values():
            s.close()

    def _run(self, sink) -> None:
        import selectors
        sel = selectors.DefaultSelector()
        for p, s in self._socks.items():
            sel.register(s, selectors.EVENT_READ, p)
        last = time.monotonic()
        try:
            while not self._stop.is_set():
                ready = sel.select(timeout=0.05)
                if not ready:
                    if self.timeout_s is not None and time.monotonic() - last > self.timeout_s:
                        return
                    continue
                last = time.monotonic()
                batch = []
                for key, _ in ready:
                    p = key.data
                    while True:
                        try:
                            data = key.fileobj.recv(65536)
                        except BlockingIOError:
                            break
                        arrival = time.perf_counter_ns()
                        host = time.time_ns()
                        try:
                            samples = ngimu_samples(data)
                        except (OscError, ValueError, IndexError, __import__("struct").error):
                            self.bad_packets += 1
                            continue
                        for stamp, g, a, m in samples:
                            batch.append((p, host if stamp is None else stamp, host, arrival, g, a, m))
                if batch:
                    self.received += len(batch)
                    if not sink(batch):
                        self.dropped += len(batch)
        finally:
            sel.close()
            self.close()
            self.done.set()
