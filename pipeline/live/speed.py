"""Walking speed during a live session, for the speed-matched normative bands of the therapist's page.

At each stride the live engine completes, the last ``window_s`` of that foot's samples go to the nightly's own
foot kinematics (``stridelab.estimators.gait.foot_kinematics``: ESKF with zero-velocity updates and RTS smoother, the gait
stage's stride speed) in a worker process; the speed of the last complete stride in the window joins the last
``n_strides`` estimates, whose median is the session's current speed. Only past samples are used (causal; the
estimate lags the stride by up to one stride). The worker is a separate process because the compiled kernels hold
the GIL: 20-30 ms per call in a thread would stall the computing thread. A window holding a lost sample is skipped.
"""
from __future__ import annotations

import threading
from collections import deque

import numpy as np


def last_stride_speed(gyr: np.ndarray, acc: np.ndarray, sampling_rate_hz: float) -> float:
    """Speed (m/s) of the last complete stride of a foot-IMU window by the gait stage's estimator; NaN if none."""
    from stridelab.estimators.gait import PARAM_COLUMNS, foot_kinematics
    fk = foot_kinematics(gyr, acc, sampling_rate_hz=sampling_rate_hz)
    v = fk.strides.values[:, list(PARAM_COLUMNS).index("gait_speed_m_s")] if len(fk.strides.values) else []
    v = np.asarray(v, float)
    v = v[np.isfinite(v)]
    return float(v[-1]) if len(v) else float("nan")


def _worker_call(gyr, acc, sampling_rate_hz):
    """(speed, CPU seconds the worker spent): the worker's CPU is not in the session process's own CPU time."""
    import time
    c0 = time.process_time()
    v = last_stride_speed(gyr, acc, sampling_rate_hz)
    return v, time.process_time() - c0


class LiveSpeed:
    """Per foot a ring of the last ``window_s`` of samples; :meth:`stride_done` asks the worker for the speed."""

    def __init__(self, sides, *, sampling_rate_hz: float, window_s: float = 6.0, n_strides: int = 10,
                 on_update=None):
        self.fs = float(sampling_rate_hz)
        self.n = int(round(window_s * self.fs))
        self.rings = {s: np.full((self.n, 6), np.nan) for s in sides}
        self.filled = {s: 0 for s in sides}
        self.speeds: deque = deque(maxlen=n_strides)
        self.on_update = on_update
        self.pending = 0
        self.skipped = 0
        self.worker_cpu_s = 0.0
        self._lock = threading.Lock()
        self._pool = None

    def start(self) -> None:
        """Start the worker and load its kernels (a first call) before the session's first sample."""
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor
        self._pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"))
        t = np.arange(int(3 * self.fs)) / self.fs
        acc = np.column_stack([np.zeros_like(t), np.zeros_like(t), np.full_like(t, 9.81)])
        self._pool.submit(last_stride_speed, np.zeros_like(acc), acc, self.fs).result(timeout=120)

    def add(self, side: str, gyr: np.ndarray, acc: np.ndarray) -> None:
        """Rows of one batch (NaN where lost)."""
        r = self.rings.get(side)
        if r is None:
            return
        m = min(len(gyr), self.n)
        r[:-m] = r[m:]
        r[-m:, :3], r[-m:, 3:] = gyr[-m:], acc[-m:]
        self.filled[side] = min(self.n, self.filled[side] + m)

    def stride_done(self, side: str) -> None:
        if self._pool is None or side not in self.rings or self.filled[side] < self.n:
            return
        r = self.rings[side]
        with self._lock:
            if self.pending >= 2 or not np.isfinite(r).all():     # a backlog, or a lost sample in the window
                self.skipped += 1
                return
            self.pending += 1
        fut = self._pool.submit(_worker_call, r[:, :3].copy(), r[:, 3:].copy(), self.fs)
        fut.add_done_callback(self._done)

    def _done(self, fut) -> None:
        with self._lock:
            self.pending -= 1
            try:
                v, cpu = fut.result()
            except Exception:          # noqa: BLE001 - a failed estimate is no estimate; the session goes on
                self.skipped += 1
                return
            self.worker_cpu_s += cpu
            if np.isfinite(v):
                self.speeds.append(v)
        if self.on_update is not None:
            self.on_update(self.current())

    def current(self) -> dict:
        with self._lock:
            v = list(self.speeds)
        return {"speed_m_s": round(float(np.median(v)), 3) if v else None, "n_strides": len(v),
                "source": "live: gait-stage foot kinematics on the last strides"}

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None
