"""Reader for the Mobilise-D standardized ``data.mat`` format (Palmerini et al., *Sci Data* 10:38, 2023,
"Mobility recorded by wearable devices and gold standards: the Mobilise-D procedure for data standardization").

Layout of ``data.mat`` (MATLAB struct ``data``)::

    data.<TimeMeasureN>.<TestM>.<TrialK>
        StartDateTime  'YYYY-MM-DDThh:mm:ss.fff+hh:mm'   TimeZone 'Europe/Berlin'
        SU.LowerBack   Acc (N,3) g · Gyr (N,3) deg/s · Mag (N,3) µT · Bar (N,) hPa · Timestamp (N,) unix s · Fs.Acc Hz
        Standards.<System>  (INDIP, Stereophoto, ...)
            MicroWB / ContinuousWalkingPeriod   one struct or a struct array, one element per walking bout:
                Start, End (s from the trial start), Cadence (steps/min), AverageStrideLength (m),
                WalkingSpeed (m/s), NumberStrides, InitialContact_Event (s), InitialContact_LeftRight
                ('Left'/'Right'), Turn_Start, Turn_End (s), Turn_Angle (deg), ...
            Fs

Beside it ``infoForAlgo.mat`` (struct ``infoForAlgo.<TimeMeasureN>``): Height (cm), Weight (kg), SensorHeight
(cm, height of the lower-back sensor above the floor), WalkingAid_01, Handedness, optionally LegLength (cm).
The participant is named by the last two folders of the file (``HA/001`` → ``HA-001``, cohort ``HA``).

Units out (StrideLab's): acceleration m/s² (the file's g × 9.81, the constant mobgap's loader uses), angular
rate rad/s (deg/s × π/180), magnetic field as stored; axes as stored (the McRoberts sensor at L5: x vertical,
y medio-lateral, z anterior-posterior; see docs/walking_at_home.md for the body frame the stage detects).
Both MATLAB v5/v7 files (scipy) and v7.3 files (HDF5, h5py) are read. Malformed input raises ``ValueError``
with one line naming the file, what is wrong and what to do.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import numpy as np

__all__ = ["MobilisedInfo", "MobilisedReference", "MobilisedTrial", "find_mobilised_files", "read_mobilised",
           "read_mobilised_info", "G_M_S2"]

G_M_S2 = 9.81                      # g → m/s², as mobgap's load_mobilised_matlab_format
_BOUT_KINDS = ("MicroWB", "ContinuousWalkingPeriod")


@dataclass(frozen=True)
class MobilisedInfo:
    """``infoForAlgo`` of one time measure; ``None`` where the file has no value."""
    height_m: float | None = None
    weight_kg: float | None = None
    sensor_height_m: float | None = None
    leg_length_m: float | None = None
    walking_aid: bool | None = None
    handedness: str | None = None


@dataclass(frozen=True)
class MobilisedReference:
    """One reference system's walking bouts of one kind (``MicroWB`` or ``ContinuousWalkingPeriod``).

    Per bout (B,): ``start_s``, ``end_s`` (s from the trial start), ``n_strides``, ``cadence_spm`` (steps/min),
    ``stride_length_m`` (bout average), ``walking_speed_m_s``; NaN where the file has no value.
    Initial contacts (I,): ``ic_s`` (s from the trial start), ``ic_side`` ('left'/'right'/''), ``ic_bout`` (index
    of the bout; contacts stored as NaN are dropped). Turns (T,): ``turn_start_s``, ``turn_end_s``, ``turn_angle_deg`` (signed, as stored)."""
    system: str
    kind: str
    start_s: np.ndarray
    end_s: np.ndarray
    n_strides: np.ndarray
    cadence_spm: np.ndarray
    stride_length_m: np.ndarray
    walking_speed_m_s: np.ndarray
    ic_s: np.ndarray
    ic_side: np.ndarray
    ic_bout: np.ndarray
    turn_start_s: np.ndarray
    turn_end_s: np.ndarray
    turn_angle_deg: np.ndarray


@dataclass(frozen=True)
class MobilisedTrial:
    """One ``TimeMeasure/Test/Trial`` of one participant: the lower-back SU and the references.

    ``acc`` (N, 3) m/s², ``gyr`` (N, 3) rad/s, ``mag`` (N, 3) as stored or None, sensor frame of the file;
    ``start_utc_ns`` = the first sample (``StartDateTime``, else ``Timestamp[0]``) in ns since the epoch (UTC);
    ``timezone`` the IANA name of the file (or the UTC offset of ``StartDateTime`` when absent)."""
    path: Path
    participant_id: str
    cohort: str
    time_measure: str
    test: str
    trial: str
    fs_hz: float
    start_utc_ns: int
    timezone: str
    acc: np.ndarray
    gyr: np.ndarray
    mag: np.ndarray | None
    references: tuple[MobilisedReference, ...]
    info: MobilisedInfo

    @property
    def name(self) -> str:
        return f"{self.participant_id}_{self.time_measure}_{self.test}_{self.trial}"

    def reference(self, system: str, kind: str = "MicroWB") -> MobilisedReference | None:
        for r in self.references:
            if r.system == system and r.kind == kind:
                return r
        return None


# --------------------------------------------------------------------------------------------------- loading

def _load_mat(path: Path, var: str, what: str) -> dict:
    """The struct ``var`` of a MATLAB file as nested dicts / lists / arrays (v5/v7 via scipy, v7.3 via h5py)."""
    import scipy.io as sio
    if not path.is_file():
        raise ValueError(f"{path}: file not found; expected a Mobilise-D {what}")
    try:
        m = sio.loadmat(path, simplify_cells=True, variable_names=[var])
    except NotImplementedError:                      # v7.3 = HDF5
        m = _load_mat73(path, var, what)
    except (OSError, ValueError, TypeError, sio.matlab.MatReadError) as e:
        raise ValueError(f"{path}: not a readable MATLAB file ({e}); expected a Mobilise-D {what}") from e
    if var not in m:
        raise ValueError(f"{path}: no variable '{var}'; a Mobilise-D {what} holds the struct '{var}'")
    if not isinstance(m[var], dict):
        raise ValueError(f"{path}: '{var}' is not a struct; expected the Mobilise-D standardized {what}")
    return m


def _load_mat73(path: Path, var: str, what: str) -> dict:
    import h5py
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        raise ValueError(f"{path}: not a readable MATLAB v7.3 (HDF5) file ({e}); expected a Mobilise-D {what}") from e
    with f:
        if var not in f:
            return {}
        return {var: _h5(f, f[var])}


def _h5(f, node):
    """MATLAB v7.3 node → Python: groups → dict, char → str, cell/struct arrays (references) → list, numeric →
    array in MATLAB's (row, column) order, 1×1 → scalar, 1×n / n×1 → 1-D."""
    import h5py
    if isinstance(node, h5py.Group):
        return {k: _h5(f, node[k]) for k in node.keys() if not k.startswith("#")}
    cls = node.attrs.get("MATLAB_class", b"")
    cls = cls.decode() if isinstance(cls, bytes) else str(cls)
    if node.attrs.get("MATLAB_empty", 0):
        return np.zeros(0)
    data = node[()]
    if data.dtype == h5py.ref_dtype or data.dtype.kind == "O":
        items = [_h5(f, f[r]) for r in np.asarray(data).T.ravel()]
        return items[0] if len(items) == 1 else items
    data = np.asarray(data).T
    if cls == "char":
        return "".join(chr(c) for c in data.ravel())
    if data.size == 1:
        return data.ravel()[0].item()
    if data.ndim == 2 and 1 in data.shape:
        return data.ravel()
    return data


