"""The clock policy of ingest (docs/clocks.md): what a topic's time base is, each decision named in a warning.

Applied by :class:`stridelab.pipeline.ingest.series.TopicSeries` to every block (:class:`TopicClock`) and every slice
(:class:`Batching`); the series itself only orders, de-duplicates and writes. (Unset stamps take their log time in
the per-block checks, :mod:`stridelab.pipeline.ingest.block_checks`.)

Implausible stamps (docs/clocks.md "Implausible stamps"): never a silent 1970 or a 56-year gap.

Warehouse time is wall-clock UTC. A ``header.stamp`` before :data:`EARLIEST_NS` (2000-01-01) or after now + 1 day
is not wall-clock time: simulation time (seconds since the start, ``use_sim_time``), a device's time since power-on,
or a single bad value (a stamp of exactly 0 whose log time is not wall-clock either). Decided per topic on its first
block of messages, and applied to every later block:

- ``stamp`` (most stamps plausible): samples whose stamp is still implausible (after the unset-stamp rule gave
  them their log time) are dropped as outliers, counted in a warning;
- ``log_time`` (most stamps implausible, most log times plausible: mixed clock domains in the file): every
  sample of the topic takes its ``log_time`` (the recorder's wall clock), named in a warning;
- refused when neither clock is wall-clock time, or when more than half of a topic's samples are dropped.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

EARLIEST_NS = 946_684_800_000_000_000          # 2000-01-01T00:00:00Z (the importers' default start is this instant)
FUTURE_MARGIN_NS = 86_400 * 10**9              # now + 1 day
MOST = 0.5                                     # "most" stamps: more than half of the first block


def latest_ns() -> int:
    """The latest plausible stamp: the ingesting host's clock (not the file's) + 1 day (docs/clocks.md)."""
    return time.time_ns() + FUTURE_MARGIN_NS


def implausible(t: np.ndarray, latest: int) -> np.ndarray:
    return (t < EARLIEST_NS) | (t > latest)


@dataclass
class ClockDecision:
    mode: str                 # "stamp" | "log_time"
    reason: str = ""


def decide(t: np.ndarray, log: np.ndarray, latest: int) -> ClockDecision | str:
    """The topic's time base from its first block (``t``: stamps with unset ones already replaced by log time);
    a str is the refusal's reason."""
    bad_t = implausible(t, latest).mean() if len(t) else 0.0
    if bad_t <= MOST:
        return ClockDecision("stamp")
    bad_log = implausible(log, latest).mean() if len(log) else 1.0
    if bad_log <= MOST:
        return ClockDecision("log_time", "header.stamp is not wall-clock time (before 2000 or in the future: "
                                         "simulation or device time) while log_time is: log_time used for every "
                                         "sample")
    return ("no time base: neither header.stamp nor log_time is wall-clock time (both before 2000 or in the future: simulation "
            "time?); re-export with wall-clock stamps")


class NoTimeBase(ValueError):
    """A topic without a wall-clock time base; ``str(err)`` is the reason (the series names its topic)."""


