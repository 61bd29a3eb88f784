"""The MCAP reader's one decode path for chunks: the decompressed chunks of a group walked record by record by one
numba kernel, every message decoded straight into one set of arrays per channel.

:class:`GroupDecoder` takes every chunk of every file (any writer, definitions inside chunks or not, any mix of
channels). Per chunk, right after its decompression (still in the core's cache), :func:`_walk` checks each record
as the recording format requires and, by the channel's *slot*:

- an all-double type (``sensor_msgs/msg/Imu``, ``MagneticField``, ``geometry_msgs/msg/PoseStamped``): the message's
  ``header.stamp``, ``log_time`` and selected doubles are decoded, bit for bit, at the channel's next row (the CDR
  layout and checks of :func:`stridelab.pipeline.formats.ros2_cdr.decode_doubles`);
- a channel StrideLab does not decode: the message is counted;
- :data:`LOCATE`: the message's position is kept and decoded once the group is walked, by the decoder of its layout
  (``sensor_msgs/msg/Range``: a vectorised kernel over the located messages; annotations, which hold strings and
  JSON: per message) -- and the messages of a channel that no definition known to this group names yet, decoded
  by the reader once the definitions before them are registered.

The walk stops, at a record boundary and without side effects, for what only Python can do: a Schema or Channel
record (the reader registers it and gives the new channel a slot), a message on a channel without a slot (given a
:data:`LOCATE` slot), a channel out of room (its rows are moved to larger arrays), and anything wrong (the reader
raises the one-line error); then it resumes where it stopped. A group is never decoded twice, and what is an error
is decided here, in file order. Messages outside chunks (unchunked files, rosbag2 SQLite bags, messages
compressed one by one) come as lists of positions and are decoded by the vectorised kernels of
:mod:`~stridelab.pipeline.formats.ros2_cdr`; the all-double layout is written out in both (a numba function
shared by both, even inlined, made the walk 40-60 % slower), and the tests check them against each other and
against mcap_ros2's decoder.
"""
from __future__ import annotations

import numpy as np
from numba import njit


#: ``slot_of`` value of a channel without a slot (not defined yet)
NO_SLOT = -1
#: ``n_doubles`` of a slot whose messages are only located (start, length, log_time), decoded after the walk
LOCATE = -1

# what :func:`_walk` returns (the record concerned at ``at[0]``); BAD_MESSAGE + the decoder's status (1-4)
DONE, DEFINE, UNKNOWN_CHANNEL, ROOM, SHORT_MESSAGE, NOT_FILLED, IMPOSSIBLE_LENGTH = 0, 1, 2, 3, 4, 5, 6
BAD_MESSAGE = 16

OP_SCHEMA, OP_CHANNEL, OP_MESSAGE = 0x03, 0x04, 0x05


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
        ulen = _u64(buf, p + 1)
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
            loc_log[j] = np.int64(_u64(buf, q + 6))
            n_loc[0] = j + 1
        elif nd > 0:
            i = fill[s]
            c = cap[s]
            if i >= c:
                at[0] = p
                return ROOM
            r = row0[s] + i
            # the message's CDR (the layout and checks of ros2_cdr.decode_doubles_kernel, written out here: a
            # function shared by both, even inlined, made this walk 40-60 % slower)
            m = q + 22
            L = length - 22
            st = 0
            if L < 16:
                st = 2
            elif buf[m] != 0 or buf[m + 1] != 1:
                st = 1
            else:
                sec = np.int64(np.int32(_u32(buf, m + 4)))
                nsec = np.int64(_u32(buf, m + 8))
                slen = np.int64(_u32(buf, m + 12))
                body = m + 4 + (16 + slen - 4 + 7) // 8 * 8
                need = body - m + 8 * nd
                if need > L:
                    st = 2
                elif L - need > 3:
                    st = 3
                elif nsec >= 1_000_000_000:
                    st = 4
                else:
                    out_t[r] = sec * 1_000_000_000 + nsec
                    base = row0[s] * width + i
                    for k in range(n_fields[s]):
                        out_vals[base + k * c] = _u64(buf, body + 8 * fields[s, k])
            if st:
                at[0] = p
                return BAD_MESSAGE + st
            out_log[r] = np.int64(_u64(buf, q + 6))
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
        ulen = _u64(buf, p + 1)
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


class Slots:
    """The slot tables of a set of channels: ``specs`` channel id -> ``(doubles after the header, field indices)``
    for a decoded type, None for a channel whose messages are only counted, :data:`LOCATE` for one decoded after
    the walk. Made once per registry snapshot and shared read-only by its groups (a group that adds a slot copies)."""

    def __init__(self, specs: dict[int, tuple[int, np.ndarray] | None | int]):
        self.channel_ids: list[int] = []
        self.slot_of = np.full(1 << 16, NO_SLOT, dtype=np.int64)
        self.specs: list = []
        for cid in sorted(specs):
            self.append(cid, specs[cid])
        self.pack()

    def append(self, cid: int, spec) -> None:
        self.slot_of[cid] = len(self.channel_ids)
        self.channel_ids.append(cid)
        self.specs.append(spec)

    def pack(self) -> None:
        specs = self.specs
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

    def copy(self) -> "Slots":
        out = Slots.__new__(Slots)
        out.channel_ids, out.slot_of, out.specs = list(self.channel_ids), self.slot_of.copy(), list(self.specs)
        out.pack()
        return out


class GroupDecoder:
    """Decodes the chunks of one group, each right after its decompression, into arrays sized for the group from
    the first chunk's message density (2 % and 64 rows of slack per slot) and grown when a channel outgrows them.

    ``slots``: the :class:`Slots` of the channels known when the group starts (or their specs as a dict).
    :meth:`walk` returns None when a chunk is done, else ``(status, position)`` for the caller (definitions, unknown
    channels, errors), which then calls :meth:`add_slot` or raises, and walks again from where it says."""

    def __init__(self, slots: "Slots | dict", group_bytes: int):
        self.group_bytes = group_bytes
        self._use(slots if isinstance(slots, Slots) else Slots(slots))
        self._own = False
        self.fill = np.zeros(len(self.channel_ids), dtype=np.int64)
        self.counts = np.zeros(len(self.channel_ids), dtype=np.int64)
        self.cap = None
        self.at = np.zeros(1, dtype=np.int64)
        self.n_loc = np.zeros(1, dtype=np.int64)
        self.loc = [np.empty(LOCATE_ROOM, dtype=np.int64) for _ in range(4)]
        self.loc_chunk: list[int] = []
        self.bufs: list[np.ndarray] = []

    # -- slots ----------------------------------------------------------------------------------------------
    def _use(self, slots: Slots) -> None:
        self.slots = slots
        self.channel_ids, self.slot_of = slots.channel_ids, slots.slot_of
        self.fields, self.n_doubles, self.n_fields = slots.fields, slots.n_doubles, slots.n_fields

    def add_slot(self, cid: int, spec) -> None:
        """Give channel ``cid`` (without a slot so far) a slot: its messages from the current record on are decoded
        (or counted, or located) by ``spec``."""
        old_width = self.fields.shape[1]
        slots = self.slots if self._own else self.slots.copy()
        self._own = True
        slots.append(cid, spec)
        slots.pack()
        self._use(slots)
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