def _arr(x, dtype=float) -> np.ndarray:
    if x is None:
        return np.zeros(0, dtype)
    a = np.atleast_1d(np.asarray(x))
    if a.dtype.kind in "USO" and dtype is not object:
        return np.zeros(0, dtype)
    return a.astype(dtype).ravel()


def _num(d: dict, key: str) -> float:
    v = d.get(key)
    try:
        a = np.asarray(v, float).ravel()
    except (TypeError, ValueError):
        return float("nan")
    return float(a[0]) if a.size == 1 else float("nan")


def _reference(path: Path, where: str, system: str, kind: str, node, fs: float) -> MobilisedReference:
    bouts = node if isinstance(node, list) else [node]
    if not all(isinstance(b, dict) for b in bouts):
        raise ValueError(f"{path}: {where}.{system}.{kind} is not a struct (array); expected walking bouts "
                         "with Start/End in s (Mobilise-D standardized format)")
    cols: dict[str, list] = {k: [] for k in ("start", "end", "ns", "cad", "sl", "ws")}
    ic, side, ib, ts, te, ta = [], [], [], [], [], []
    for i, b in enumerate(bouts):
        if "Start" not in b or "End" not in b:
            raise ValueError(f"{path}: {where}.{system}.{kind}({i + 1}) has no Start/End; each walking bout "
                             "needs Start and End in s")
        s, e = _num(b, "Start"), _num(b, "End")
        if not (np.isfinite(s) and np.isfinite(e) and e >= s):
            raise ValueError(f"{path}: {where}.{system}.{kind}({i + 1}) Start {s} / End {e} are not a valid "
                             "interval in s; fix or drop the bout")
        cols["start"].append(s)
        cols["end"].append(e)
        cols["ns"].append(_num(b, "NumberStrides"))
        cols["cad"].append(_num(b, "Cadence"))
        cols["sl"].append(_num(b, "AverageStrideLength"))
        cols["ws"].append(_num(b, "WalkingSpeed"))
        t = _arr(b.get("InitialContact_Event"))
        lr = b.get("InitialContact_LeftRight")
        lr = [lr] if isinstance(lr, str) else ([] if lr is None else list(np.atleast_1d(np.asarray(lr, object))))
        sides = [str(x).strip().lower() if str(x).strip().lower() in ("left", "right") else "" for x in lr]
        if sides and len(sides) != t.size:
            raise ValueError(f"{path}: {where}.{system}.{kind}({i + 1}) has {t.size} InitialContact_Event but "
                             f"{len(sides)} InitialContact_LeftRight; they must pair one to one")
        sides = sides or [""] * t.size
        keep = np.isfinite(t)                 # Stereophoto marks a contact it could not time with NaN: dropped
        ic.extend(t[keep].tolist())
        side.extend(x for x, k in zip(sides, keep) if k)
        ib.extend([i] * int(keep.sum()))
        t0, t1, ang = _arr(b.get("Turn_Start")), _arr(b.get("Turn_End")), _arr(b.get("Turn_Angle"))
        if t0.size == t1.size:
            ts.extend(t0.tolist())
            te.extend(t1.tolist())
            ta.extend(ang.tolist() if ang.size == t0.size else [np.nan] * t0.size)
    f = lambda k: np.asarray(cols[k], float)  # noqa: E731
    return MobilisedReference(
        system=system, kind=kind, start_s=f("start"), end_s=f("end"),
        n_strides=np.nan_to_num(f("ns"), nan=-1).astype(np.int64), cadence_spm=f("cad"),
        stride_length_m=f("sl"), walking_speed_m_s=f("ws"), ic_s=np.asarray(ic, float),
        ic_side=np.asarray(side, dtype="<U5"), ic_bout=np.asarray(ib, np.int64), turn_start_s=np.asarray(ts, float),
        turn_end_s=np.asarray(te, float), turn_angle_deg=np.asarray(ta, float))


