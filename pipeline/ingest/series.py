"""One topic of a recording on its way into the Parquet store: validation, clock policy, streaming writes.

Blocks arrive in file order (any order of messages, overlapping chunks); they are buffered, sorted by
``header.stamp`` and written in slices of about :data:`FLUSH_ROWS` rows, holding back the newest
:data:`HOLD_ROWS` so messages up to that many samples out of order still land in order. Memory per
topic is therefore bounded whatever the recording's length.

Where the work runs: :func:`stridelab.pipeline.ingest.block_checks.check_block` (finite values, unset stamps, order and repeats inside the
block, the subsample for the unit and clock statistics) is one pass of a numba kernel that the MCAP
reader calls on its chunk threads (``iter_blocks(on_block=...)``); :meth:`TopicSeries.add` then only
compares block edges, and each slice (policy, hashes, Parquet encoding) is written on a thread of its
own, in order, while the reader decodes the next chunks.

Clock policy (docs/clocks.md; the time-base decisions in :mod:`stridelab.pipeline.clock_policy`, order and repeats here),
each case reported as a warning of the recording, never silently:

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
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pyarrow as pa
import xxhash

from stridelab.pipeline import clock_policy
from stridelab.pipeline.formats.mcap_read import Block
from stridelab.pipeline.ingest.block_checks import _stamp_flags, check_block  # noqa: F401 - check_block: a block not checked yet
from stridelab.warehouse.store import SeriesWriter

GAP_WARN_S = 1.0            # gaps longer than this are recorded as warnings (the data are kept)
FLUSH_ROWS = 1 << 19
HOLD_ROWS = FLUSH_ROWS // 4

def _schema(*value_columns: str) -> pa.Schema:
    """Stamps and float64 values, all required (never null: a missing reading is NaN, never a null), so
    Parquet writes no definition levels: 0.6 instead of 0.9 CPU-s per 8 M IMU rows."""
    return pa.schema([pa.field("t_ns", pa.int64(), nullable=False), pa.field("log_ns", pa.int64(), nullable=False)]
                     + [pa.field(c, pa.float64(), nullable=False) for c in value_columns])


SCHEMAS = {
    "imu": _schema("gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z"),
    "mag": _schema("mag_x", "mag_y", "mag_z"),
    "reference_pose": _schema("px", "py", "pz", "qw", "qx", "qy", "qz"),
    "range": _schema("field_of_view", "min_range_m", "max_range_m", "range_m"),
}


class SeriesRejected(ValueError):
    """The topic (hence the recording) cannot be stored; ``str(err)`` is the one-line reason."""


@dataclass
class _Piece:
    """Rows waiting to be written, with what is known about their order."""
    t: np.ndarray
    log: np.ndarray
    v: np.ndarray
    back: bool                     # not sorted inside
    rep: bool                      # may repeat a stamp inside
    n_none: int = 0


def _cat(vs: list[np.ndarray]) -> np.ndarray:
    """Value blocks as one Fortran-ordered array (column by column: contiguous copies only)."""
    if len(vs) == 1:
        return np.asfortranarray(vs[0])
    v = np.empty((sum(len(x) for x in vs), vs[0].shape[1]), order="F")
    for k in range(v.shape[1]):
        np.concatenate([x[:, k] for x in vs], out=v[:, k])
    return v


def _split(vs: list[np.ndarray], cut: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Value blocks before and after row ``cut`` (views)."""
    head, tail, a = [], [], 0
    for x in vs:
        b = a + len(x)
        if b <= cut:
            head.append(x)
        elif a >= cut:
            tail.append(x)
        else:
            head.append(x[:cut - a])
            tail.append(x[cut - a:])
        a = b
    return head, tail


def _hold(t, log, vs, start: int, rep: bool) -> list[_Piece]:
    """Rows ``start:`` held back for the next slice, one piece per value block (stamps copied: they must
    not keep the whole concatenated slice alive; value blocks are views of their own block)."""
    out, a = [], start
    for v in vs:
        b = a + len(v)
        out.append(_Piece(t[a:b].copy(), log[a:b].copy(), v, False, rep))
        a = b
    return out


