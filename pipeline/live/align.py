"""Samples of several sensors, each on its own clock, onto one frame grid; gaps counted, never filled.

A sample's frame index is ``k = k0_p + round((t_p - t0_p) / T)`` with ``T = 1 / sampling_rate_hz``, ``t0_p`` the
sensor's first stamp and ``k0_p`` where that first sample falls on the session grid:

* ``clock="shared"``: the sensors stamp with one clock (one acquisition system, x-io NGIMUs synchronised by
  their ``/time`` messages, a replayed recording): ``k0_p = round((t0_p - t0) / T)``, ``t0`` the first stamp
  of the session.
* ``clock="host"``: independent sensor clocks; ``k0_p = round((h0_p - h0) / T)`` from the host receive times
  ``h`` of each sensor's first sample (one transfer latency of error, under one sample on a LAN). The
  sensor's own stamps then place its later samples, so network jitter does not move them, and clock *drift*
  (a device crystal off by tens of ppm: one sample per few minutes at 100 Hz) is corrected by
  :class:`ClockDrift`: the rate of the sensor clock against the host clock is the slope of the lower envelope
  of ``h − t`` (the per-second minima: the samples that met the least transfer delay) over a sliding window,
  fitted by Theil–Sen (the median of pairwise slopes: robust to a second of late Wi-Fi packets); elapsed sensor
  time is scaled by that rate, piecewise from one refit to the next, so a new estimate never makes a sample jump.

Frame ``k`` is handed on once every sensor has delivered a sample at or after ``k``, or ``max_wait_ms`` of
wall time after the first of its samples arrived, or once any sensor is ``max_wait_frames`` beyond it (a
backlog bound): a sensor that stalls must not stop the others, and a network that delivers one sensor's
packets in bursts (Wi-Fi) must not make its samples "lost" when they are only late by a few milliseconds.
A sensor that has nothing at ``k`` then counts a lost sample at ``k`` (``gaps``): its row is NaN and
``valid`` False; the estimators see the loss, nothing is interpolated. A sample arriving after its frame was handed on is
counted ``late`` and not used; a repeated index is counted ``duplicate``.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np


class ClockDrift:
    """Rate of one sensor's clock against the host clock, from (sensor stamp, host receive time) pairs.

    Buckets of ``bucket_s`` of sensor time keep the minimum of ``h − t`` (the lower envelope: transfer delay is
    never negative, and its minimum is the most stable part of it); over the last ``window_s`` of buckets the
    slope of that envelope against ``t`` is the Theil–Sen estimate (median of the pairwise slopes; Sen 1968), refit
    as each bucket closes once ``min_buckets`` exist. ``elapsed_ns(t)``: host-clock ns since the sensor's first
    stamp, ``(t − t_a)(1 + rate) + e_a`` with ``(t_a, e_a)`` moved to each refit (continuous: no jumps).
    ``rate_ppm``: the current estimate (positive = the host clock runs faster than the sensor's)."""

    def __init__(self, *, window_s: float = 60.0, bucket_s: float = 1.0, min_buckets: int = 3,
                 max_rate_ppm: float = 5000.0):
        self.max_rate = max_rate_ppm * 1e-6
        self.implausible = False              # a rate beyond max_rate_ppm: not a clock (a replay faster than real)
        self.window = max(2, int(round(window_s / bucket_s)))
        self.bucket_ns = int(bucket_s * 1e9)
        self.min_buckets = int(min_buckets)
        self.t0 = None
        self.rate = 0.0
        self._ta, self._ea = 0, 0.0           # anchor: sensor ns since t0, elapsed host ns there
        self._centres: list[float] = []
        self._minima: list[float] = []
        self._cur, self._cur_min = None, None
        self._fitted = False

    @property
    def rate_ppm(self) -> float:
        return self.rate * 1e6

    def add(self, t_ns: int, host_ns: int) -> None:
        if self.t0 is None:
            self.t0 = int(t_ns)
        rel = int(t_ns) - self.t0
        b = rel // self.bucket_ns
        d = float(int(host_ns) - int(t_ns))
        if self._cur is None or b > self._cur:
            if self._cur is not None:
                self._centres.append((self._cur + 0.5) * self.bucket_ns)
                self._minima.append(self._cur_min)
                del self._centres[:-self.window], self._minima[:-self.window]
                self._refit(rel)
            self._cur, self._cur_min = b, d
        elif b == self._cur:
            self._cur_min = min(self._cur_min, d)

    def _refit(self, rel_now: int) -> None:
        if len(self._minima) < self.min_buckets:
            return
        c, m = np.asarray(self._centres), np.asarray(self._minima)
        i, j = np.triu_indices(len(c), 1)
        rate = float(np.median((m[j] - m[i]) / (c[j] - c[i])))
        if abs(rate) > self.max_rate or self.implausible:    # crystals are off by tens of ppm: a stream that
            self.implausible, rate = True, 0.0                 # once ran faster than real time is no device clock
        if not self._fitted:       # the first estimate applies from the first sample (what accrued before it
            self._fitted = True    # is a few ms at most: one sample may repeat or be skipped, counted as such)
        else:                      # later ones from now on: continuous, so a new estimate never moves samples
            self._ea = self.elapsed_ns(self.t0 + rel_now)
            self._ta = rel_now
        self.rate = rate

    def elapsed_ns(self, t_ns: int) -> float:
        if self.t0 is None:
            return 0.0
        return self._ea + (int(t_ns) - self.t0 - self._ta) * (1.0 + self.rate)


@dataclass
class FrameBatch:
    """Consecutive frames ``k0 .. k0 + n - 1``. Per placement: gyr, acc, mag (n, 3) (NaN where lost; mag NaN
    when the sensor has none) and valid (n,) bool. ``arrival_ns`` (n,): monotonic time the frame became
    complete (the newest arrival among its samples); ``t_ns`` (n,): session time of each frame."""
    k0: int
    n: int
    t_ns: np.ndarray
    arrival_ns: np.ndarray
    gyr: dict[str, np.ndarray]
    acc: dict[str, np.ndarray]
    mag: dict[str, np.ndarray]
    valid: dict[str, np.ndarray]
    has_mag: dict[str, bool] = field(default_factory=dict)


class FrameAligner:
    """Collect samples of ``placements`` into :class:`FrameBatch` es (see the module docstring)."""

    def __init__(self, placements, *, sampling_rate_hz: float, clock: str = "shared", max_wait_ms: float = 40.0,
                 max_wait_frames: int = 100, ring: int = 1024, drift_correction: bool = True,
                 drift_window_s: float = 60.0):
        if clock not in ("shared", "host"):
            raise ValueError(f"clock must be 'shared' or 'host', got {clock!r}")
        if not sampling_rate_hz > 0:
            raise ValueError(f"sampling_rate_hz must be > 0, got {sampling_rate_hz}")
        self.placements = tuple(placements)
        self.period_ns = 1e9 / sampling_rate_hz
        self.clock = clock
        self.max_wait = int(max_wait_frames)
        self.max_wait_ns = int(max_wait_ms * 1e6)
        self.W = int(ring)
        P = len(self.placements)
        self._ix = {p: i for i, p in enumerate(self.placements)}
        self._data = np.full((P, self.W, 9), np.nan)
        self._have = np.zeros((P, self.W), dtype=bool)
        self._arr = np.zeros((P, self.W), dtype=np.int64)
        self._first = np.zeros(self.W, dtype=np.int64)      # arrival of the first sample of each frame (0: none)
        self._t0 = [None] * P                   # first stamp of each sensor
        self._k0 = [0] * P
        self._newest = np.full(P, -1, dtype=np.int64)   # highest frame index received per sensor
        self._has_mag = [False] * P
        self._origin_t = None                   # session t0 (shared clock) / first host time
        self._origin_h = None
        self.next_k = 0
        self.gaps = np.zeros(P, dtype=np.int64)
        self.late = np.zeros(P, dtype=np.int64)
        self.duplicate = np.zeros(P, dtype=np.int64)
        self.received = np.zeros(P, dtype=np.int64)
        self.t0_ns = None                       # session time of frame 0
        # host clock: each sensor's rate against the host clock (None: stamps taken at face value)
        self.drift = [ClockDrift(window_s=drift_window_s) if clock == "host" and drift_correction else None
                      for _ in range(P)]

    def counters(self) -> dict:
        return {p: {"received": int(self.received[i]), "gaps": int(self.gaps[i]), "late": int(self.late[i]),
                    "duplicate": int(self.duplicate[i]),
                    **({"drift_ppm": round(self.drift[i].rate_ppm, 1)} if self.drift[i] is not None else {})}
                for p, i in self._ix.items()}

    def add(self, placement: str, t_ns: int, host_ns: int, arrival_ns: int, gyr, acc, mag=None, *,
            emit: bool = True) -> list[FrameBatch]:
        """Add one sample; returns the batches it completed (often none, or one). ``emit=False`` only stores it
        (call :meth:`ready` after a burst: one batch for the burst instead of one per frame)."""
        i = self._ix.get(placement)
        if i is None:
            return []
        if self._t0[i] is None:
            if self._origin_t is None:
                self._origin_t, self._origin_h = int(t_ns), int(host_ns)
                self.t0_ns = int(t_ns)
            self._t0[i] = int(t_ns)
            ref = (t_ns - self._origin_t) if self.clock == "shared" else (host_ns - self._origin_h)
            self._k0[i] = int(round(ref / self.period_ns))
        dr = self.drift[i]
        if dr is None:
            k = self._k0[i] + int(round((t_ns - self._t0[i]) / self.period_ns))
        else:
            dr.add(t_ns, host_ns)
            k = self._k0[i] + int(round(dr.elapsed_ns(t_ns) / self.period_ns))
        self.received[i] += 1
        if k < self.next_k:
            self.late[i] += 1
            return []
        out = []
        if k >= self.next_k + self.W:               # would overwrite the ring: hand on what is older first
            out += self._emit_upto(k - self.W)
        j = k % self.W
        if self._have[i, j]:
            self.duplicate[i] += 1
            return out
        d = self._data[i, j]
        d[0:3] = gyr
        d[3:6] = acc
        if mag is not None:
            d[6:9] = mag
            self._has_mag[i] = True
        self._have[i, j] = True
        self._arr[i, j] = arrival_ns
        if self._first[j] == 0:
            self._first[j] = max(int(arrival_ns), 1)
        if k > self._newest[i]:
            self._newest[i] = k
        if emit:
            out += self.ready()
        return out

    def ready(self, now_ns: int | None = None) -> list[FrameBatch]:
        """Hand on the frames that are complete or waited long enough (``now_ns``: monotonic now, default
        ``time.perf_counter_ns()``, the clock of ``arrival_ns``)."""
        newest = int(self._newest.max())
        if newest < 0:
            return []
        # every sensor (started or not) holds the frames it has not reached: at most max_wait_frames ...
        upto = max(int(self._newest.min()), newest - self.max_wait)
        # ... and at most max_wait_ms after the frame's first sample arrived
        now = time.perf_counter_ns() if now_ns is None else int(now_ns)
        k = max(upto + 1, self.next_k)
        while k <= newest:
            f = self._first[k % self.W]
            if f == 0 or now - f < self.max_wait_ns:
                break
            k += 1
        return self._emit_upto(max(upto, k - 1))

    def flush(self) -> list[FrameBatch]:
        """Hand on every frame up to the newest received (end of stream)."""
        if (self._newest < 0).all():
            return []
        return self._emit_upto(int(self._newest.max()))

    def _emit_upto(self, upto: int) -> list[FrameBatch]:
        a = self.next_k
        if upto < a:
            return []
        ks = np.arange(a, upto + 1)
        j = ks % self.W
        n = len(ks)
        gyr, acc, mag, valid, hm = {}, {}, {}, {}, {}
        arrival = np.zeros(n, dtype=np.int64)
        for p, i in self._ix.items():
            v = self._have[i, j].copy()
            d = self._data[i, j].copy()
            d[~v] = np.nan
            gyr[p], acc[p], mag[p] = d[:, 0:3], d[:, 3:6], d[:, 6:9]
            valid[p] = v
            hm[p] = self._has_mag[i]
            if self._t0[i] is not None:         # losses are counted once a sensor has started
                self.gaps[i] += int((~v[ks >= self._k0[i]]).sum())
            arrival = np.maximum(arrival, np.where(v, self._arr[i, j], 0))
            self._have[i, j] = False
            self._data[i, j] = np.nan
        self._first[j] = 0
        self.next_k = upto + 1
        t = self.t0_ns + np.rint(ks * self.period_ns).astype(np.int64)
        return [FrameBatch(a, n, t, arrival, gyr, acc, mag, valid, hm)]
