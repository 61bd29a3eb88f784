"""Readers for Xsens MT Manager text exports and the Voisard et al. 2023 gait annotations.

Two preambles are read, then a tab-separated header containing ``PacketCounter Acc_X Acc_Y Acc_Z Gyr_X Gyr_Y
Gyr_Z Mag_X Mag_Y Mag_Z`` and one row per packet (acc m/s², gyr rad/s, mag in normalised units; other columns such
as ``SampleTimeFine`` or ``Quat_q0`` are ignored):

* the Voisard layout (``../shared/data/voisard_gait``): line 1 ``Acquisition frequency: <f> Hz``, line 2 the header;
* MT Manager's own export: any number of ``//`` comment lines (``// Start Time: …``, ``// Update Rate: 100.0Hz``,
  ``// Filter Profile: …``, ``// Option Flags: …``, ``// Firmware Version: …``, ``// Device ID: …``), the rate from
  the ``Update Rate`` line, then the header. Trailing tabs (MT Manager ends rows with one) are ignored.

Gaps in the packet counter (dropped packets) are reported in ``n_dropped`` and left as recorded by
``load_xsens_mt_txt``; ``on_packet_grid`` puts a recording on the gap-free packet grid (linear interpolation over
dropped packets, ``filled`` marks them). The Voisard annotations index that grid (sample = packet − first packet):
on 8-6 the rows lag the reference heel strikes by exactly the packets dropped before them (12 at sample ~1096).

Repeated packet counter (policy; ``packet_index``): a row whose counter does not advance on the last advancing row
(the same value again, or a step back by less than half the 16-bit range) is a *repeated* row. Its values differ
from its predecessor's, so it is a sample, not a duplicate, and nothing says which of the two is misnumbered:
the rows are **kept in file order**, the repeated row is placed one packet after the row before it, and the rows
after it keep their own counter unless that would put them at or before an earlier row (then they follow one
packet after it: the shift is absorbed by the next gap). The reader **warns** (``XsensPacketWarning``, naming the
file, the count and the first data line) and **counts** them in ``n_repeated``. Times and the packet grid then stay
strictly increasing, so the importer, the benches and the gait stage go on.

Voisard ``N-M.json`` (subject N, trial M): ``Subject``, ``Trial``, ``Age``, ``Gender``, ``Height`` (cm),
``Weight`` (kg), ``TrialBoundaries`` [start, end] and ``UTurnBoundaries`` [start, end] in samples,
``LeftFootEvents``/``RightFootEvents`` = list of [toe-off, heel-strike] sample pairs, one per footstep.
The data are AGPL-3.0: read them from ../shared/data, never copy them into the repository.
"""
from __future__ import annotations

import json
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["XsensRecording", "VoisardAnnotation", "VoisardTrial", "load_xsens_mt_txt", "load_voisard_json",
           "load_voisard_trial", "load_voisard_dir", "on_packet_grid", "packet_index", "XsensPacketWarning",
           "XSENS_COLUMNS"]

XSENS_COLUMNS = ("PacketCounter", "Acc_X", "Acc_Y", "Acc_Z", "Gyr_X", "Gyr_Y", "Gyr_Z", "Mag_X", "Mag_Y", "Mag_Z")
_RATE = re.compile(r"frequency\s*:\s*([0-9.]+)\s*Hz", re.IGNORECASE)
_MT_RATE = re.compile(r"update\s*rate\s*:\s*([0-9.]+)\s*Hz", re.IGNORECASE)
_HALF = 32768                      # half the 16-bit counter range: a larger forward step is a step back


class XsensPacketWarning(UserWarning):
    """A file's packet counter repeats (or steps back); the rows were kept in file order (module docstring)."""


@dataclass(frozen=True)
class XsensRecording:
    """acc (N, 3) m/s², gyr (N, 3) rad/s, mag (N, 3) normalised units, packet (N,) int; sensor frame.
    index (N,) int64: each row's place on the packet grid from the first row (``packet_index``); n_repeated: rows
    whose counter did not advance (policy in the module docstring)."""
    acc: np.ndarray
    gyr: np.ndarray
    mag: np.ndarray
    packet: np.ndarray
    sampling_rate_hz: float
    n_dropped: int
    filled: np.ndarray | None = None
    index: np.ndarray | None = None
    n_repeated: int = 0


