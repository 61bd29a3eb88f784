"""Daily summaries in the participant's local time zone (zoneinfo; DST days have 23 or 25 hours)."""
from __future__ import annotations

import datetime as _dt
from zoneinfo import ZoneInfo

import numpy as np

from stridelab.estimators.activity._types import (CLASSES, LEVEL, NON_WEAR, TRANSITIONS, WALKING_CLASSES, ActivityResult,
                                        DailySummary)


def local_midnights_ns(t_first_ns: int, t_last_ns: int, timezone: str) -> list[tuple[str, int, int]]:
    """(ISO date, UTC ns of local midnight, UTC ns of the next local midnight) for every local date touched by
    [t_first_ns, t_last_ns]. Midnight is resolved by zoneinfo (fold=0), so DST days are 23 h or 25 h long."""
    tz = ZoneInfo(timezone)
    d0 = _dt.datetime.fromtimestamp(t_first_ns / 1e9, tz).date()
    d1 = _dt.datetime.fromtimestamp(t_last_ns / 1e9, tz).date()
    out = []
    d = d0
    while d <= d1:
        nxt = d + _dt.timedelta(days=1)
        a = int(round(_dt.datetime(d.year, d.month, d.day, tzinfo=tz).timestamp())) * 1_000_000_000
        b = int(round(_dt.datetime(nxt.year, nxt.month, nxt.day, tzinfo=tz).timestamp())) * 1_000_000_000
        out.append((d.isoformat(), a, b))
        d = nxt
    return out


def daily_summaries(result: ActivityResult, timezone: str | None = None) -> list[DailySummary]:
    """One ``DailySummary`` per local calendar day touched by the recording (a recording crossing midnight
    gives two). A second belongs to the day of its start instant; steps and transitions to the day of their
    instant; bouts to the day they start in. ``timezone`` defaults to the one given to ``classify_day``."""
    tzname = timezone or result.timezone
    t = result.second_t_ns
    if t.size == 0:
        return []
    days = local_midnights_ns(int(t[0]), int(t[-1]), tzname)
    edges = np.array([a for _, a, _ in days] + [days[-1][2]], dtype=np.int64)
    day_of_sec = np.searchsorted(edges, t, side="right") - 1
    t0 = result.t0_ns
    to_ns = lambda s: np.int64(t0) + np.round(np.asarray(s, dtype=np.float64) * 1e9).astype(np.int64)  # noqa: E731
    day_of_step = np.searchsorted(edges, to_ns(result.step_times_s), side="right") - 1
    day_of_tr = np.searchsorted(edges, to_ns(result.transitions.t_s), side="right") - 1
    b = result.bouts
    day_of_bout = np.searchsorted(edges, to_ns(b.start_s), side="right") - 1
    n_cls = len(CLASSES)
    out = []
    for k, (date, a, e) in enumerate(days):
        cls = result.second_class[day_of_sec == k]
        cnt = np.bincount(cls, minlength=n_cls)
        smod = result.step_modality[day_of_step == k]
        steps = {name: int(np.sum(smod == LEVEL + i)) for i, name in enumerate(WALKING_CLASSES)}
        trk = result.transitions.kind[day_of_tr == k]
        trans = {name: int(np.sum(trk == i)) for i, name in enumerate(TRANSITIONS)}
        sel = day_of_bout == k
        dur = (b.end_s - b.start_s)[sel]
        out.append(DailySummary(date=date, day_start_ns=a, day_end_ns=e, day_length_s=int((e - a) // 1_000_000_000),
                                recorded_s=int(cls.size), wear_s=int(cls.size - cnt[NON_WEAR]),
                                seconds={name: int(cnt[i]) for i, name in enumerate(CLASSES)}, steps=steps,
                                transitions=trans, n_bouts=int(sel.sum()),
                                bout_s_median=float(np.median(dur)) if dur.size else 0.0,
                                bout_s_max=float(dur.max()) if dur.size else 0.0))
    return out