def _start(path: Path, where: str, trial: dict, ts: np.ndarray) -> tuple[int, str]:
    tz = trial.get("TimeZone")
    tz = tz if isinstance(tz, str) and tz.strip() else ""
    sdt = trial.get("StartDateTime")
    if isinstance(sdt, str) and sdt.strip():
        try:
            dt = datetime.fromisoformat(sdt.strip().replace("Z", "+00:00"))
        except ValueError as e:
            raise ValueError(f"{path}: {where}.StartDateTime '{sdt}' is not ISO 8601 with an offset "
                             "(e.g. 2020-12-10T13:57:44.733+01:00); fix it") from e
        if dt.tzinfo is None:
            raise ValueError(f"{path}: {where}.StartDateTime '{sdt}' has no UTC offset; it cannot be placed in "
                             "time. Add the offset (e.g. +01:00)")
        us = round(dt.timestamp() * 1e6)
        return int(us) * 1000, tz or dt.strftime("%z")
    if ts.size and np.isfinite(ts[0]) and ts[0] > 0:
        return int(round(float(ts[0]) * 1e6)) * 1000, tz or "UTC"
    raise ValueError(f"{path}: {where} has neither StartDateTime nor SU.LowerBack.Timestamp; the trial cannot be "
                     "placed in time")


def _imu(path: Path, where: str, su: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, float, np.ndarray]:
    for k in ("Acc", "Gyr"):
        if k not in su:
            raise ValueError(f"{path}: {where}.SU.LowerBack has no {k}; the lower-back SU needs Acc (g) and "
                             "Gyr (deg/s)")
    acc = np.asarray(su["Acc"], float)
    gyr = np.asarray(su["Gyr"], float)
    if acc.ndim != 2 or acc.shape[1] != 3 or gyr.shape != acc.shape or acc.shape[0] < 2:
        raise ValueError(f"{path}: {where}.SU.LowerBack Acc {acc.shape} / Gyr {gyr.shape}: expected two (N, 3) "
                         "arrays of the same length")
    if not (np.all(np.isfinite(acc)) and np.all(np.isfinite(gyr))):
        raise ValueError(f"{path}: {where}.SU.LowerBack Acc/Gyr hold NaN or Inf samples; StrideLab does not "
                         "store data it can see is corrupt. Export the trial again")
    fs_node = su.get("Fs")
    fs = _num(fs_node, "Acc") if isinstance(fs_node, dict) else _num(su, "Fs")
    if not (np.isfinite(fs) and fs > 0):
        raise ValueError(f"{path}: {where}.SU.LowerBack.Fs is missing or not positive; the sampling rate (Hz) "
                         "is needed")
    mag = su.get("Mag")
    mag = np.asarray(mag, float) if mag is not None and np.asarray(mag).shape == acc.shape else None
    ts = _arr(su.get("Timestamp"))
    return acc * G_M_S2, np.deg2rad(gyr), mag, float(fs), ts