@dataclass(frozen=True)
class VoisardAnnotation:
    """Subject data and reference events of one trial. Events are (K, 2) int sample indices, columns
    [toe-off, heel-strike] per footstep; boundaries are [start, end] samples."""
    subject: int
    trial: int
    age: float
    gender: str
    height_cm: float
    weight_kg: float
    trial_boundaries: np.ndarray
    uturn_boundaries: np.ndarray
    left_events: np.ndarray
    right_events: np.ndarray


@dataclass(frozen=True)
class VoisardTrial:
    """One trial: the annotation and the three recordings (left foot, right foot, lower back)."""
    name: str
    annotation: VoisardAnnotation
    left: XsensRecording
    right: XsensRecording
    lower_back: XsensRecording | None


def packet_index(packet: np.ndarray) -> tuple[np.ndarray, int, np.ndarray]:
    """(index, n_dropped, repeated rows) of the rows of a 16-bit packet counter (policy in the module docstring).

    index (N,) int64 strictly increasing, 0 at the first row: a row whose counter advances by 0 < Δ < 2¹⁵ on the
    last advancing row (mod 2¹⁶: the counter wraps) goes to that row's index + Δ, at least one after the row before
    it; any other row (a repeated value, a step back) is *repeated* and goes one after the row before it.
    n_dropped = packets the counter skips (Σ of gaps in ``index``); repeated = (R,) int64 row numbers."""
    p = np.asarray(packet, np.int64)
    if len(p) == 0:
        return np.zeros(0, np.int64), 0, np.zeros(0, np.int64)
    step = np.diff(p) % 65536
    if np.all((step > 0) & (step < _HALF)):                           # the normal case, vectorised
        idx = np.concatenate([[0], np.cumsum(step)]).astype(np.int64)
        return idx, int(idx[-1] - (len(p) - 1)), np.zeros(0, np.int64)
    idx = np.zeros(len(p), np.int64)
    ref_c, ref_i, rep = int(p[0]), 0, []
    for i in range(1, len(p)):
        d = (int(p[i]) - ref_c) % 65536
        if 0 < d < _HALF:
            idx[i] = max(idx[i - 1] + 1, ref_i + d)
            ref_c, ref_i = int(p[i]), int(idx[i])
        else:
            idx[i] = idx[i - 1] + 1
            rep.append(i)
    return idx, int(idx[-1] - (len(p) - 1)), np.array(rep, np.int64)


def _preamble(path: Path, lines: list[str]) -> tuple[float, int]:
    """(rate Hz, line number of the column header) of the Voisard or the MT Manager (``//``) layout."""
    if lines and lines[0].lstrip().startswith("//"):
        n = 0
        while n < len(lines) and lines[n].lstrip().startswith("//"):
            n += 1
        rates = [m.group(1) for ln in lines[:n] if (m := _MT_RATE.search(ln))]
        if not rates:
            raise ValueError(f"{path}: the '//' header has no '// Update Rate: <f>Hz' line; export again from MT "
                             "Manager with the header, or write 'Acquisition frequency: <f> Hz' as line 1")
        return float(rates[0]), n
    first = lines[0] if lines else ""
    m = _RATE.search(first)
    if not m:
        raise ValueError(f"{path}: first line {first.strip()[:60]!r} is not 'Acquisition frequency: <f> Hz' nor an "
                         "MT Manager '// …' header (expected an Xsens MT Manager text export)")
    return float(m.group(1)), 1