class TopicClock:
    """The clock policy of one topic: the decision (:func:`decide`) taken on its first block and applied to every
    block, the samples dropped as outliers, the refusal and the warnings that say what was done."""

    def __init__(self):
        self.decision: ClockDecision | None = None
        self.n_dropped = 0                       # samples whose stamp is not wall-clock time, dropped as outliers
        self.latest = latest_ns()

    def apply(self, t: np.ndarray, log: np.ndarray, v: np.ndarray):
        """(t, log, v, changed) of one block under the topic's decision (``t``: stamps with unset ones already
        replaced by log time); ``changed``: rows were replaced or dropped (order flags must be recomputed).
        Raises :class:`NoTimeBase` when the first block has no wall-clock time base."""
        if self.decision is None:
            d = decide(t, log, self.latest)
            if isinstance(d, str):
                raise NoTimeBase(d)
            self.decision = d
        changed = False
        if self.decision.mode == "log_time":
            t, changed = log, True
        bad = implausible(t, self.latest)
        if bad.any():
            keep = ~bad
            self.n_dropped += int(bad.sum())
            t, log, v, changed = t[keep], log[keep], v[keep], True
        return t, log, v, changed

    def refusal(self, n_in: int) -> str | None:
        """Why the topic is refused after all its blocks (more than half of its ``n_in`` samples dropped)."""
        if self.n_dropped > MOST * n_in:
            return (f"{self.n_dropped} of {n_in} samples have a header.stamp before 2000 or in the future: no "
                    f"wall-clock time base; export wall-clock stamps")
        return None

    def warnings(self, n_unset: int) -> list[str]:
        """What the policy did, for the recording's warnings (``n_unset``: samples whose stamp was unset (zero)
        and took their log time, counted by the per-block checks)."""
        out = []
        log_time = self.decision is not None and self.decision.mode == "log_time"
        if log_time:
            out.append(self.decision.reason)
        elif n_unset:
            out.append(f"{n_unset} samples with an unset (zero) header.stamp: their log_time is used")
        if self.n_dropped:
            out.append(f"{self.n_dropped} samples with a {'log_time' if log_time else 'time'} before 2000 or in the "
                       f"future (not wall-clock time) dropped as outliers")
        return out



BATCH_TINY = 0.2            # a step below this fraction of the 90th-percentile step is inside a batch
BATCH_FRACTION = 0.3        # batched stamping when more steps than this are inside batches


class Batching:
    """Batched stamping (several samples per packet stamped microseconds apart, docs/clocks.md): detected once on a
    topic's first slice of stamps (:meth:`detect`), then each slice is re-spaced at the nominal sample period from
    each batch's first stamp, never past the next batch's start (:meth:`respace`)."""

    def __init__(self):
        self.batched: bool | None = None         # None: not decided yet
        self.period_ns = 0.0
        self.batch_size = 1.0
        self.batch_thresh = 0

    def detect(self, t: np.ndarray) -> None:
        d = np.diff(np.unique(t))
        self.batched = False
        if len(d) < 16:
            return
        p90 = float(np.percentile(d, 90))
        thresh = BATCH_TINY * p90
        tiny = d < thresh
        if tiny.mean() <= BATCH_FRACTION:
            return
        self.batch_thresh = int(max(thresh, 1))
        starts = self.starts(np.unique(t))
        sizes = np.diff(starts)
        steps = np.diff(np.unique(t)[starts])
        ok = sizes > 0
        self.period_ns = float(np.median(steps[ok] / sizes[ok])) if ok.any() else p90
        self.batch_size = float(np.median(sizes)) if len(sizes) else 1.0
        self.batched = True

    def starts(self, t: np.ndarray) -> np.ndarray:
        s = np.ones(len(t), dtype=bool)
        s[1:] = np.diff(t) >= self.batch_thresh
        return np.flatnonzero(s)

    def respace(self, t: np.ndarray, next_start: int | None) -> np.ndarray:
        starts = self.starts(t)
        sizes = np.diff(np.append(starts, len(t)))
        t_start = t[starts].astype(np.float64)
        t_next = np.append(t_start[1:], np.nan if next_start is None else float(next_start))
        room = (t_next - t_start) / sizes
        step = np.where(np.isfinite(room), np.minimum(self.period_ns, room), self.period_ns)
        batch = np.repeat(np.arange(len(starts)), sizes)
        k = np.arange(len(t)) - starts[batch]
        return t[starts][batch] + np.round(k * step[batch]).astype(np.int64)   # int64 + int64: no float rounding

    def warnings(self) -> list[str]:
        if not self.batched:
            return []
        return [f"header.stamp comes in batches of about {self.batch_size:.0f} samples: re-spaced at the "
                f"nominal rate {1e9 / self.period_ns:.2f} Hz from each batch's first stamp"]