def read_mobilised_info(path: str | Path) -> dict[str, MobilisedInfo]:
    """``infoForAlgo.mat`` → {time measure: MobilisedInfo}."""
    path = Path(path)
    m = _load_mat(path, "infoForAlgo", "infoForAlgo.mat")
    out = {}
    for tm, d in m["infoForAlgo"].items():
        if not isinstance(d, dict):
            continue
        cm = lambda k: (_num(d, k) / 100.0 if np.isfinite(_num(d, k)) else None)  # noqa: E731
        aid = _num(d, "WalkingAid_01")
        hand = d.get("Handedness")
        w = _num(d, "Weight")
        out[tm] = MobilisedInfo(height_m=cm("Height"), weight_kg=w if np.isfinite(w) else None,
                                sensor_height_m=cm("SensorHeight"), leg_length_m=cm("LegLength"),
                                walking_aid=None if not np.isfinite(aid) else bool(aid),
                                handedness=hand if isinstance(hand, str) and hand else None)
    return out


def find_mobilised_files(root: str | Path) -> list[Path]:
    """Every ``data.mat`` under ``root`` (or ``[root]`` for a file), sorted; ValueError if none."""
    p = Path(root)
    if p.is_file():
        return [p]
    if not p.is_dir():
        raise ValueError(f"{p}: does not exist; expected a Mobilise-D data.mat or a folder holding them")
    files = sorted(p.rglob("data.mat"))
    if not files:
        raise ValueError(f"{p}: no data.mat below it; expected the Mobilise-D standardized format "
                         "(<cohort>/<participant>/data.mat)")
    return files


def read_mobilised(path: str | Path) -> list[MobilisedTrial]:
    """All trials of one ``data.mat`` (or of the ``data.mat`` in a participant folder), in file order.

    ``infoForAlgo.mat`` beside it is read when present (else ``MobilisedInfo()`` with every field None)."""
    path = Path(path)
    if path.is_dir():
        path = path / "data.mat"
    m = _load_mat(path, "data", "data.mat")
    info_path = path.parent / "infoForAlgo.mat"
    infos = read_mobilised_info(info_path) if info_path.is_file() else {}
    cohort = path.parent.parent.name or "unknown"
    participant = f"{cohort}-{path.parent.name}" if path.parent.name else path.stem
    wanted = None
    tl = path.parent / "test_list.json"
    if tl.is_file():
        try:
            wanted = {tuple(e["key"]): e.get("value", {}) for e in json.loads(tl.read_text())["data"]}
        except (ValueError, KeyError, TypeError) as e:
            raise ValueError(f"{tl}: not the Mobilise-D test list ({e}); fix or remove it") from e
    trials: list[MobilisedTrial] = []
    for tm, tests in m["data"].items():
        if not isinstance(tests, dict):
            continue
        for test, trs in tests.items():
            if not isinstance(trs, dict):
                continue
            for trial, d in trs.items():
                if not isinstance(d, dict):
                    continue
                where = f"data.{tm}.{test}.{trial}"
                su = d.get("SU", {})
                lb = su.get("LowerBack") if isinstance(su, dict) else None
                if not isinstance(lb, dict):
                    if wanted is not None and (tm, test, trial) in wanted and ["SU", "LowerBack"] in \
                            wanted[(tm, test, trial)].get("available_sensors", []):
                        raise ValueError(f"{path}: {where} has no SU.LowerBack though test_list.json lists it")
                    continue                      # a trial without the lower-back sensor: nothing to read
                acc, gyr, mag, fs, ts = _imu(path, where, lb)
                t0, tz = _start(path, where, d, ts)
                refs = []
                std = d.get("Standards", {})
                for system, sysd in (std.items() if isinstance(std, dict) else ()):
                    if not isinstance(sysd, dict):
                        continue
                    sfs = _num(sysd, "Fs")
                    for kind in _BOUT_KINDS:
                        if kind in sysd:
                            refs.append(_reference(path, where, system, kind, sysd[kind],
                                                   sfs if np.isfinite(sfs) else fs))
                trials.append(MobilisedTrial(
                    path=path, participant_id=participant, cohort=cohort, time_measure=tm, test=test,
                    trial=trial, fs_hz=fs, start_utc_ns=t0, timezone=tz, acc=acc, gyr=gyr, mag=mag,
                    references=tuple(refs), info=infos.get(tm, MobilisedInfo())))
    if not trials:
        raise ValueError(f"{path}: no trial with an SU.LowerBack sensor in data.<TimeMeasure>.<Test>.<Trial>; "
                         "expected the Mobilise-D standardized format")
    return trials