def load_xsens_mt_txt(path: Path | str) -> XsensRecording:
    """Read one MT Manager text export (either layout of the module docstring); raises ``ValueError`` naming the
    file and what is wrong; warns (``XsensPacketWarning``) when the packet counter repeats."""
    path = Path(path)
    try:
        with open(path, encoding="utf-8", errors="strict") as f:
            text = f.read()
    except (OSError, UnicodeDecodeError) as e:
        raise ValueError(f"{path}: not a readable text file ({e})") from e
    lines = text.splitlines()
    fs, h = _preamble(path, lines)
    if not fs > 0:
        raise ValueError(f"{path}: sampling rate {fs} Hz is not positive")
    if h >= len(lines):
        raise ValueError(f"{path}: no column header after the rate line; expected tab-separated "
                         f"{' '.join(XSENS_COLUMNS)}")
    header = [x.strip() for x in lines[h].rstrip("\r\n").split("\t")]
    while header and not header[-1]:
        header.pop()
    missing = [c for c in XSENS_COLUMNS if c not in header]
    if missing:
        raise ValueError(f"{path}: header lacks {', '.join(missing)}; expected tab-separated "
                         f"{' '.join(XSENS_COLUMNS)}")
    rows, line_no = [], []
    for i, ln in enumerate(lines[h + 1:], start=h + 2):
        if ln.strip():
            r = ln.rstrip("\r\n").split("\t")
            while len(r) > len(header) and not r[-1].strip():
                r.pop()
            rows.append(r)
            line_no.append(i)
    bad = [i for i, r in enumerate(rows) if len(r) != len(header)]
    if bad:
        raise ValueError(f"{path}: data line {line_no[bad[0]]} has {len(rows[bad[0]])} fields, header has "
                         f"{len(header)}")
    use = [header.index(c) for c in XSENS_COLUMNS]
    try:
        x = np.array([[r[j] for j in use] for r in rows], dtype=float) if rows else np.empty((0, len(use)))
    except ValueError as e:
        raise ValueError(f"{path}: non-numeric value in the data ({e})") from e
    if x.shape[0] < 10 or not np.all(np.isfinite(x)):
        raise ValueError(f"{path}: fewer than 10 rows or non-finite values")
    col = {c: x[:, i] for i, c in enumerate(XSENS_COLUMNS)}
    packet = np.rint(col["PacketCounter"]).astype(np.int64)
    index, n_dropped, repeated = packet_index(packet)
    n_rep = len(repeated)
    if n_rep:
        warnings.warn(f"{path}: packet counter repeats or steps back at {n_rep} row(s) (first at data line "
                      f"{line_no[int(repeated[0])]}); rows kept in file order, each repeated row placed one packet after the row before "
                      "it (pipeline/formats/xsens_mt.py policy)", XsensPacketWarning, stacklevel=2)
    stack = lambda p: np.column_stack([col[f"{p}_{a}"] for a in "XYZ"])  # noqa: E731
    return XsensRecording(acc=stack("Acc"), gyr=stack("Gyr"), mag=stack("Mag"), packet=packet,
                          sampling_rate_hz=fs, n_dropped=n_dropped, index=index, n_repeated=n_rep)


def on_packet_grid(rec: XsensRecording) -> XsensRecording:
    """The recording on the gap-free packet grid (one row per packet from the first to the last; the 16-bit
    counter is unwrapped; repeated counters placed by ``packet_index``). Dropped packets are linearly interpolated
    and marked in ``filled`` (N,) bool; ``n_dropped`` and ``n_repeated`` are kept. A recording without gaps is
    returned with ``filled`` all False."""
    k = rec.index if rec.index is not None else packet_index(rec.packet)[0]
    grid = np.arange(k[-1] + 1)
    filled = np.ones(len(grid), bool)
    filled[k] = False
    interp = lambda x: np.column_stack([np.interp(grid, k, x[:, i]) for i in range(x.shape[1])])  # noqa: E731
    return XsensRecording(acc=interp(rec.acc), gyr=interp(rec.gyr), mag=interp(rec.mag),
                          packet=(rec.packet[0] + grid) % 65536, sampling_rate_hz=rec.sampling_rate_hz,
                          n_dropped=rec.n_dropped, filled=filled, index=grid.astype(np.int64),
                          n_repeated=rec.n_repeated)


def _events(v, path, key) -> np.ndarray:
    a = np.asarray(v, dtype=float).reshape(-1, 2) if len(v) else np.empty((0, 2))
    if a.size and (not np.all(np.isfinite(a)) or np.any(a[:, 1] < a[:, 0])):
        raise ValueError(f"{path}: {key} must be [toe-off, heel-strike] pairs with heel-strike >= toe-off")
    return np.rint(a).astype(np.int64)


