"""A live session: source -> frame aligner -> engine -> (published to the page, recorded to MCAP).

Threads: the source's thread, which (``inline``, the default) aligns, computes and publishes its samples as they
arrive (no hand-over to another thread whose wake-up would add to every latency); the recorder thread (the MCAP
chunks, off the latency path); the web server (:mod:`stridelab.pipeline.live.server`); ``run`` waits. With
``inline=False`` samples go through a bounded queue (``queue_s`` of samples) to ``run``'s thread, and what does
not fit is counted as dropped by the source.
"""
from __future__ import annotations

import gc
import queue
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from stridelab.pipeline.live.align import FrameAligner
from stridelab.pipeline.live.engine import LiveEngine, LiveParams, LiveOutput

#: what a display frame carries per joint: the sagittal (FE) angle
DISPLAY_JOINTS = ("hip_left", "hip_right", "knee_left", "knee_right", "ankle_left", "ankle_right")


def calibration_rows(cal) -> list[dict]:
    """The session calibration as the calibration stage's catalog rows (what
    ``stridelab.pipeline.stages.joint_angles.session_calibration`` rebuilds it from): the recording carries the calibration
    the live angles were computed with, so the nightly compares like with like."""
    import dataclasses
    import json
    rows = []
    for p, c in sorted(cal.imus.items() if cal is not None else ()):
        q = c.quat_sensor_af if c.valid else np.full(4, np.nan)
        rows.append({"placement": p, **{f"q{k}": (float(v) if np.isfinite(v) else None) for k, v in zip("wxyz", q)},
                     "method": c.method, "status": c.status, "reasons": json.dumps(list(c.reasons)),
                     "n_reps": int(c.n_cycles), "params": json.dumps(dataclasses.asdict(cal.params), default=list),
                     "session_status": cal.status, "session_reasons": json.dumps(list(cal.reasons))})
    return {"rows": rows}


