"""The MCAP reader's one decode path: the decompressed chunks of a group walked record by record by one numba
kernel, every message decoded straight into one set of arrays per channel.

:class:`GroupDecoder` takes every chunk of every file (any writer, definitions inside chunks or not, any mix of
channels). Per chunk, right after its decompression (still in the core's cache), :func:`_walk` checks each record
as the recording format requires and, by the channel's *slot*:

- an all-double type (``sensor_msgs/msg/Imu``, ``MagneticField``, ``geometry_msgs/msg/PoseStamped``): the message
  is decoded by :func:`stridelab.pipeline.formats.ros2_cdr.decode_doubles_at` (``header.stamp``, ``log_time`` and
  the selected doubles, bit for bit) at the channel's next row;
- a channel StrideLab does not decode: the message is counted;
- :data:`LOCATE`: the message's position is kept and decoded once the group is walked, by the decoder of its layout
  (``sensor_msgs/msg/Range``: a vectorised kernel over the located messages; annotations, which hold strings and
  JSON: per message) -- and the messages of a channel that no definition known to this group names yet, decoded
  by the reader once the definitions before them are registered.

The walk stops, at a record boundary and without side effects, for what only Python can do: a Schema or Channel
record (the reader registers it and gives the new channel a slot), a message on a channel without a slot (given a
:data:`LOCATE` slot), a channel out of room (its rows are moved to larger arrays), and anything wrong (the reader
raises the one-line error); then it resumes where it stopped. There is no other path: a group is never decoded
twice, and what is an error is decided here, in file order.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from stridelab.pipeline.formats.ros2_cdr import decode_doubles_at, u64

#: ``slot_of`` value of a channel without a slot (not defined yet)
NO_SLOT = -1
#: ``n_doubles`` of a slot whose messages are only located (start, length, log_time), decoded after the walk
LOCATE = -1

# what :func:`_walk` returns (the record concerned at ``at[0]``); BAD_MESSAGE + the decoder's status (1-4)
DONE, DEFINE, UNKNOWN_CHANNEL, ROOM, SHORT_MESSAGE, NOT_FILLED, IMPOSSIBLE_LENGTH = 0, 1, 2, 3, 4, 5, 6
BAD_MESSAGE = 16

OP_SCHEMA, OP_CHANNEL, OP_MESSAGE = 0x03, 0x04, 0x05


@njit(cache=True, nogil=True)
def _walk(buf, p, slot_of, n_doubles, fields, n_fields, row0, cap, fill, counts, out_t, out_log, out_vals,
          loc_slot, loc_start, loc_len, loc_log, n_loc, at):
    """Walk the records of ``buf`` (one decompressed chunk) from ``p``: slot ``s`` owns rows ``row0[s] .. row0[s] +
    cap[s]`` of ``out_t``/``out_log`` and, field by field, the same span (times its field index) of ``out_vals``
    (uint64 words of the float64 values, so NaN payloads survive); ``fill[s]`` rows are used. Messages of
    :data:`LOCATE` slots go to ``loc_*`` (slot, payload start and length, log_time) from ``n_loc[0]`` on.
    ``counts[s]`` counts every message of slot ``s``, decoded or not. Records other than Schema, Channel and
    Message are skipped (the specification allows no others inside a chunk).

    Returns :data:`DONE` when the records fill ``buf`` exactly; otherwise stops before the record at ``at[0]``
    (nothing of it written) with :data:`DEFINE` (a Schema or Channel record), :data:`UNKNOWN_CHANNEL`,
    :data:`ROOM` (its slot or the located messages are full), :data:`SHORT_MESSAGE` (a Message record shorter
    than its fixed fields), :data:`NOT_FILLED` (a record runs past the chunk, or bytes are left over),
    :data:`IMPOSSIBLE_LENGTH` (a length above 2**62) or :data:`BAD_MESSAGE` + the decoder's status.
    """
    end = buf.shape[0]
    width = fields.shape[1]
    while p + 9 <= end:
        ulen = u64(buf, p + 1)
        if ulen > np.uint64(1) << np.uint64(62):
            at[0] = p
            return IMPOSSIBLE_LENGTH
        length = np.int64(ulen)
        q = p + 9
        if q + length > end:
            at[0] = p
            return NOT_FILLED
        op = buf[p]
        if op != OP_MESSAGE:
            if op == OP_SCHEMA or op == OP_CHANNEL:
                at[0] = p
                return DEFINE
            p = q + length
            continue
        if length < 22:
            at[0] = p
            return SHORT_MESSAGE
        s = slot_of[np.int64(buf[q]) | (np.int64(buf[q + 1]) << 8)]
        if s < 0:
            at[0] = p
            return UNKNOWN_CHANNEL
        nd = n_doubles[s]
        if nd < 0:
            j = n_loc[0]
            if j >= loc_slot.shape[0]:
                at[0] = p
                return ROOM
            loc_slot[j] = s
            loc_start[j] = q + 22
            loc_len[j] = length - 22
            loc_log[j] = np.int64(u64(buf, q + 6))
            n_loc[0] = j + 1
        elif nd > 0:
            i = fill[s]
            c = cap[s]
            if i >= c:
                at[0] = p
                return ROOM
            r = row0[s] + i
            st = decode_doubles_at(buf, q + 22, length - 22, nd, fields[s], n_fields[s], out_t, r, out_vals,
                                   row0[s] * width + i, c)
            if st:
                at[0] = p
                return BAD_MESSAGE + st
            out_log[r] = np.int64(u64(buf, q + 6))
            fill[s] = i + 1
        counts[s] += 1
        p = q + length
    at[0] = p
    return DONE if p == end else NOT_FILLED


@njit(cache=True, nogil=True)
def _count(buf, slot_of, counts):
    """Add each slot's messages in ``buf`` (one decompressed chunk) to ``counts`` (to size the group's arrays);
    stops quietly at anything unusual (the walk reports it)."""
    end = buf.shape[0]
    p = 0
    while p + 9 <= end:
        ulen = u64(buf, p + 1)
        if ulen > np.uint64(end):
            return
        q = p + 9
        nxt = q + np.int64(ulen)
        if nxt > end:
            return
        if buf[p] == OP_MESSAGE and ulen >= np.uint64(22):
            s = slot_of[np.int64(buf[q]) | (np.int64(buf[q + 1]) << 8)]
            if s >= 0:
                counts[s] += 1
        p = nxt


#: room for located messages (annotations, ranges, channels defined later) per group, grown when full
LOCATE_ROOM = 4096
#: rows of a channel first met after the arrays were sized (doubled whenever full)
NEW_SLOT_ROWS = 256


class GroupDecoder:
    """Decodes the chunks of one group, each right after its decompression, into arrays sized for the group from
    the first chunk's message density (2 % and 64 rows of slack per slot) and grown when a channel outgrows them.

    ``slots``: channel id -> ``(doubles after the header, field indices)`` for a decoded type, None for a channel
    whose messages are only counted, :data:`LOCATE` for one decoded after the walk. :meth:`walk` returns None when
    a chunk is done, else ``(status, position)`` for the caller (definitions, unknown channels, errors), which then
    calls :meth:`add_slot` or raises, and walks again from where it says."""

    def __init__(self, slots: dict[int, tuple[int, np.ndarray] | None | int], group_bytes: int):
        self.group_bytes = group_bytes
        self.channel_ids: list[int] = []
        self.slot_of = np.full(1 << 16, NO_SLOT, dtype=np.int64)
        self._specs: list = []
        for cid in sorted(slots):
            self._append(cid, slots[cid])
        self._pack()
        self.fill = np.zeros(len(self.channel_ids), dtype=np.int64)
        self.counts = np.zeros(len(self.channel_ids), dtype=np.int64)
        self.cap = None
        self.at = np.zeros(1, dtype=np.int64)
        self.n_loc = np.zeros(1, dtype=np.int64)
        self.loc = [np.empty(LOCATE_ROOM, dtype=np.int64) for _ in range(4)]
        self.loc_chunk: list[int] = []
        self.bufs: list[np.ndarray] = []

    # -- slots ----------------------------------------------------------------------------------------------
    def _append(self, cid: int, spec) -> None:
        self.slot_of[cid] = len(self.channel_ids)
        self.channel_ids.append(cid)
        self._specs.append(spec)

    def _pack(self) -> None:
        specs = self._specs
        width = max([len(v[1]) for v in specs if isinstance(v, tuple)] + [1])
        self.fields = np.zeros((len(specs), width), dtype=np.int64)
        self.n_doubles = np.zeros(len(specs), dtype=np.int64)
        self.n_fields = np.zeros(len(specs), dtype=np.int64)
        for s, v in enumerate(specs):
            if isinstance(v, tuple):
                self.n_doubles[s], self.n_fields[s] = v[0], len(v[1])
                self.fields[s, :len(v[1])] = v[1]
            elif v is not None:
                self.n_doubles[s] = LOCATE

    def add_slot(self, cid: int, spec) -> None:
        """Give channel ``cid`` (without a slot so far) a slot: its messages from the current record on are decoded
        (or counted, or located) by ``spec``."""
        old_width = self.fields.shape[1]
        self._append(cid, spec)
        self._pack()
        self.fill = np.append(self.fill, 0)
        self.counts = np.append(self.counts, 0)
        if self.cap is not None:
            self._relayout(np.append(self.cap, 0), old_width)

    def slot_channel(self, slot: int) -> int:
        return self.channel_ids[slot]

    # -- arrays ---------------------------------------------------------------------------------------------
    def _size(self, first: np.ndarray) -> None:
        counts = np.zeros(len(self.channel_ids), dtype=np.int64)
        _count(first, self.slot_of, counts)
        dens = counts / max(1, len(first))
        cap = np.where(self.n_doubles > 0, np.ceil(dens * self.group_bytes * 1.02) + 64, 0).astype(np.int64)
        cap[counts == 0] = 0
        self._relayout(cap, self.fields.shape[1])

    def _relayout(self, cap: np.ndarray, old_width: int) -> None:
        """(Re)allocate the arrays for ``cap`` rows per slot, moving the rows decoded so far."""
        width = self.fields.shape[1]
        row0 = np.concatenate([[0], np.cumsum(cap)[:-1]]).astype(np.int64)
        total = int(cap.sum())
        out_t = np.empty(total, dtype=np.int64)
        out_log = np.empty(total, dtype=np.int64)
        out_vals = np.empty(total * width, dtype=np.uint64)
        if self.cap is not None:
            for s in np.flatnonzero(self.fill[:len(self.cap)]).tolist():
                n, a, b, c, nf = (int(self.fill[s]), int(self.row0[s]), int(row0[s]), int(self.cap[s]),
                                  int(self.n_fields[s]))
                out_t[b:b + n] = self.out_t[a:a + n]
                out_log[b:b + n] = self.out_log[a:a + n]
                old = self.out_vals[a * old_width:a * old_width + nf * c].reshape(nf, c)[:, :n]
                out_vals[b * width:b * width + nf * int(cap[s])].reshape(nf, int(cap[s]))[:, :n] = old
        self.cap, self.row0, self.out_t, self.out_log, self.out_vals = cap.astype(np.int64), row0, out_t, out_log, \
            out_vals

    def _grow(self, pos: int, buf: np.ndarray) -> None:
        """Room for the record at ``pos``: its slot's rows doubled, or the located messages' room."""
        s = int(self.slot_of[int(buf[pos + 9]) | (int(buf[pos + 10]) << 8)])
        if self.n_doubles[s] < 0:
            self.loc = [np.concatenate([x, np.empty(len(x), dtype=np.int64)]) for x in self.loc]
            return
        cap = self.cap.copy()
        cap[s] = max(NEW_SLOT_ROWS, 2 * int(cap[s]))
        self._relayout(cap, self.fields.shape[1])

    # -- walking --------------------------------------------------------------------------------------------
    def begin(self, raw: bytes) -> np.ndarray:
        """The next chunk's bytes as the array :meth:`walk` takes."""
        b = np.frombuffer(raw, dtype=np.uint8)
        if self.cap is None:
            self._size(b)
        self.loc_start_of_chunk = int(self.n_loc[0])
        return b

    def walk(self, buf: np.ndarray, p: int = 0) -> tuple[int, int] | None:
        """Walk ``buf`` (from :meth:`begin`) from ``p``; None when done, else ``(status, position)``."""
        while True:
            status = _walk(buf, p, self.slot_of, self.n_doubles, self.fields, self.n_fields, self.row0, self.cap,
                           self.fill, self.counts, self.out_t, self.out_log, self.out_vals, *self.loc, self.n_loc,
                           self.at)
            p = int(self.at[0])
            if status == ROOM:
                self._grow(p, buf)
                continue
            if status == DONE:
                n = int(self.n_loc[0]) - self.loc_start_of_chunk
                if n:                            # kept only while located messages point into it
                    self.bufs.append(buf)
                    self.loc_chunk += [len(self.bufs) - 1] * n
                return None
            return status, p

    def result(self):
        """``{slot: (t_ns, log_ns, values (N, fields) float64, each column contiguous)}`` of the decoded slots, and
        ``[(buf, slots, starts, lengths, log_ns)]`` of the located messages per chunk, in file order
        (:attr:`counts`: every slot's messages)."""
        vals = self.out_vals.view(np.float64) if self.cap is not None else None
        width = self.fields.shape[1]
        out = {}
        for s in np.flatnonzero(self.fill).tolist():
            n, c, a, nf = int(self.fill[s]), int(self.cap[s]), int(self.row0[s]), int(self.n_fields[s])
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