def load_voisard_json(path: Path | str) -> VoisardAnnotation:
    """Read one ``N-M.json`` annotation; raises ``ValueError`` naming the file and the missing/odd key."""
    path = Path(path)
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ValueError(f"{path}: not readable JSON ({e})") from e
    need = ("Subject", "Trial", "TrialBoundaries", "UTurnBoundaries", "LeftFootEvents", "RightFootEvents")
    missing = [k for k in need if k not in d]
    if missing:
        raise ValueError(f"{path}: missing key(s) {', '.join(missing)} (expected a Voisard et al. annotation)")
    try:
        tb = np.asarray(d["TrialBoundaries"], dtype=np.int64).reshape(2)
        ub = np.asarray(d["UTurnBoundaries"], dtype=np.int64).reshape(2)
        left = _events(d["LeftFootEvents"], path, "LeftFootEvents")
        right = _events(d["RightFootEvents"], path, "RightFootEvents")
    except (TypeError, ValueError) as e:
        if str(e).startswith(str(path)):
            raise
        raise ValueError(f"{path}: boundaries must be [start, end] and events [toe-off, heel-strike] pairs ({e})") \
            from e
    return VoisardAnnotation(subject=int(d["Subject"]), trial=int(d["Trial"]), age=float(d.get("Age", np.nan)),
                             gender=str(d.get("Gender", "")), height_cm=float(d.get("Height", np.nan)),
                             weight_kg=float(d.get("Weight", np.nan)), trial_boundaries=tb,
                             uturn_boundaries=ub, left_events=left, right_events=right)


def load_voisard_trial(directory: Path | str, name: str, *, packet_grid: bool = True) -> VoisardTrial:
    """Trial ``name`` ("N-M") of a Voisard folder: ``N-M.json``, ``N-M_lf.txt``, ``N-M_rf.txt`` (``_lb`` optional).
    ``packet_grid``: recordings on the gap-free packet grid the annotations index (``on_packet_grid``)."""
    d = Path(directory)
    need = [d / f"{name}.json", d / f"{name}_lf.txt", d / f"{name}_rf.txt"]
    missing = [p.name for p in need if not p.is_file()]
    if missing:
        raise ValueError(f"{d}: trial {name} lacks {', '.join(missing)}")
    lb = d / f"{name}_lb.txt"
    conv = on_packet_grid if packet_grid else (lambda r: r)
    read = lambda p: conv(load_xsens_mt_txt(p))  # noqa: E731
    return VoisardTrial(name=name, annotation=load_voisard_json(need[0]), left=read(need[1]), right=read(need[2]),
                        lower_back=read(lb) if lb.is_file() else None)


def _trial_key(p: Path):
    s, _, t = p.stem.partition("-")
    return (int(s), int(t)) if s.isdigit() and t.isdigit() else (10 ** 9, 0)


def voisard_truncated_copies(directory: Path | str) -> list[str]:
    """Trials of a Voisard folder whose sensor files are a byte-for-byte truncated copy of another trial of the same
    subject (the public set's trial 9-3 is the first 2270 lines of 9-4): one line per copy, for a bench's
    ``warnings``. Such a trial is scored as recorded, in its subject's fold, so it weighs that subject twice but
    leaks nothing between cross-validation folds."""
    d = Path(directory)
    by_subject: dict[str, list[Path]] = {}
    for p in sorted(d.glob("*-*_lf.txt")):
        by_subject.setdefault(p.name.split("-")[0], []).append(p)
    out = []
    for files in by_subject.values():
        data = {p: p.read_bytes() for p in files}
        for a in files:
            for b in files:
                if a != b and len(data[a]) < len(data[b]) and data[b].startswith(data[a]):
                    out.append(f"{d}: trial {a.name[:-7]} is a truncated copy of trial {b.name[:-7]} "
                               f"({a.name} is the first {len(data[a])} bytes of {b.name}); both are scored")
    return out


def load_voisard_dir(directory: Path | str, *, packet_grid: bool = True,
                     skipped: list | None = None) -> list[VoisardTrial]:
    """All trials of a folder (every ``N-M.json``) in subject, trial order; ``ValueError`` if there is none.

    ``skipped``: when a list is given, a trial that cannot be read is left out and ``(trial name, reason)`` appended
    to it (the reason names the file); without it the first bad trial raises its ``ValueError``."""
    d = Path(directory)
    js = sorted((p for p in d.glob("*-*.json") if re.fullmatch(r"\d+-\d+", p.stem)), key=_trial_key)
    if not js:
        raise ValueError(f"{d}: no N-M.json files; expected the Voisard et al. gait data (see ../shared/data)")
    out = []
    for p in js:
        try:
            out.append(load_voisard_trial(d, p.stem, packet_grid=packet_grid))
        except ValueError as e:
            if skipped is None:
                raise
            skipped.append((p.stem, str(e).splitlines()[0] if str(e) else type(e).__name__))
    return out
