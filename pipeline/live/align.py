"""Samples of several sensors, each on its own clock, onto one frame grid; gaps counted, never filled.

A sample's frame index is ``k = k0_p + round((t_p - t0_p) / T)`` with ``T = 1 / sampling_rate_hz``, ``t0_p`` the
sensor's first stamp and ``k0_p`` where that first sample falls on the session grid:

* ``clock="shared"``: the sensors stamp with one clock (one acquisition system, x-io NGIMUs synchronised by
  their ``/time`` messages, a replayed recording): ``k0_p = round((t0_p - t0) / T)``, ``t0`` the first stamp
  of the session.
* ``clock="host"``: independent sensor clocks; ``k0_p = round((h0_p - h0) / T)`` from the host receive times
  ``h`` of each sensor's first sample (one transfer latency of error, under one sample on a LAN). The
  sensor's own stamps then place its later samples, so network jitter does not move them; clock *drift*
  between sensors (tens of ppm, about one sample per 10 minutes at 100 Hz) is not corrected.

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
                 max_wait_frames: int = 100, ring: int = 1024):
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

    def counters(self) -> dict:
        return {p: {"received": int(self.received[i]), "gaps": int(self.gaps[i]), "late": int(self.late[i]),
                    "duplicate": int(self.duplicate[i])} for p, i in self._ix.items()}

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
        k = self._k0[i] + int(round((t_ns - self._t0[i]) / self.period_ns))
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