class LatencyStats:
    """Latency histogram with fixed memory (10 µs bins up to 1 s, beyond counted in the last bin) and the max."""

    def __init__(self):
        self.bins = np.zeros(100_001, dtype=np.int64)
        self.max_ns = 0
        self.n = 0

    def add(self, lat_ns: np.ndarray) -> None:
        lat_ns = np.asarray(lat_ns, np.int64)
        if not len(lat_ns):
            return
        np.add.at(self.bins, np.minimum(lat_ns // 10_000, len(self.bins) - 1).clip(0), 1)
        self.max_ns = max(self.max_ns, int(lat_ns.max()))
        self.n += len(lat_ns)

    def quantile_ms(self, q: float) -> float:
        if self.n == 0:
            return float("nan")
        c = np.cumsum(self.bins)
        i = int(np.searchsorted(c, q * self.n))
        return (i + 1) * 0.01            # upper edge of the bin, ms

    def summary(self) -> dict:
        return {"n": self.n, "p50_ms": self.quantile_ms(0.5), "p99_ms": self.quantile_ms(0.99),
                "max_ms": self.max_ns / 1e6}


@dataclass
class Hub:
    """What the page sees: recent display frames (bounded), events, strides, metrics, counters."""
    keep_frames: int = 3000
    frames: deque = field(default_factory=deque)
    events: deque = field(default_factory=lambda: deque(maxlen=200))
    strides: deque = field(default_factory=lambda: deque(maxlen=40))
    state: dict = field(default_factory=dict)
    seq: int = 0
    eid: int = 0                      # events published so far (each event's ``eid``)
    lock: threading.Lock = field(default_factory=threading.Lock)
    #: called (from the computing thread) right after new events were published: the server sends them at once
    listeners: list = field(default_factory=list)

    def publish(self, out: LiveOutput) -> None:
        rows = np.full((out.n, len(DISPLAY_JOINTS)), np.nan)
        for j, key in enumerate(DISPLAY_JOINTS):
            if key in out.angles:
                rows[:, j] = out.angles[key][:, 0]
        rows = np.round(rows, 2)
        t = (out.t_ns // 1_000_000).tolist()
        with self.lock:
            for i in range(out.n):
                self.frames.append((self.seq, out.k0 + i, t[i], rows[i].tolist(), bool(out.offset_ready[i])))
                self.seq += 1
            while len(self.frames) > self.keep_frames:
                self.frames.popleft()
            for e in out.events:
                self.eid += 1
                self.events.append({**e, "seq": self.seq, "eid": self.eid})
            for s in out.strides:
                self.strides.append(s)
            if out.metrics:
                self.state["metrics"] = out.metrics
        if out.events:
            for cb in self.listeners:
                cb()

    def since(self, seq: int, limit: int = 400) -> tuple[list, list, dict]:
        with self.lock:
            fr = [f for f in self.frames if f[0] >= seq][-limit:]
            ev = [e for e in self.events if e["seq"] > seq]
            return fr, ev, dict(self.state)

    def events_after(self, eid: int) -> list:
        with self.lock:
            return [e for e in self.events if e["eid"] > eid]


class LiveSession:
    """Run one session: ``source`` (see :mod:`stridelab.pipeline.live.sources`), ``placements`` computed, optional
    ``recorder`` (:class:`stridelab.pipeline.live.recorder.McapRecorder`)."""

    def __init__(self, source, placements, *, sampling_rate_hz: float, calibration=None,
                 params: LiveParams = LiveParams(), recorder=None, clock: str = "shared", queue_s: float = 10.0,
                 max_wait_ms: float = 40.0, inline: bool = True, speed_estimate: bool = False):
        self.source = source
        self.placements = tuple(placements)
        self.fs = float(sampling_rate_hz)
        self.engine = LiveEngine(self.placements, sampling_rate_hz=self.fs, calibration=calibration, params=params)
        self.aligner = FrameAligner(self.placements, sampling_rate_hz=self.fs, clock=clock,
                                    max_wait_ms=max_wait_ms)
        self.hub = Hub()
        self.recorder = recorder
        self.latency = LatencyStats()
        self.event_latency = LatencyStats()
        self.compute = LatencyStats()          # wall time of engine + publish per batch (what the code costs)
        self.frames_done = 0
        self.samples_in = 0
        self._cap = int(queue_s * self.fs * max(1, len(self.placements)))
        self._q: queue.Queue = queue.Queue()
        self._queued = 0
        self._qlock = threading.Lock()
        self._rec_q: queue.Queue = queue.Queue(maxsize=32)
        self._arrivals = np.zeros(256, dtype=np.int64)      # frame arrival times, for event latencies
        self._stop = threading.Event()
        self.inline = inline
        self._proc_lock = threading.Lock()
        self.cpu_s = 0.0
        self.wall_s = 0.0
        self.speed = None           # walking speed for the speed-matched bands (stridelab.pipeline.live.speed)
        sides = [sd for sd in ("left", "right") if f"foot_{sd}" in self.placements]
        if speed_estimate and sides:
            from stridelab.pipeline.live.speed import LiveSpeed
            self.speed = LiveSpeed(sides, sampling_rate_hz=self.fs, on_update=self._speed_update)
        self._warm_up(calibration, params)
        self.hub.state.update({"placements": list(self.placements), "sampling_rate_hz": self.fs,
                               "calibration": None if calibration is None else calibration.status})

    def _speed_update(self, speed: dict) -> None:
        with self.hub.lock:
            self.hub.state["speed"] = speed

    def _warm_up(self, calibration, params) -> None:
        """Run a throwaway engine over two seconds of rest so every compiled kernel is loaded before the
        first real sample (the first call of a numba kernel loads it from the cache: ~1 s, a backlog otherwise)."""
        n = int(2 * self.fs)
        eng = LiveEngine(self.placements, sampling_rate_hz=self.fs, calibration=calibration, params=params)
        al = FrameAligner(self.placements, sampling_rate_hz=self.fs)
        g, a, m = np.zeros(3), np.array([0.0, 0.0, 9.81]), np.array([20.0, 0.0, -40.0])
        for i in range(n):
            for p in self.placements:
                for b in al.add(p, i * 10_000_000, 0, 0, g, a, m):
                    eng.process(b)
        LatencyStats().add(np.array([1]))

    # the source's sink: never blocks
    def sink(self, samples: list) -> bool:
        """Inline (default): the source's thread computes the samples at once (no hand-over to another thread,
        whose wake-up would add to every latency). Otherwise queued for ``run``; False when the queue is full."""
        if self.inline:
            c0 = time.thread_time()
            with self._proc_lock:
                self._ingest([samples])
            self.cpu_s += time.thread_time() - c0
            return True
        with self._qlock:
            if self._queued + len(samples) > self._cap:
                return False
            self._queued += len(samples)
        self._q.put(samples)
        return True

    def stop(self) -> None:
        self._stop.set()
        self.source.stop()

    def run(self, *, until=None) -> dict:
        """Process until the source ends (or ``stop()``, or ``until()`` is true); returns :meth:`summary`."""
        # a thread waiting for the GIL (the engine, when a sample arrives) gets it within 1 ms instead of 5 ms
        switch = sys.getswitchinterval()
        sys.setswitchinterval(0.001)
        rec_thread = None
        if self.recorder is not None:
            rec_thread = threading.Thread(target=self._record_loop, name="live-recorder", daemon=True)
            rec_thread.start()
        # the cyclic garbage collector's full collections walk every object of the process (numba, pyarrow,
        # tornado: about a million) and stop every thread meanwhile: measured up to 405 ms on the bench, the
        # whole of the worst event latency. Everything alive now (imports, compiled kernels, the warm-up) is
        # moved out of its reach (gc.freeze); collections then see only what the session allocates
        if self.speed is not None:
            self.speed.start()
        gc.collect()
        gc.freeze()
        t_cpu, t_wall = time.thread_time(), time.perf_counter()
        self.source.start(self.sink)
        try:
            while self.inline and not self._stop.is_set():
                if self.source.done.wait(0.05) or (until is not None and until()):
                    break
            while not self.inline and not self._stop.is_set():
                try:
                    samples = self._q.get(timeout=0.05)
                except queue.Empty:
                    if self.source.done.is_set() and self._q.empty():
                        break
                    if until is not None and until():
                        break
                    continue
                burst = [samples]
                while len(burst) < 200:           # a backlog is taken in one go: one batch, not one per frame
                    try:
                        burst.append(self._q.get_nowait())
                    except queue.Empty:
                        break
                with self._qlock:
                    self._queued -= sum(len(x) for x in burst)
                self._ingest(burst)
            self.source.join(10)
            with self._proc_lock:
                for b in self.aligner.flush():
                    self._process(b)
        finally:
            if self.speed is not None:
                self.speed.close()
            gc.unfreeze()
            sys.setswitchinterval(switch)
            self.source.stop()
            self.cpu_s += time.thread_time() - t_cpu
            self.wall_s = time.perf_counter() - t_wall
            if rec_thread is not None:
                self._rec_q.put(None)
                rec_thread.join()
        return self.summary()

    def _ingest(self, burst: list) -> None:
        """Samples (lists of them) into the aligner, then the frames they completed through the engine."""
        self.samples_in += sum(len(x) for x in burst)
        add = self.aligner.add
        for samples in burst:
            for (p, t, h, arr, g, a, m) in samples:
                for b in add(p, t, h, arr, g, a, m, emit=False):
                    self._process(b)
        for b in self.aligner.ready():
            self._process(b)

    def _process(self, b) -> None:
        t0 = time.perf_counter_ns()
        out = self.engine.process(b)
        arr = b.arrival_ns
        ks = np.arange(b.k0, b.k0 + b.n)
        self._arrivals[ks % len(self._arrivals)] = arr
        for e in out.events:       # (an event further back than the ring, in a long backlog batch, is not timed)
            a0 = self._arrivals[e["k"] % len(self._arrivals)] if b.k0 + b.n - e["k"] < len(self._arrivals) else 0
            e["arrival_ns"] = int(a0)          # when the event's sample arrived (perf_counter ns; 0: unknown)
        self.hub.publish(out)                  # events go to the pages now (Hub.listeners), frames at the next tick
        if self.speed is not None:
            for side in self.speed.rings:
                p = f"foot_{side}"
                self.speed.add(side, b.gyr[p], b.acc[p])
            for st in out.strides:
                self.speed.stride_done(st["side"])
        now = time.perf_counter_ns()
        self.compute.add(np.array([now - t0]))
        ok = arr > 0
        self.latency.add(now - arr[ok])
        for e in out.events:
            if e["arrival_ns"] > 0:
                self.event_latency.add(np.array([now - e["arrival_ns"]]))
        self.frames_done += b.n
        if self.recorder is not None:
            self._rec_q.put((b, out))

    def _record_loop(self) -> None:
        first, standing_done = True, False
        while True:
            item = self._rec_q.get()
            if item is None:
                return
            b, out = item
            if first:              # what the live computation ran with: calibration rows and filter settings
                prm = self.engine.params
                self.recorder.add_json("/live/calibration", int(b.t_ns[0]), {
                    **calibration_rows(self.engine.calibration), "estimator": prm.estimator,
                    "use_magnetometer": prm.use_magnetometer, "sampling_rate_hz": self.fs})
            first = False
            if not standing_done and out.offset_ready.any():
                eng = self.engine          # the offsets never change once found (engine state read, not frames)
                self.recorder.add_json("/live/standing", int(b.t_ns[0]), {
                    "offset_frame": int(eng.offset_frame), "standing": list(eng.standing),
                    "offset_deg": {k: np.where(np.isfinite(v), v, None).tolist() for k, v in eng.offset.items()}})
                standing_done = True
            host = b.t_ns      # log time: the frame's session time (host clock of the replay / device stamps)
            for p in self.placements:
                v = b.valid[p]
                if v.any():
                    self.recorder.add_imu(p, b.t_ns[v], host[v], b.gyr[p][v], b.acc[p][v],
                                          b.mag[p][v] if b.has_mag.get(p) else None)
            if out.angles:
                self.recorder.add_json("/live/joint_angles", int(b.t_ns[0]), {
                    "k0": out.k0, "t_ns": b.t_ns.tolist(),
                    "angles_deg": {k: np.where(np.isfinite(v), np.round(v, 6), None).tolist()
                                   for k, v in out.angles.items()},
                    "offset_ready": out.offset_ready.tolist()})
            for e in out.events:
                self.recorder.add_json("/live/events", int(e["t_ns"]), e)

    def summary(self) -> dict:
        c = self.aligner.counters()
        return {"frames": self.frames_done, "samples_in": self.samples_in,
                "samples_dropped": int(getattr(self.source, "dropped", 0)),
                "gaps": {p: v["gaps"] for p, v in c.items()}, "late": {p: v["late"] for p, v in c.items()},
                **({"clock_drift_ppm": {p: v["drift_ppm"] for p, v in c.items()}}
                   if any("drift_ppm" in v for v in c.values()) else {}),
                "latency": self.latency.summary(), "event_latency": self.event_latency.summary(),
                "compute_per_batch": self.compute.summary(),
                "engine_cpu_s": self.cpu_s, "wall_s": self.wall_s,
                "standing": self.engine.standing, "metrics": self.engine.metrics,
                **({"walking_speed": {**self.speed.current(), "worker_cpu_s": round(self.speed.worker_cpu_s, 3),
                                      "skipped": self.speed.skipped}} if self.speed is not None else {})}
