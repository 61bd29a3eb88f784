"""Readers for Xsens MT Manager text exports and the Voisard et al. 2023 gait annotations.

MT Manager export (as in ``../shared/data/voisard_gait``): line 1 ``Acquisition frequency: <f> Hz``; line 2 a
tab-separated header containing ``PacketCounter Acc_X Acc_Y Acc_Z Gyr_X Gyr_Y Gyr_Z Mag_X Mag_Y Mag_Z``; then one
row per packet (acc m/s², gyr rad/s, mag in normalised units). Other columns are ignored. Gaps in the packet
counter (dropped packets) are reported in ``n_dropped`` and left as recorded by ``load_xsens_mt_txt``;
``on_packet_grid`` puts a recording on the gap-free packet grid (linear interpolation over dropped packets,
``filled`` marks them). The Voisard annotations index that grid (sample = packet − first packet): on 8-6 the
rows lag the reference heel strikes by exactly the packets dropped before them (12 at sample ~1096).

Voisard ``N-M.json`` (subject N, trial M): ``Subject``, ``Trial``, ``Age``, ``Gender``, ``Height`` (cm),
``Weight`` (kg), ``TrialBoundaries`` [start, end] and ``UTurnBoundaries`` [start, end] in samples,
``LeftFootEvents``/``RightFootEvents`` = list of [toe-off, heel-strike] sample pairs, one per footstep.
The data are AGPL-3.0: read them from ../shared/data, never copy them into the repository.
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["XsensRecording", "VoisardAnnotation", "VoisardTrial", "load_xsens_mt_txt", "load_voisard_json",
           "load_voisard_trial", "load_voisard_dir", "on_packet_grid", "XSENS_COLUMNS"]

XSENS_COLUMNS = ("PacketCounter", "Acc_X", "Acc_Y", "Acc_Z", "Gyr_X", "Gyr_Y", "Gyr_Z", "Mag_X", "Mag_Y", "Mag_Z")
_RATE = re.compile(r"frequency\s*:\s*([0-9.]+)\s*Hz", re.IGNORECASE)


@dataclass(frozen=True)
class XsensRecording:
    """acc (N, 3) m/s², gyr (N, 3) rad/s, mag (N, 3) normalised units, packet (N,) int; sensor frame."""
    acc: np.ndarray
    gyr: np.ndarray
    mag: np.ndarray
    packet: np.ndarray
    sampling_rate_hz: float
    n_dropped: int
    filled: np.ndarray | None = None


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


def load_xsens_mt_txt(path: Path | str) -> XsensRecording:
    """Read one MT Manager text export; raises ``ValueError`` naming the file and what is wrong."""
    path = Path(path)
    try:
        with open(path, encoding="utf-8", errors="strict") as f:
            first = f.readline()
            header = f.readline().rstrip("\r\n").split("\t")
            body = f.read()
    except (OSError, UnicodeDecodeError) as e:
        raise ValueError(f"{path}: not a readable text file ({e})") from e
    m = _RATE.search(first)
    if not m:
        raise ValueError(f"{path}: first line {first.strip()[:60]!r} is not 'Acquisition frequency: <f> Hz' "
                         "(expected an Xsens MT Manager text export)")
    fs = float(m.group(1))
    header = [h.strip() for h in header]
    missing = [c for c in XSENS_COLUMNS if c not in header]
    if missing:
        raise ValueError(f"{path}: header lacks {', '.join(missing)}; expected tab-separated "
                         f"{' '.join(XSENS_COLUMNS)}")
    rows = [ln.split("\t") for ln in body.splitlines() if ln.strip()]
    bad = [i for i, r in enumerate(rows) if len(r) != len(header)]
    if bad:
        raise ValueError(f"{path}: data line {bad[0] + 3} has {len(rows[bad[0]])} fields, header has {len(header)}")
    try:
        x = np.array(rows, dtype=float) if rows else np.empty((0, len(header)))
    except ValueError as e:
        raise ValueError(f"{path}: non-numeric value in the data ({e})") from e
    if x.shape[0] < 10 or not np.all(np.isfinite(x[:, [header.index(c) for c in XSENS_COLUMNS]])):
        raise ValueError(f"{path}: fewer than 10 rows or non-finite values")
    col = {c: x[:, header.index(c)] for c in XSENS_COLUMNS}
    packet = np.rint(col["PacketCounter"]).astype(np.int64)
    dp = np.diff(packet) % 65536                       # the MTw counter is 16-bit and wraps
    n_dropped = int(np.sum(np.maximum(dp - 1, 0)))
    stack = lambda p: np.column_stack([col[f"{p}_{a}"] for a in "XYZ"])  # noqa: E731
    return XsensRecording(acc=stack("Acc"), gyr=stack("Gyr"), mag=stack("Mag"), packet=packet,
                          sampling_rate_hz=fs, n_dropped=n_dropped)


def on_packet_grid(rec: XsensRecording) -> XsensRecording:
    """The recording on the gap-free packet grid (one row per packet from the first to the last; the 16-bit
    counter is unwrapped). Dropped packets are linearly interpolated and marked in ``filled`` (N,) bool;
    ``n_dropped`` is kept. A recording without gaps is returned with ``filled`` all False."""
    step = np.diff(rec.packet) % 65536
    if np.any(step == 0):
        raise ValueError("packet counter repeats a value; cannot place the rows on the packet grid")
    k = np.concatenate([[0], np.cumsum(step)]).astype(np.int64)          # unwrapped packet index from the first
    grid = np.arange(k[-1] + 1)
    filled = np.ones(len(grid), bool)
    filled[k] = False
    interp = lambda x: np.column_stack([np.interp(grid, k, x[:, i]) for i in range(x.shape[1])])  # noqa: E731
    return XsensRecording(acc=interp(rec.acc), gyr=interp(rec.gyr), mag=interp(rec.mag),
                          packet=(rec.packet[0] + grid) % 65536, sampling_rate_hz=rec.sampling_rate_hz,
                          n_dropped=rec.n_dropped, filled=filled)


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


def load_voisard_dir(directory: Path | str, *, packet_grid: bool = True) -> list[VoisardTrial]:
    """All trials of a folder (every ``N-M.json``) in subject, trial order; ``ValueError`` if there is none."""
    d = Path(directory)
    js = sorted((p for p in d.glob("*-*.json") if re.fullmatch(r"\d+-\d+", p.stem)), key=_trial_key)
    if not js:
        raise ValueError(f"{d}: no N-M.json files; expected the Voisard et al. gait data (see ../shared/data)")
    return [load_voisard_trial(d, p.stem, packet_grid=packet_grid) for p in js]
