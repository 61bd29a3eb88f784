"""One topic of a recording on its way into the Parquet store: validation, clock policy, streaming writes.

Blocks arrive in file order (any order of messages, overlapping chunks); they are buffered, sorted by
``header.stamp`` and written in slices of about :data:`FLUSH_ROWS` rows, holding back the newest
:data:`HOLD_ROWS` so messages up to that many samples out of order still land in order. Memory per
topic is therefore bounded whatever the recording's length.

Clock policy (docs/clocks.md), each case reported as a warning of the recording, never silently:

- unset (zero) ``header.stamp``: the sample takes its ``log_time``;
- exact duplicate samples (same stamp, same values): dropped;
- a repeated stamp with different values: the first sample in file order is kept;
- batched stamping (several samples per packet stamped microseconds apart): each batch is re-spaced
  at the nominal sample period from its first sample's stamp (never past the next batch's start);
- the recording is refused only when no time base can be recovered (every stamp and log_time zero or
  all samples on one instant) or messages are more than :data:`HOLD_ROWS` samples out of order.
"""
from __future__ import annotations

import hashlib

import uuid
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pyarrow as pa

from pipeline.formats.mcap_read import Block
from warehouse.store import SeriesWriter

GAP_WARN_S = 1.0            # gaps longer than this are recorded as warnings (the data are kept)
FLUSH_ROWS = 1 << 19
HOLD_ROWS = FLUSH_ROWS // 4
BATCH_TINY = 0.2            # a step below this fraction of the 90th-percentile step is inside a batch
BATCH_FRACTION = 0.3        # batched stamping when more steps than this are inside batches
SUBSAMPLE = 61              # statistics on every 61st sample (prime: no aliasing with batches or chunks)

SCHEMAS = {
    "imu": pa.schema([("t_ns", pa.int64()), ("log_ns", pa.int64())]
                     + [(c, pa.float64()) for c in ("gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z")]),
    "mag": pa.schema([("t_ns", pa.int64()), ("log_ns", pa.int64())]
                     + [(c, pa.float64()) for c in ("mag_x", "mag_y", "mag_z")]),
    "reference_pose": pa.schema([("t_ns", pa.int64()), ("log_ns", pa.int64())]
                                + [(c, pa.float64()) for c in ("px", "py", "pz", "qw", "qx", "qy", "qz")]),
    "range": pa.schema([("t_ns", pa.int64()), ("log_ns", pa.int64())]
                       + [(c, pa.float64()) for c in ("field_of_view", "min_range_m", "max_range_m", "range_m")]),
}


class SeriesRejected(ValueError):
    """The topic (hence the recording) cannot be stored; ``str(err)`` is the one-line reason."""


