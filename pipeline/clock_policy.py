"""Clock sanity of a topic's stamps (docs/clocks.md "Implausible stamps"): never a silent 1970 or a 56-year gap.

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