class TopicSeries:
    """Streaming validation, clock policy and buffered Parquet writing for one topic.

    :meth:`add` runs on the caller's thread and keeps only what the blocks' checks report; every
    slice of :data:`FLUSH_ROWS` rows is handed to one writing thread of this topic (in order, at
    most two slices in flight), whose errors surface at the next :meth:`add` or at :meth:`finish`.
    """

    def __init__(self, topic: str, kind: str, root: Path, legacy_digest: bool = False):
        self.topic, self.kind, self.root = topic, kind, Path(root)
        # reading side (the caller's thread)
        self.buf: list[_Piece] = []
        self.buf_rows = 0
        self.n_in = 0                       # samples received
        self._sub: list[np.ndarray] = []       # subsampled IMU values (unit checks)
        self._off: list[np.ndarray] = []       # subsampled log_time - stamp (clock checks)
        self._rot = np.zeros(3)                # gyroscope vs gravity direction: sums of |c|², |d|², c.d
        self._rot_pairs = 0
        self.n_nan = 0              # reference poses without a position
        self.n_no_quat = 0          # ... with a position but no orientation
        self.n_pose = 0
        self.n_zero = 0
        self.unsorted = False
        self.clock = clock_policy.TopicClock()   # decided on the first block, applied to every block
        # writing side (the topic's writing thread)
        self._held: list[_Piece] = []       # newest rows held back from the last slice (sorted)
        self.writer: SeriesWriter | None = None
        self.n = 0                          # rows written
        self.t0: int | None = None
        self.last_t: int | None = None      # stored stamp of the last written row
        self.last_orig: int | None = None   # received stamp of the last written row
        self.last_vals: np.ndarray | None = None
        self.dt_medians: list[float] = []
        self.gaps: list[tuple[int, float]] = []
        self.n_exact = 0
        self.n_conflict = 0
        self.batches = clock_policy.Batching()   # batched stamping: detected once, re-spaced slice by slice
        # the stored samples (not the file bytes) identify a recording (ingest.sample_hash); stamps and
        # values hashed apart, so that where the writes cut the stream does not matter. XXH3-128 (~25 GB/s
        # here against SHA-256's 1.8 with the CPU's SHA extensions: 0.27 CPU-s per 24 h day); the SHA-256
        # digests of the samples' earlier identity only where the warehouse still holds such (``legacy_digest``)
        self.stamp_digest, self.value_digest = xxhash.xxh3_128(), xxhash.xxh3_128()
        self.legacy = (hashlib.sha256(), hashlib.sha256()) if legacy_digest else None
        self._pool: ThreadPoolExecutor | None = None
        self._pending: list[Future] = []

    # ---- input -------------------------------------------------------------------------------
    def add(self, b: Block) -> None:
        if len(b.t_ns) == 0:
            return
        c = b.checks if getattr(b, "checks", None) is not None else check_block(b).checks
        if c.n_bad:
            raise SeriesRejected(f"{self.topic}: {c.n_bad} samples with NaN/inf values (first at sample "
                                 f"{self.n_in + c.first_bad}); fix or drop them at export")
        self.n_nan += c.n_nan
        self.n_no_quat += c.n_no_quat
        self.n_pose += c.n_pose
        self.n_zero += c.n_zero
        if c.sub is not None:
            self._sub.append(c.sub)
            self._off.append(c.off)
            self._rot += np.asarray(c.rot[:3])
            self._rot_pairs += int(c.rot[3])
        t, log, v, back, rep = c.t, b.log_ns, b.values, c.back, c.rep
        if not c.n_none:                    # (samples without any time base refuse the topic in _write)
            try:
                t, log, v, changed = self.clock.apply(t, log, v)       # pipeline/clock_policy.py
            except clock_policy.NoTimeBase as e:
                raise SeriesRejected(f"{self.topic}: {e}") from None
            if changed and len(t):
                _, _, back, rep = _stamp_flags(np.ascontiguousarray(t), np.ascontiguousarray(log))
        self.n_in += len(c.t)
        if len(t) == 0:
            return
        if back:
            self.unsorted = True
        self.buf.append(_Piece(t, log, v, back, rep, c.n_none))
        self.buf_rows += len(t)
        if self.buf_rows >= FLUSH_ROWS:
            self._submit(final=False)

    def _submit(self, final: bool) -> None:
        pieces, self.buf, self.buf_rows = self.buf, [], 0
        while self._pending and (len(self._pending) >= 2 or self._pending[0].done()):
            self._pending.pop(0).result()          # re-raises a SeriesRejected of an earlier slice
        if not pieces and not final:
            return
        if final and self._pool is None:
            # the whole topic in one slice (a lab trial's topics; 28 of them per file): written here, without
            # the two writing threads of a long series (a thread pool per topic and one per Parquet file)
            self._write(pieces, final)
            return
        if self._pool is None:
            self._pool = ThreadPoolExecutor(1, thread_name_prefix="series")
        self._pending.append(self._pool.submit(self._write, pieces, final))

    def _wait(self) -> None:
        try:
            while self._pending:
                self._pending.pop(0).result()
        finally:
            self._pending = []
            if self._pool is not None:
                self._pool.shutdown(wait=True, cancel_futures=True)
                self._pool = None

    def finish(self) -> None:
        self._submit(final=True)
        self._wait()
        why = self.clock.refusal(self.n_in)
        if why:
            raise SeriesRejected(f"{self.topic}: {why}")
        if self.n_conflict > 0.5 * self.n_in:
            raise SeriesRejected(f"{self.topic}: {self.n_conflict} of {self.n_in} samples repeat a header.stamp "
                                 f"with different values: no usable time base; export sensor time stamps "
                                 f"(or leave them unset so that log_time is used)")

    # ---- the policy (on the writing thread) ------------------------------------------------------
    def _write(self, new: list[_Piece], final: bool) -> None:
        n_none = sum(p.n_none for p in new)
        if n_none:
            raise SeriesRejected(f"{self.topic}: {n_none} samples have neither a header.stamp nor a "
                                 f"log_time: no time base; export sensor time stamps")
        pieces = self._held + new
        self._held = []
        if not pieces:
            return
        # order known from the blocks' checks and their edges: sort and look for repeats only if needed
        back = any(p.back for p in pieces)
        rep = any(p.rep for p in pieces)
        for a, b in zip(pieces, pieces[1:]):
            back |= bool(b.t[0] < a.t[-1])
            rep |= bool(b.t[0] == a.t[-1])
        t = pieces[0].t if len(pieces) == 1 else np.concatenate([p.t for p in pieces])
        log = pieces[0].log if len(pieces) == 1 else np.concatenate([p.log for p in pieces])
        # values stay in their blocks (views, no copy) unless the rows must be reordered or dropped
        vs = [p.v for p in pieces]
        del pieces, new
        if back:
            order = np.argsort(t, kind="stable")
            t, log, vs = t[order], log[order], [np.asfortranarray(_cat(vs)[order])]
            rep = True                     # repeats may now sit next to each other
        if self.last_orig is not None and t[0] < self.last_orig:
            raise SeriesRejected(f"{self.topic}: messages arrive more than {HOLD_ROWS:,} samples out of "
                                 f"header.stamp order; sort the file first (`mcap sort`)")
        if self.batches.batched is None and (final or len(t) > 2 * HOLD_ROWS):
            self.batches.detect(t)
        cut = len(t)
        if not final:
            cut = len(t) - HOLD_ROWS
            if self.batches.batched:
                starts = self.batches.starts(t)
                cut = int(starts[np.searchsorted(starts, cut, side="right") - 1])
            if cut <= 0:
                self._held = _hold(t, log, vs, 0, rep)
                return
            vs, tail = _split(vs, cut)
            self._held = _hold(t, log, tail, cut, rep)
        t, log = t[:cut], log[:cut]
        if rep or (self.last_orig is not None and t[0] == self.last_orig):
            t, log, v = self._dedupe(t, log, _cat(vs))
            vs = [v]
        if len(t) == 0:
            return
        orig_last = int(t[-1])
        if self.batches.batched:
            nxt = None if final else int(self._held[0].t[0])
            t = self.batches.respace(t, nxt)
        self._stats(t)
        self.last_orig, self.last_t, self.last_vals = orig_last, int(t[-1]), vs[-1][-1].copy()
        if self.t0 is None:
            self.t0 = int(t[0])
        self.n += len(t)
        stamps = np.ascontiguousarray(t, dtype=np.int64)
        self.stamp_digest.update(stamps)
        if self.legacy is not None:
            self.legacy[0].update(stamps)
        for v in vs:                       # row-major, as always; block by block (in cache)
            rows = np.ascontiguousarray(v, dtype=np.float64)
            self.value_digest.update(rows)
            if self.legacy is not None:
                self.legacy[1].update(rows)
        if self.kind == "mag":
            vs = [v * 1e6 for v in vs]     # tesla on the wire -> µT in the warehouse
        schema = SCHEMAS[self.kind]
        cols = [pa.array(t), pa.array(log)] + [
            pa.chunked_array([pa.array(np.ascontiguousarray(v[:, k])) for v in vs], type=pa.float64())
            for k in range(vs[0].shape[1])]
        if self.writer is None:
            # a staging name: the final path (study/participant/session/placement + content hash) is
            # known only after the whole file was read; commit() moves it there
            self.writer = SeriesWriter(self.root, f"series/_staging/{uuid.uuid4().hex}.parquet", schema)
        self.writer.write(pa.Table.from_arrays(cols, schema=schema), last=final)

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

    @property
    def gyro_to_gravity_turn(self) -> tuple[float, float, int]:
        """(ratio, correlation, window pairs) of the turn the gyroscope predicts for the gravity direction to the
        turn the accelerometer measures, over quasi-static windows (:func:`_rotation_sums`): ratio ~1 in rad/s,
        ~57 in deg/s; NaN without pairs or rotation."""
        sxx, syy, sxy = self._rot
        if self._rot_pairs == 0 or sxx <= 0 or syy <= 0:
            return float("nan"), float("nan"), self._rot_pairs
        return float(np.sqrt(sxx / syy)), float(sxy / np.sqrt(sxx * syy)), self._rot_pairs

    def warnings(self) -> list[str]:
        out = self.clock.warnings(self.n_zero)
        if self.n_exact:
            out.append(f"{self.n_exact} exact duplicate samples dropped")
        if self.n_conflict:
            out.append(f"{self.n_conflict} samples repeat an earlier header.stamp with different values: "
                       f"the first kept, the others dropped")
        out += self.batches.warnings()
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
        try:
            self._wait()
        except Exception:  # noqa: BLE001 - aborting anyway; the first error was reported
            pass
        if self.writer is not None:
            self.writer.abort()
            self.writer = None