class TopicSeries:
    """Streaming validation, clock policy and buffered Parquet writing for one topic."""

    def __init__(self, topic: str, kind: str, root: Path):
        self.topic, self.kind, self.root = topic, kind, Path(root)
        self.buf: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self.buf_rows = 0
        self.writer: SeriesWriter | None = None
        self.n = 0                          # rows written
        self.n_in = 0                       # samples received
        self.t0: int | None = None
        self.last_t: int | None = None      # stored stamp of the last written row
        self.last_orig: int | None = None   # received stamp of the last written row
        self.last_vals: np.ndarray | None = None
        self.dt_medians: list[float] = []
        self._sub: list[np.ndarray] = []       # subsampled IMU values (unit checks)
        self._off: list[np.ndarray] = []       # subsampled log_time - stamp (clock checks)
        self.gaps: list[tuple[int, float]] = []
        self.n_nan = 0              # reference poses without a position
        self.n_no_quat = 0          # ... with a position but no orientation
        self.n_pose = 0
        self.n_zero = 0
        self.n_exact = 0
        self.n_conflict = 0
        self.unsorted = False
        self.batched: bool | None = None
        self.period_ns = 0.0
        self.batch_size = 1.0
        self.batch_thresh = 0
        # the stored samples (not the file bytes) identify a recording (ingest.sample_hash); stamps and
        # values hashed apart, so that where the writes cut the stream does not matter
        self.stamp_digest, self.value_digest = hashlib.sha256(), hashlib.sha256()

    # ---- input -------------------------------------------------------------------------------
    def add(self, b: Block) -> None:
        t, log, v = b.t_ns, b.log_ns, b.values
        if len(t) == 0:
            return
        if self.kind == "range":
            pass        # REP-117: +inf beyond max range, -inf below min, NaN invalid: legitimate readings
        elif self.kind == "reference_pose" and not np.isinf(v).any():
            pos_nan = np.isnan(v[:, :3]).any(axis=1)               # occluded markers: kept as NaN
            self.n_nan += int(pos_nan.sum())
            self.n_no_quat += int((np.isnan(v[:, 3:7]).any(axis=1) & ~pos_nan).sum())
            self.n_pose += len(v)
        elif not np.isfinite(v).all():
            bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
            raise SeriesRejected(f"{self.topic}: {len(bad)} samples with NaN/inf values (first at sample "
                                 f"{self.n_in + int(bad[0])}); fix or drop them at export")
        zero = t == 0
        if zero.any():
            t = np.where(zero, log, t)
            self.n_zero += int(zero.sum())
        if len(t) > 1 and (np.diff(t) < 0).any():
            self.unsorted = True
        if self.kind == "imu":                      # every 61st sample feeds the unit and clock statistics
            self._sub.append(v[::SUBSAMPLE].copy())          # a copy: a view would keep the block alive
            self._off.append(log[::SUBSAMPLE] - t[::SUBSAMPLE])
        self.n_in += len(t)
        self.buf.append((t, log, v))
        self.buf_rows += len(t)
        if self.buf_rows >= FLUSH_ROWS:
            self._write(final=False)

    def finish(self) -> None:
        self._write(final=True)
        if self.n_conflict > 0.5 * self.n_in:
            raise SeriesRejected(f"{self.topic}: {self.n_conflict} of {self.n_in} samples repeat a header.stamp "
                                 f"with different values: no usable time base; export sensor time stamps "
                                 f"(or leave them unset so that log_time is used)")

    # ---- the policy --------------------------------------------------------------------------
    def _write(self, final: bool) -> None:
        if not self.buf:
            return
        t = np.concatenate([x[0] for x in self.buf])
        log = np.concatenate([x[1] for x in self.buf])
        ncol = self.buf[0][2].shape[1]
        v = np.empty((len(t), ncol), order="F")         # column by column: contiguous copies only
        for k in range(ncol):
            np.concatenate([x[2][:, k] for x in self.buf], out=v[:, k])
        self.buf, self.buf_rows = [], 0
        if (t == 0).any():
            raise SeriesRejected(f"{self.topic}: {int((t == 0).sum())} samples have neither a header.stamp nor a "
                                 f"log_time: no time base; export sensor time stamps")
        if len(t) > 1 and (t[1:] < t[:-1]).any():
            order = np.argsort(t, kind="stable")
            t, log, v = t[order], log[order], np.asfortranarray(v[order])
        if self.last_orig is not None and t[0] < self.last_orig:
            raise SeriesRejected(f"{self.topic}: messages arrive more than {HOLD_ROWS:,} samples out of "
                                 f"header.stamp order; sort the file first (`mcap sort`)")
        if self.batched is None and (final or len(t) > 2 * HOLD_ROWS):
            self._detect_batches(t)
        cut = len(t)
        if not final:
            cut = len(t) - HOLD_ROWS
            if self.batched:
                starts = self._batch_starts(t)
                cut = int(starts[np.searchsorted(starts, cut, side="right") - 1])
            if cut <= 0:
                self.buf, self.buf_rows = [(t, log, v)], len(t)
                return
            # copies: the held-back rows must not keep the whole concatenated slice alive
            self.buf, self.buf_rows = [(t[cut:].copy(), log[cut:].copy(), v[cut:].copy(order="F"))], len(t) - cut
        t, log, v = t[:cut], log[:cut], v[:cut]
        t, log, v = self._dedupe(t, log, v)
        if len(t) == 0:
            return
        orig_last = int(t[-1])
        if self.batched:
            nxt = None if final else int(self.buf[0][0][0])
            t = self._respace(t, nxt)
        self._stats(t)
        self.last_orig, self.last_t, self.last_vals = orig_last, int(t[-1]), v[-1].copy()
        if self.t0 is None:
            self.t0 = int(t[0])
        self.n += len(t)
        self.stamp_digest.update(np.ascontiguousarray(t, dtype=np.int64).tobytes())
        self.value_digest.update(np.ascontiguousarray(v, dtype=np.float64).tobytes())
        if self.kind == "mag":
            v = v * 1e6          # tesla on the wire -> µT in the warehouse
        schema = SCHEMAS[self.kind]
        cols = [pa.array(t), pa.array(log)] + [pa.array(np.ascontiguousarray(v[:, k])) for k in range(v.shape[1])]
        if self.writer is None:
            # a staging name: the final path (study/participant/session/placement + content hash) is
            # known only after the whole file was read; commit() moves it there
            self.writer = SeriesWriter(self.root, f"series/_staging/{uuid.uuid4().hex}.parquet", schema)
        self.writer.write(pa.Table.from_arrays(cols, schema=schema))

    def _dedupe(self, t, log, v):
        n = len(t)
        dup = np.zeros(n, dtype=bool)
        dup[1:] = t[1:] == t[:-1]
        if self.last_orig is not None:
            dup[0] = t[0] == self.last_orig
        if not dup.any():
            return t, log, v
        idx = np.arange(n)
        keep_idx = np.maximum.accumulate(np.where(dup, 0, idx))
        ref = v[keep_idx].copy()
        if dup[0]:                         # a run that continues the previous slice
            run0 = keep_idx == 0
            run0 &= np.cumsum(~dup) == 0
            ref[run0] = self.last_vals
        same = ((v == ref) | (np.isnan(v) & np.isnan(ref))).all(axis=1)
        self.n_exact += int((dup & same).sum())
        self.n_conflict += int((dup & ~same).sum())
        keep = ~dup
        return t[keep], log[keep], v[keep]

    def _detect_batches(self, t: np.ndarray) -> None:
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
        starts = self._batch_starts(np.unique(t))
        sizes = np.diff(starts)
        steps = np.diff(np.unique(t)[starts])
        ok = sizes > 0
        self.period_ns = float(np.median(steps[ok] / sizes[ok])) if ok.any() else p90
        self.batch_size = float(np.median(sizes)) if len(sizes) else 1.0
        self.batched = True

    def _batch_starts(self, t: np.ndarray) -> np.ndarray:
        s = np.ones(len(t), dtype=bool)
        s[1:] = np.diff(t) >= self.batch_thresh
        return np.flatnonzero(s)

    def _respace(self, t: np.ndarray, next_start: int | None) -> np.ndarray:
        starts = self._batch_starts(t)
        sizes = np.diff(np.append(starts, len(t)))
        t_start = t[starts].astype(np.float64)
        t_next = np.append(t_start[1:], np.nan if next_start is None else float(next_start))
        room = (t_next - t_start) / sizes
        step = np.where(np.isfinite(room), np.minimum(self.period_ns, room), self.period_ns)
        batch = np.repeat(np.arange(len(starts)), sizes)
        k = np.arange(len(t)) - starts[batch]
        return t[starts][batch] + np.round(k * step[batch]).astype(np.int64)   # int64 + int64: no float rounding

    def _stats(self, t: np.ndarray) -> None:
        full = t if self.last_t is None else np.concatenate([[self.last_t], t])
        d = np.diff(full)
        if len(d):
            self.dt_medians.append(float(np.median(d[::7])))      # a subsample is plenty for a median
            for i in np.flatnonzero(d > GAP_WARN_S * 1e9)[:20]:
                self.gaps.append((int(full[i]), float(d[i]) / 1e9))

    # ---- outputs -----------------------------------------------------------------------------
    @property
    def rate_hz(self) -> float:
        return 1e9 / float(np.median(self.dt_medians)) if self.dt_medians else float("nan")

    @property
    def clock_offset_s(self) -> float:
        """Median of log_time - header.stamp (s): the sensor clock's offset to the host's."""
        return float(np.median(np.concatenate(self._off))) / 1e9 if self._off else float("nan")

    @property
    def acc_norm_median(self) -> float:
        v = np.concatenate(self._sub)
        return float(np.median(np.linalg.norm(v[:, 3:], axis=1)))

    @property
    def gyr_p99(self) -> float:
        v = np.concatenate(self._sub)
        return float(np.percentile(np.abs(v[:, :3]), 99))

    def warnings(self) -> list[str]:
        out = []
        if self.n_zero:
            out.append(f"{self.n_zero} samples with an unset (zero) header.stamp: their log_time is used")
        if self.n_exact:
            out.append(f"{self.n_exact} exact duplicate samples dropped")
        if self.n_conflict:
            out.append(f"{self.n_conflict} samples repeat an earlier header.stamp with different values: "
                       f"the first kept, the others dropped")
        if self.batched:
            out.append(f"header.stamp comes in batches of about {self.batch_size:.0f} samples: re-spaced at the "
                       f"nominal rate {1e9 / self.period_ns:.2f} Hz from each batch's first stamp")
        if self.unsorted:
            out.append("messages were not in header.stamp order: sorted")
        if self.n_nan:
            out.append(f"{self.n_nan} reference samples without a position (occlusion), kept as NaN")
        if self.n_no_quat and self.n_no_quat == self.n_pose - self.n_nan:
            out.append("the reference gives positions only (no orientation): orientation is not scored against it")
        elif self.n_no_quat:
            out.append(f"{self.n_no_quat} reference samples with a position but no orientation (a cluster marker "
                       f"occluded), kept as NaN")
        for t_gap, dur in self.gaps:
            when = datetime.fromtimestamp(t_gap / 1e9, tz=timezone.utc).isoformat(timespec="seconds")
            out.append(f"gap of {dur:.1f} s after {when} (data kept; estimators treat the two sides as "
                       f"separate segments)")
        return out

    def abort(self) -> None:
        if self.writer is not None:
            self.writer.abort()
            self.writer = None
