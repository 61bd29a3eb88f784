"""The MCAP reader's fast path: a group of decompressed chunks holding only fixed-layout messages, decoded
straight into one set of arrays per channel.

What most recordings are made of: chunks whose records are all Message records on channels of the all-double
ROS 2 types (``sensor_msgs/msg/Imu``, ``MagneticField``, ``geometry_msgs/msg/PoseStamped``), on channels StrideLab
ignores, or on annotation and range channels (a few messages among the samples). For those, one pass of a numba
kernel per chunk replaces the general path's record tables, per-chunk decoding and the join of the chunks' blocks
(:func:`stridelab.pipeline.formats.mcap_read._group_task`), in :class:`GroupDecoder`:

1. the group's arrays are allocated once, sized from the first chunk's messages per channel (counted by
   :func:`_count_kernel`) scaled to the group's declared bytes, with slack;
2. each chunk, right after its decompression (still in the core's cache), is walked by :func:`_decode_kernel`,
   which checks every record as the general path would and writes every message's ``header.stamp``,
   ``log_time`` and selected doubles (bit for bit, as 64-bit words) at its channel's next row; annotation and
   range messages are only located, for the general decoders.

A chunk the kernel refuses (any other record, a malformed record, a message that does not fit its schema, a
channel out of room) sends the whole group to the general path, which raises the precise one-line error, so
the fast path never decides what is an error. The decoded values are those of
:func:`stridelab.pipeline.formats.ros2_cdr.decode_doubles`, in file order per channel, each column contiguous.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

#: ``slot_of`` value of a channel the fast path cannot take (not defined yet)
NO_SLOT = -1
#: ``n_doubles`` of a slot whose messages are only located (start, length, log_time), for the general decoders
#: (annotations, ranges: a few messages among the samples)
LOCATE = -1


@dataclass(frozen=True)
class Plan:
    """Channels of a registry snapshot the fast path takes: ``channel_ids[s]`` is slot ``s``; ``slot_of`` (65536,)
    maps a channel id to its slot or :data:`NO_SLOT`; per slot ``n_doubles`` after the header (0: counted, not
    decoded; :data:`LOCATE`: located for a general decoder) and ``fields`` (slots, max fields) indices of the
    doubles to extract, ``n_fields`` of them."""
    channel_ids: np.ndarray
    slot_of: np.ndarray
    n_doubles: np.ndarray
    fields: np.ndarray
    n_fields: np.ndarray


def make_plan(channels: dict[int, tuple[int, np.ndarray] | None | str]) -> Plan:
    """``channels``: channel id -> (doubles after the header, field indices) for a decoded type, None for a
    channel whose messages are only counted, ``"locate"`` for one decoded by a general decoder."""
    ids = np.array(sorted(channels), dtype=np.int64)
    slot_of = np.full(1 << 16, NO_SLOT, dtype=np.int64)
    slot_of[ids] = np.arange(len(ids))
    width = max([len(v[1]) for v in channels.values() if v is not None] + [1])
    fields = np.zeros((len(ids), width), dtype=np.int64)
    n_doubles = np.zeros(len(ids), dtype=np.int64)
    n_fields = np.zeros(len(ids), dtype=np.int64)
    for s, cid in enumerate(ids.tolist()):
        v = channels[cid]
        if isinstance(v, str):
            n_doubles[s] = LOCATE
        elif v is not None:
            n_doubles[s], n_fields[s] = v[0], len(v[1])
            fields[s, :len(v[1])] = v[1]
    return Plan(ids, slot_of, n_doubles, fields, n_fields)


# Little-endian reads at any byte offset. The index is unsigned: numba then emits no negative-index
# wraparound per byte, and LLVM merges the eight byte loads into one (5x faster decoding than signed indices).
@njit(cache=True, nogil=True, inline="always")
def _u64(buf, p):
    q = np.uint64(p)
    v = np.uint64(0)
    for b in range(8):
        v |= np.uint64(buf[q + np.uint64(b)]) << np.uint64(8 * b)
    return v


@njit(cache=True, nogil=True, inline="always")
def _u32(buf, p):
    q = np.uint64(p)
    return (np.uint32(buf[q]) | (np.uint32(buf[q + np.uint64(1)]) << 8) | (np.uint32(buf[q + np.uint64(2)]) << 16)
            | (np.uint32(buf[q + np.uint64(3)]) << 24))


@njit(cache=True, nogil=True)
def _count_kernel(buf, slot_of, counts):
    """Add each slot's messages in ``buf`` (one decompressed chunk) to ``counts``; 0, or 1 when the chunk is
    not for the fast path (a record other than a Message, a channel without a slot, a record shorter than a
    Message's fixed fields or running past the chunk, records that do not fill it exactly)."""
    end = buf.shape[0]
    p = 0
    while p + 9 <= end:
        if buf[p] != 5:
            return 1
        length = _u64(buf, p + 1)
        if length < np.uint64(22) or length > np.uint64(end):
            return 1
        q = p + 9
        nxt = q + np.int64(length)
        if nxt > end:
            return 1
        s = slot_of[np.int64(buf[q]) | (np.int64(buf[q + 1]) << 8)]
        if s < 0:
            return 1
        counts[s] += 1
        p = nxt
    return 0 if p == end else 1


@njit(cache=True, nogil=True)
def _decode_kernel(buf, slot_of, n_doubles, fields, n_fields, row0, cap, pos, counts, out_t, out_log, out_vals,
                   loc_slot, loc_start, loc_len, loc_log, n_loc):
    """Decode the messages of ``buf`` (one decompressed chunk) at each slot's next row ``pos[s]``: slot ``s``
    owns rows ``row0[s] .. row0[s] + cap[s]`` of ``out_t``/``out_log`` and, field by field, the same span (times
    its field index) of ``out_vals`` (uint64 words of the float64 values, so NaN payloads survive). Messages
    of :data:`LOCATE` slots go to ``loc_*`` (slot, payload start and length, log_time) from ``n_loc[0]`` on.
    ``counts[s]`` counts every message of slot ``s``, decoded or not.

    Returns 0; 1 when the chunk is not for the fast path (a record other than a Message, a channel without a
    slot, a record shorter than a Message's fixed fields or running past the chunk, records that do not fill
    it, or a message the general decoder would refuse: encapsulation, size against the schema, nanoseconds out
    of range); 2 when a slot or the located messages run out of room. Rows written before a refusal are
    garbage: the caller decodes the chunk again another way.
    """
    end = buf.shape[0]
    width = fields.shape[1]
    p = 0
    while p + 9 <= end:
        if buf[p] != 5:
            return 1
        ulen = _u64(buf, p + 1)
        if ulen < np.uint64(22) or ulen > np.uint64(end):
            return 1
        length = np.int64(ulen)
        q = p + 9
        if q + length > end:
            return 1
        s = slot_of[np.int64(buf[q]) | (np.int64(buf[q + 1]) << 8)]
        if s < 0:
            return 1
        counts[s] += 1
        nd = n_doubles[s]
        if nd < 0:
            j = n_loc[0]
            if j >= loc_slot.shape[0]:
                return 2
            loc_slot[j] = s
            loc_start[j] = q + 22
            loc_len[j] = length - 22
            loc_log[j] = np.int64(_u64(buf, q + 6))
            n_loc[0] = j + 1
        elif nd > 0:
            m = q + 22                       # payload start
            L = length - 22
            if L < 16 or buf[m] != 0 or buf[m + 1] != 1:
                return 1
            sec = np.int64(np.int32(_u32(buf, m + 4)))
            nsec = np.int64(_u32(buf, m + 8))
            if nsec >= 1_000_000_000:
                return 1
            slen = np.int64(_u32(buf, m + 12))
            body = m + 4 + (16 + slen - 4 + 7) // 8 * 8
            need = body - m + 8 * nd
            if need > L or L - need > 3:
                return 1
            i = pos[s]
            c = cap[s]
            if i >= c:
                return 2
            r = row0[s] + i
            out_t[r] = sec * 1_000_000_000 + nsec
            out_log[r] = np.int64(_u64(buf, q + 6))
            base = row0[s] * width + i
            for k in range(n_fields[s]):
                out_vals[base + k * c] = _u64(buf, body + 8 * fields[s, k])
            pos[s] = i + 1
        p = q + length
    return 0 if p == end else 1


#: room for located messages (annotations, ranges) per group; a group with more takes the general path
LOCATE_ROOM = 4096


class GroupDecoder:
    """Decodes the chunks of one group, each right after its decompression (still in the core's cache), into
    arrays sized for the group from the first chunk's message density (2 % and 64 rows of slack per slot).

    :meth:`add` returns False when the group is not for the fast path (see :func:`_decode_kernel`) or a slot
    ran out of room; :meth:`result` then returns None and the caller decodes the group the general way."""

    def __init__(self, plan: Plan, group_bytes: int):
        self.plan = plan
        self.group_bytes = group_bytes
        self.ok = True
        self.bufs: list[np.ndarray] = []
        self.pos = np.zeros(len(plan.channel_ids), dtype=np.int64)
        self.counts = np.zeros(len(plan.channel_ids), dtype=np.int64)
        self.cap = None
        self.n_loc = np.zeros(1, dtype=np.int64)
        self.loc = [np.empty(LOCATE_ROOM, dtype=np.int64) for _ in range(4)]
        self.loc_chunk: list[int] = []

    def _allocate(self, first: np.ndarray) -> bool:
        plan = self.plan
        counts = np.zeros(len(plan.channel_ids), dtype=np.int64)
        if _count_kernel(first, plan.slot_of, counts):
            return False
        dens = counts / max(1, len(first))
        cap = np.where(plan.n_doubles > 0, np.ceil(dens * self.group_bytes * 1.02) + 64, 0).astype(np.int64)
        cap[counts == 0] = 0
        self.cap = cap
        self.row0 = np.concatenate([[0], np.cumsum(cap)[:-1]]).astype(np.int64)
        total = int(cap.sum())
        self.out_t = np.empty(total, dtype=np.int64)
        self.out_log = np.empty(total, dtype=np.int64)
        self.out_vals = np.empty(total * plan.fields.shape[1], dtype=np.uint64)
        return True

    def add(self, raw: bytes) -> bool:
        if not self.ok:
            return False
        b = np.frombuffer(raw, dtype=np.uint8)
        if self.cap is None and not self._allocate(b):
            self.ok = False
            return False
        plan = self.plan
        before_loc = int(self.n_loc[0])
        if _decode_kernel(b, plan.slot_of, plan.n_doubles, plan.fields, plan.n_fields, self.row0, self.cap, self.pos,
                          self.counts, self.out_t, self.out_log, self.out_vals, *self.loc, self.n_loc):
            self.ok = False
            return False
        n_loc = int(self.n_loc[0]) - before_loc
        if n_loc:
            self.bufs.append(b)
            self.loc_chunk += [len(self.bufs) - 1] * n_loc
        return True

    def result(self):
        """None, or ``{slot: (t_ns, log_ns, values (N, fields) float64, each column contiguous)}`` of the decoded
        slots and ``[(buf, slots, starts, lengths, log_ns)]`` of the located messages per chunk, in file order
        (:attr:`counts`: every slot's messages)."""
        if not self.ok or self.cap is None:
            return None
        plan = self.plan
        vals = self.out_vals.view(np.float64)
        width = plan.fields.shape[1]
        out = {}
        for s in np.flatnonzero(self.pos).tolist():
            n, c, a, nf = int(self.pos[s]), int(self.cap[s]), int(self.row0[s]), int(plan.n_fields[s])
            out[s] = (self.out_t[a:a + n], self.out_log[a:a + n],
                      vals[a * width:a * width + nf * c].reshape(nf, c)[:, :n].T)
        located = []
        n_loc = int(self.n_loc[0])
        if n_loc:
            chunk = np.asarray(self.loc_chunk)
            slots, starts, lengths, logs = (x[:n_loc] for x in self.loc)
            for j in np.unique(chunk).tolist():
                sel = chunk == j
                located.append((self.bufs[j], slots[sel], starts[sel], lengths[sel], logs[sel]))
        return out, located
