"""``stridelab import``: device exports -> recording-format MCAP files in an inbox (DESIGN.md "Recording format").

One converter per format turns what the format's reader in ``pipeline/formats`` returns into
:class:`stridelab.estimators.recording.Recording` objects: StrideLab units (the readers convert), the ``session`` record
filled (defaults per format, then a sidecar ``<file>.session.toml``, then ``--session FIELD=VALUE``), and the
references the file carries written as reference topics (``/reference/pose/<placement>``,
``/reference/events``). The MCAP is written by :func:`stridelab.pipeline.formats.mcap_write.write_recording`, atomically
(temporary file + rename): a bad file leaves nothing behind and gets one line (file, what is wrong, what to do).

Times: formats without an absolute clock start at the session field ``start`` (ISO 8601, default
``2000-01-01T00:00:00Z``). Extra session fields the stages read:
``reference_frame = "sensor_enu"`` (the optical orientation is the sensor's own frame in ENU, as in BROAD: the
orientation stage scores it without a mounting/heading alignment) and ``accelerometer_only`` (comma-separated
placements without a gyroscope; the orientation stage skips them).
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable

import numpy as np

from stridelab.estimators.recording import ImuData, PLACEMENTS, PoseData, Recording

DEFAULT_START = "2000-01-01T00:00:00Z"
_NOT_SESSION = ("start",)          # import options, not written into the session record


class ImportRejected(ValueError):
    """One file cannot be imported; ``str(err)`` is the one-line reason (what is wrong, what to do)."""


@dataclass(frozen=True)
class Converted:
    """One recording to write: ``rec`` with times relative to the recording start (ns), the default session
    fields of the format, and the output name stem."""
    rec: Recording
    defaults: dict
    stem: str
    t0_ns: int | None = None        # absolute start when the file has a clock (else the session 'start')


@dataclass(frozen=True)
class Format:
    name: str
    description: str
    convert: Callable[[Path, str | None], list[Converted]]
    suffixes: tuple[str, ...]       # files picked from a directory argument ("" = the directory itself)


@dataclass
class ImportResult:
    written: list[Path] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)     # imported, with a note (e.g. a repeated packet counter)


def _rel_ns(n: int, fs: float) -> np.ndarray:
    return np.rint(np.arange(n) * (1e9 / fs)).astype(np.int64)


def _slug(s: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", s).strip("._-") or "x"


def _pick_placement(placement: str | None, default: str) -> str:
    return placement or default


# ---- converters (one per format; the parsing is in pipeline/formats) ----------------------------

def _xio(path: Path, placement: str | None) -> list[Converted]:
    from stridelab.pipeline.formats.loop_csv import load_loop_csv
    r = load_loop_csv(path)
    pl = _pick_placement(placement, "foot_right")
    t = _rel_ns(len(r.acc), r.sampling_rate_hz)
    rec = Recording(metadata={}, imu={pl: ImuData(t, r.acc, r.gyr, r.mag)}, name=path.stem)
    return [Converted(rec, {"participant": "xio01", "trial": _slug(path.stem), "kind": "lab",
                            "protocol": "x-io CSV"}, f"xio-{_slug(path.stem)}")]


def _gaitmap(path: Path, placement: str | None) -> list[Converted]:
    from stridelab.pipeline.formats.c3d import MarkerData, cluster_orientation
    from stridelab.pipeline.formats.gaitmap import load_gaitmap_example
    from stridelab.estimators.quaternion import quat_from_matrix
    d = path if path.is_dir() else path.parent
    ex = load_gaitmap_example(d)
    imu, poses, events = {}, {}, []
    for foot in (ex.left, ex.right):
        pl = f"foot_{foot.side}"
        t = _rel_ns(len(foot.acc), ex.sampling_rate_hz)
        imu[pl] = ImuData(t, foot.acc, foot.gyr, None)
        # heel marker position; foot orientation from the rigid heel-toe-5th-metatarsal triangle (lab frame, z up)
        names = ("FCC", "TOE", "FM5")
        md = MarkerData(labels=names, pos_m=np.stack([foot.markers[n] for n in names], axis=1),
                        rate_hz=ex.mocap_rate_hz, first_frame=0, units="m")
        R = cluster_orientation(md, names)
        ok = np.isfinite(R).all(axis=(1, 2))
        q = np.full((len(R), 4), np.nan)
        q[ok] = quat_from_matrix(R[ok])
        poses[pl] = PoseData(_rel_ns(len(R), ex.mocap_rate_hz), foot.markers["FCC"], q)
        at = lambda i, t=t: int(t[min(int(i), len(t) - 1)])           # noqa: E731 - IMU sample -> ns
        for col, typ in ((2, "IC"), (3, "TC")):
            for i in foot.strides[:, col]:
                events.append({"t_ns": at(i), "type": typ, "side": foot.side,
                               "source": "gaitmap stride_events_sample.csv (mocap)"})
        # the labelled strides (borders = mid-stances, min_vel) and the span they cover: stride lengths are scored
        # on the strides the reference labels, events inside the span (as stridelab bench gait does)
        for a, b in foot.strides[:, :2]:
            events.append({"t_ns": at(a), "end_ns": at(b), "type": "stride", "side": foot.side,
                           "source": "gaitmap stride_events_sample.csv (mocap)"})
        events.append({"t_ns": at(foot.strides[:, 0].min()), "end_ns": at(foot.strides[:, 1].max()),
                       "type": "annotated", "placement": pl, "label": "labelled strides",
                       "source": "gaitmap stride_events_sample.csv (first start, last end)"})
    rec = Recording(metadata={}, imu=imu, reference_poses=poses, events=events, name="gaitmap_example")
    return [Converted(rec, {"participant": "gaitmap01", "trial": "walk", "kind": "lab",
                            "protocol": "gaitmap example: 2x20 m straight walk",
                            "reference": "Qualisys markers (heel FCC position, foot orientation from FCC/TOE/FM5)"},
                      "gaitmap-example")]


def _uci(path: Path, placement: str | None) -> list[Converted]:
    from stridelab.estimators.activity.evaluation import SCORED_CLASSES
    from stridelab.pipeline.formats.uci_chest import LABEL_TO_CLASS, load_uci_participant
    u = load_uci_participant(path)
    pl = _pick_placement(placement, "chest")
    t = _rel_ns(len(u.acc), u.sampling_rate_hz)
    events = []
    lab = u.labels
    cut = np.flatnonzero(np.diff(lab)) + 1
    for a, b in zip(np.concatenate([[0], cut]), np.concatenate([cut, [len(lab)]])):
        code = int(lab[a])
        cls = LABEL_TO_CLASS.get(code)
        end = int(t[b - 1]) + int(round(0.5e9 / u.sampling_rate_hz))     # half a period after the run's last sample
        events.append({"t_ns": int(t[a]), "end_ns": end, "type": "activity", "code": code,
                       "label": SCORED_CLASSES[cls] if cls is not None else "unscored",
                       "source": "UCI chest label column (window model fitted on UCI labels 1-8: in-sample here; "
                                 "rules only: not fitted)"})
    rec = Recording(metadata={}, imu={pl: ImuData(t, u.acc, None, None)}, events=events, name=path.stem)
    return [Converted(rec, {"participant": f"uci{_slug(u.participant).zfill(2)}", "trial": "day",
                            "kind": "free_living", "protocol": "UCI chest activities",
                            "accelerometer_only": pl, "counts_per_g": f"{u.counts_per_g:.3f}"},
                      f"uci-{_slug(u.participant)}")]


def _broad(path: Path, placement: str | None) -> list[Converted]:
    from stridelab.pipeline.formats.broad import load_broad
    out = []
    pl = _pick_placement(placement, "hand")
    for tr in load_broad(path):
        t = _rel_ns(len(tr.acc), tr.sampling_rate_hz)
        pos = tr.pos_ref if tr.pos_ref is not None else np.full((len(t), 3), np.nan)
        q = tr.quat_ref.copy()
        events = []
        m = tr.movement.astype(np.int8)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], m, [0]])))
        for a, b in zip(edges[::2], edges[1::2]):
            events.append({"t_ns": int(t[a]), "end_ns": int(t[b - 1]), "type": "score", "label": "movement",
                           "placement": pl, "source": "BROAD movement mask"})
        rec = Recording(metadata={}, imu={pl: ImuData(t, tr.acc, tr.gyr, tr.mag)},
                        reference_poses={pl: PoseData(t, pos, q)}, events=events, name=tr.name)
        trial = _slug(tr.name.replace("/", "-"))
        out.append(Converted(rec, {"participant": "broad01", "trial": trial, "kind": "lab",
                                   "protocol": "BROAD " + ("disturbed" if tr.disturbed else "undisturbed"),
                                   "reference_frame": "sensor_enu",
                                   "reference": "OptiTrack orientation of the IMU case (BROAD opt_quat), movement mask"},
                             f"broad-{trial}"))
    return out


def _apdm(path: Path, placement: str | None) -> list[Converted]:
    from stridelab.pipeline.formats.apdm import LABEL_PLACEMENTS, load_apdm
    r = load_apdm(path)
    imu = {}
    for s in r.sensors:
        pl = s.placement
        if placement and len(r.sensors) == 1:
            pl = placement
        if not pl:
            raise ImportRejected(f"{path}: a monitor label is not a known placement (known: "
                                 f"{', '.join(sorted(set(LABEL_PLACEMENTS)))}, case and spaces ignored); relabel the "
                                 f"monitor, or give --placement for a file with one sensor")
        if pl in imu:
            raise ImportRejected(f"{path}: two sensors map to placement '{pl}'; relabel them")
        imu[pl] = ImuData(s.t_ns - r.t0_ns, s.acc, s.gyr, s.mag)
    rec = Recording(metadata={}, imu=imu, name=path.stem)
    return [Converted(rec, {"participant": "apdm01", "trial": _slug(path.stem), "kind": "lab",
                            "protocol": "APDM Opal"}, f"apdm-{_slug(path.stem)}", t0_ns=r.t0_ns)]


def _cwa(path: Path, placement: str | None) -> list[Converted]:
    from stridelab.pipeline.formats.axivity import load_cwa
    r = load_cwa(path)
    pl = _pick_placement(placement, "chest")
    rec = Recording(metadata={}, imu={pl: ImuData(r.t_ns - r.t_ns[0], r.acc, r.gyr, r.mag)}, name=path.stem)
    d = {"participant": f"ax{r.device_id}", "trial": "day", "kind": "free_living", "protocol": "Axivity CWA"}
    if r.gyr is None:
        d["accelerometer_only"] = pl
    return [Converted(rec, d, f"cwa-{_slug(path.stem)}", t0_ns=int(r.t_ns[0]))]


def _pyshoe(path: Path, placement: str | None) -> list[Converted]:
    from stridelab.pipeline.formats.pyshoe import load_pyshoe_trial
    tr = load_pyshoe_trial(path)
    pl = _pick_placement(placement, "foot_right")
    # samples on the reader's nominal-rate grid (ts jitters 3.3-6.1 ms around 5 ms): the foot INS runs at a constant
    # rate, and its PyShoe ARMSE moves by ~8 % between 200.1 Hz and the 200.24 Hz ingest would estimate from the
    # jittered stamps, so the pipeline gets the rate stridelab bench trajectory --pyshoe uses
    t = _rel_ns(len(tr.acc), tr.sampling_rate_hz)
    q = np.full((len(t), 4), np.nan)          # Vicon gives the foot position only
    rec = Recording(metadata={}, imu={pl: ImuData(t, tr.acc, tr.gyr, None)},
                    reference_poses={pl: PoseData(t, tr.position, q)}, name=tr.name)
    d = {"participant": "pyshoe01", "trial": _slug(tr.name), "kind": "lab", "protocol": "PyShoe Vicon trial",
         "reference": "Vicon foot position (PyShoe gt, y flipped to right-handed z up)", "foot_side": "unknown"}
    m = re.fullmatch(r"(\d{4})-(\d\d)-(\d\d)-(\d\d)-(\d\d)-(\d\d)", tr.name)
    if m:
        d["start"] = "{}-{}-{}T{}:{}:{}Z".format(*m.groups())
    return [Converted(rec, d, f"pyshoe-{_slug(tr.name)}")]


def _xsens_times(x) -> np.ndarray:
    """Sample times from the packet counter (dropped packets keep their gap; the 16-bit counter unwrapped and a
    repeated counter placed by the reader's policy, ``stridelab.pipeline.formats.xsens_mt.packet_index``)."""
    from stridelab.pipeline.formats.xsens_mt import packet_index
    k = x.index if x.index is not None else packet_index(x.packet)[0]
    return np.rint(np.asarray(k, np.int64) * (1e9 / x.sampling_rate_hz)).astype(np.int64)


_XSENS_SUFFIX = {"lf": "foot_left", "rf": "foot_right", "lb": "lower_back"}


def _xsens(path: Path, placement: str | None) -> list[Converted]:
    from stridelab.pipeline.formats.xsens_mt import load_xsens_mt_txt
    x = load_xsens_mt_txt(path)
    suffix = path.stem.rsplit("_", 1)[-1].lower()
    pl = placement or _XSENS_SUFFIX.get(suffix)
    if pl is None:
        raise ImportRejected(f"{path}: cannot tell the placement from the name; pass --placement (e.g. foot_left)")
    rec = Recording(metadata={}, imu={pl: ImuData(_xsens_times(x), x.acc, x.gyr, None)}, name=path.stem)
    return [Converted(rec, {"participant": "xsens01", "trial": _slug(path.stem), "kind": "lab",
                            "protocol": "Xsens MT Manager export",
                            "magnetometer": "not imported (normalised units; give --session mag_field_ut=...)"},
                      f"xsens-{_slug(path.stem)}")]


def _voisard(path: Path, placement: str | None) -> list[Converted]:
    from stridelab.pipeline.formats.xsens_mt import load_voisard_trial
    d = path.parent if path.is_file() else path
    name = path.stem if path.is_file() else None
    if name is None:
        raise ImportRejected(f"{path}: give the trial's N-M.json (or the folder, which imports every trial)")
    tr = load_voisard_trial(d, name, packet_grid=False)      # the rows as recorded (no interpolated packets)
    a = tr.annotation
    imu = {}
    for pl, x in (("foot_left", tr.left), ("foot_right", tr.right), ("lower_back", tr.lower_back)):
        if x is not None:
            imu[pl] = ImuData(_xsens_times(x), x.acc, x.gyr, None)
    events = []
    fs = tr.left.sampling_rate_hz
    for side, ev in (("left", a.left_events), ("right", a.right_events)):
        for to, hs in np.asarray(ev, np.int64).reshape(-1, 2):
            for typ, i in (("TC", to), ("IC", hs)):
                if i >= 0:      # annotations index the gap-free packet grid (sample = packet - first packet)
                    events.append({"t_ns": int(round(i * 1e9 / fs)), "type": typ, "side": side,
                                   "source": "Voisard et al. 2023 annotations (two IMU algorithms, hand-checked)"})
    lo, hi = (int(v) for v in np.asarray(a.trial_boundaries).ravel()[:2])
    events.append({"t_ns": int(round(max(lo, 0) * 1e9 / fs)), "end_ns": int(round(hi * 1e9 / fs)), "type": "score",
                   "label": "trial", "source": "Voisard TrialBoundaries"})
    rec = Recording(metadata={}, imu=imu, events=events, name=tr.name)
    return [Converted(rec, {"participant": f"voisard{a.subject:02d}", "trial": _slug(tr.name), "kind": "lab",
                            "protocol": "Voisard: stand, walk 10 m, U-turn, walk back",
                            "reference": "Voisard et al. 2023 gait events",
                            "magnetometer": "not imported (normalised units)"}, f"voisard-{_slug(tr.name)}")]


def _mobilised(path: Path, placement: str | None) -> list[Converted]:
    """Every trial of every ``data.mat`` under ``path`` -> one recording (``stridelab.pipeline.formats.mobilised``): the SU
    lower-back IMU as ``lower_back``; per reference system (label = INDIP / Stereophoto) the MicroWB walking bouts
    (``walking_bout``: start/end, cadence, stride length, walking speed, strides), initial contacts with side and
    turns on ``/reference/events``; infoForAlgo height, leg length, sensor height, walking aid into the session."""
    from stridelab.estimators.recording import SESSION_BODY_FIELDS
    from stridelab.pipeline.formats.mobilised import find_mobilised_files, read_mobilised
    out = []
    for f in find_mobilised_files(path):
        for tr in read_mobilised(f):
            t = _rel_ns(len(tr.acc), tr.fs_hz)
            at = lambda s: int(round(float(s) * 1e9))                   # noqa: E731 - s from trial start -> ns
            num = lambda v: None if v is None or not np.isfinite(v) else float(v)   # noqa: E731
            events = []
            for r in tr.references:
                if r.kind != "MicroWB":
                    continue
                src = f"Mobilise-D {r.system} {r.kind} (data.mat Standards)"
                for i in range(r.start_s.size):
                    events.append({"t_ns": at(r.start_s[i]), "end_ns": at(r.end_s[i]), "type": "walking_bout",
                                   "label": r.system, "placement": "lower_back", "source": src,
                                   "n_strides": int(r.n_strides[i]), "cadence_spm": num(r.cadence_spm[i]),
                                   "stride_length_m": num(r.stride_length_m[i]),
                                   "walking_speed_m_s": num(r.walking_speed_m_s[i])})
                for ic, side in zip(r.ic_s, r.ic_side):
                    events.append({"t_ns": at(ic), "type": "IC", "side": side or None, "label": r.system,
                                   "placement": "lower_back", "source": src})
                for a, b, ang in zip(r.turn_start_s, r.turn_end_s, r.turn_angle_deg):
                    events.append({"t_ns": at(a), "end_ns": at(b), "type": "turn", "label": r.system,
                                   "placement": "lower_back", "angle_deg": num(ang), "source": src})
            rec = Recording(metadata={}, imu={placement or "lower_back": ImuData(t, tr.acc, tr.gyr, tr.mag)},
                            events=events, name=tr.name)
            trial = _slug(f"{tr.test}-{tr.trial}").lower()
            d = {"participant": tr.participant_id,
                 "trial": trial, "kind": "lab", "timezone": tr.timezone,
                 "protocol": f"Mobilise-D {tr.test} ({'straight walks' if tr.test == 'Test5' else 'lab course'})",
                 "reference": "Mobilise-D INDIP (inertial + pressure insoles + distance sensors), Stereophoto"}
            for k in SESSION_BODY_FIELDS:
                v = getattr(tr.info, k, None)
                if v is not None:
                    d[k] = f"{float(v):g}"
            out.append(Converted(rec, d, f"mobilised-{_slug(tr.name)}", t0_ns=tr.start_utc_ns))
    return out


FORMATS: dict[str, Format] = {f.name: f for f in (
    Format("xio", "x-io / NGIMU CSV (Time (s), Gyroscope X (deg/s) ..., Accelerometer X (g) ...)", _xio, (".csv",)),
    Format("gaitmap", "gaitmap / NilsPod example folder (imu_sample.csv + mocap_sample.csv + stride events)",
           _gaitmap, ("",)),
    Format("uci", "UCI single chest-mounted accelerometer CSV (seq,x,y,z,label counts)", _uci, (".csv",)),
    Format("broad", "BROAD HDF5 trial (IMU + optical orientation)", _broad, (".hdf5", ".h5")),
    Format("apdm", "APDM Opal HDF5, v5 layout (Sensors/<id>/Accelerometer ...)", _apdm, (".h5", ".hdf5")),
    Format("cwa", "Axivity AX3/AX6 .cwa (read by scikit-digital-health: optional extra 'cwa')", _cwa, (".cwa",)),
    Format("pyshoe", "PyShoe Vicon trial .mat (one shoe IMU + Vicon foot position)", _pyshoe, (".mat",)),
    Format("xsens", "Xsens MT Manager text export (rate line, PacketCounter Acc_X ... Mag_Z)", _xsens, (".txt",)),
    Format("voisard", "Voisard et al. gait trial: N-M.json events + N-M_{lf,rf,lb}.txt Xsens exports", _voisard,
           (".json",)),
    Format("mobilised", "Mobilise-D standardized data.mat (+ infoForAlgo.mat): a file or a folder searched for "
           "data.mat", _mobilised, ("",)),
)}

#: sub-folders of a public-data folder (../shared/data) and how ``stridelab demo --public`` imports them
PUBLIC_DATASETS = {"broad": "broad", "gaitmap_example": "gaitmap", "uci_chest": "uci", "pyshoe_vicon": "pyshoe",
                   "voisard_gait": "voisard", "xio_gait": "xio"}
PUBLIC_STUDY = "public"


def import_public(directory: Path, inbox: Path, *, max_trials: int | None = None,
                  on_file: Callable[[str], None] = lambda m: None) -> ImportResult:
    """Import every known dataset found in ``directory`` into ``inbox/<dataset>/`` (study ``public``); folders
    not in :data:`PUBLIC_DATASETS` are ignored with a note. A dataset already imported with the same
    ``max_trials`` is not converted again (marker file ``.imported``)."""
    total = ImportResult()
    for sub in sorted(p for p in Path(directory).iterdir() if p.is_dir() and not p.name.startswith(".")):
        fmt = PUBLIC_DATASETS.get(sub.name)
        if fmt is None:
            on_file(f"note: {sub} ignored (not one of {', '.join(PUBLIC_DATASETS)})")
            continue
        out = Path(inbox) / sub.name
        marker = out / ".imported"
        want = f"max_trials={max_trials}"
        if marker.is_file() and marker.read_text() == want:
            n = len(list(out.glob("*.mcap")))
            on_file(f"{sub.name}: {n} recordings already imported into {out}")
            total.written += sorted(out.glob("*.mcap"))
            continue
        if out.is_dir():
            for old in out.glob("*.mcap"):
                old.unlink()
        files = expand(FORMATS[fmt], [sub])
        if max_trials is not None and len(files) > max_trials:      # spread over the dataset (subjects, motions)
            files = [files[i] for i in np.unique(np.linspace(0, len(files) - 1, max_trials).round().astype(int))]
        res = import_paths(fmt, files, out, study=PUBLIC_STUDY, limit=max_trials, on_file=on_file)
        total.written += res.written
        total.errors += res.errors
        marker.write_text(want)
        on_file(f"{sub.name}: {len(res.written)} recordings ({fmt}), {len(res.errors)} refused")
    return total


def register(fmt: Format) -> None:
    """Add a format (used by readers that live in their own modules)."""
    FORMATS[fmt.name] = fmt


# ---- session record ------------------------------------------------------------------------

def parse_session_options(items) -> dict:
    """``FIELD=VALUE`` pairs -> dict, parsed as ``stridelab ingest --session`` does (raises ImportRejected)."""
    from stridelab.pipeline.session_sources import parse_assignments
    try:
        return parse_assignments(items, "--session")
    except ValueError as e:
        raise ImportRejected(f"{e} (e.g. --session participant=P07)") from None


def read_sidecar(path: Path) -> dict:
    """Fields of the sidecar beside an export (``<file>.session.toml`` or ``<stem>.session.toml``, a
    ``[session]`` table or top-level keys; read as ingest reads sidecars), {} if there is none."""
    from stridelab.pipeline.session_sources import SessionSourceError, read_sidecar as _read, sidecar_paths
    for side in [path.with_name(path.name + ".session.toml"), *sidecar_paths(path)]:
        if side.is_file():
            try:
                return _read(side)
            except SessionSourceError as e:
                raise ImportRejected(f"{path}: {e}") from None
    return {}


def _t0_ns(start: str, where: Path) -> int:
    try:
        dt = datetime.fromisoformat(start.replace("Z", "+00:00"))
    except ValueError:
        raise ImportRejected(f"{where}: session start {start!r} is not an ISO 8601 time "
                             f"(e.g. --session start=2024-05-01T09:00:00Z)") from None
    if dt.tzinfo is None:
        dt = dt.replace(tzinfo=timezone.utc)
    return int(round(dt.timestamp() * 1e9))


def session_record(c: Converted, path: Path, study: str | None, sidecar: dict, overrides: dict) -> tuple[dict, int]:
    """(session record, absolute start ns) from the format defaults, the sidecar and ``--session``."""
    from stridelab.pipeline.ingest import IngestRejected, check_session_metadata
    from stridelab.pipeline.pseudonym import SITE_KEYS
    s = {"study": study or "imported", **c.defaults, **sidecar, **overrides}
    if "session" not in sidecar and "session" not in overrides:
        s["session"] = _slug(f"{s['participant']}-{s.get('trial') or c.stem}")
    s.setdefault("timezone", "UTC")
    start = s.pop("start", None)
    t0 = c.t0_ns if c.t0_ns is not None and start is None else _t0_ns(start or DEFAULT_START, path)
    if not any(s.get(k) for k in SITE_KEYS):
        try:
            check_session_metadata({"session": s})
        except IngestRejected as e:
            raise ImportRejected(f"{path}: {e}; set it with --session FIELD=VALUE or a sidecar "
                                 f"{path.name}.session.toml") from None
    return s, t0


def _shift(rec: Recording, t0: int) -> None:
    for x in list(rec.imu.values()) + list(rec.reference_poses.values()):
        x.t_ns = np.asarray(x.t_ns, np.int64) + t0
    for e in rec.events:
        e["t_ns"] = int(e["t_ns"]) + t0
        if e.get("end_ns") is not None:
            e["end_ns"] = int(e["end_ns"]) + t0


# ---- driver ---------------------------------------------------------------------------------

def expand(fmt: Format, paths) -> list[Path]:
    """Files (or folders, for folder formats) named by ``paths``; a directory argument is searched for the
    format's suffixes (non-recursive)."""
    out = []
    for p in map(Path, paths):
        if p.is_dir() and "" not in fmt.suffixes:
            out += sorted(x for x in p.iterdir() if x.is_file() and x.suffix.lower() in fmt.suffixes
                          and not x.name.startswith("."))
        else:
            out.append(p)
    return out


def import_paths(fmt_name: str, paths, inbox: Path, *, study: str | None = None, session: dict | None = None,
                 placement: str | None = None, limit: int | None = None,
                 on_file: Callable[[str], None] = lambda m: None) -> ImportResult:
    """Convert every file; bad files are reported (one line each, naming the file) and do not stop the others.
    Warnings a reader raises while converting a file (e.g. ``XsensPacketWarning``) are reported as
    ``warning: <file>: …`` lines and kept in ``ImportResult.warnings``; the file is imported."""
    import warnings
    from stridelab.pipeline.formats.mcap_write import write_recording
    fmt = FORMATS[fmt_name]
    if placement is not None and placement not in PLACEMENTS:
        on_file(f"note: placement '{placement}' is not one of the standard placements {', '.join(PLACEMENTS)}")
    inbox = Path(inbox)
    inbox.mkdir(parents=True, exist_ok=True)
    res = ImportResult()
    files = expand(fmt, paths)
    if not files:
        res.errors.append(f"{', '.join(map(str, paths))}: no {fmt.name} files found "
                          f"(expected {', '.join(s or 'a folder' for s in fmt.suffixes)})")
    for path in files:
        if limit is not None and len(res.written) >= limit:
            break
        try:
            if not path.exists():
                raise ImportRejected(f"{path}: no such file or folder")
            try:
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    converted = fmt.convert(path, placement)
                for w in caught:
                    text = str(w.message)
                    msg = f"warning: {text if str(path) in text else f'{path}: {text}'}"
                    res.warnings.append(msg)
                    on_file(msg)
            except ImportRejected:
                raise
            except (ValueError, KeyError, OSError, IndexError) as e:
                msg = str(e).splitlines()[0] if str(e) else type(e).__name__
                raise ImportRejected(f"{path}: not a readable {fmt.name} file ({msg}); "
                                     f"check the format name (stridelab import --help)") from None
            sidecar = read_sidecar(path)
            for c in converted:
                if limit is not None and len(res.written) >= limit:
                    break
                if study != PUBLIC_STUDY:
                    c = _without_file_name(c, path)
                meta, t0 = session_record(c, path, study, sidecar, dict(session or {}))
                c.rec.metadata = meta
                _shift(c.rec, t0)
                out = inbox / f"{c.stem}.mcap"
                try:
                    write_recording(c.rec, out)
                except (ValueError, OSError) as e:
                    msg = str(e).splitlines()[0] if str(e) else type(e).__name__
                    raise ImportRejected(f"{path}: cannot be written as a recording ({msg}); the file is "
                                         "left out, the others go on") from None
                res.written.append(out)
                on_file(f"wrote {out} from {path.name} (session {meta['session']}, {', '.join(sorted(c.rec.imu))})")
        except ImportRejected as e:
            res.errors.append(str(e))
            on_file(str(e))
    return res


def _without_file_name(c: Converted, path: Path) -> Converted:
    """``c`` with the export's file name replaced, wherever a converter used it (output name, default trial), by
    ``f`` + 10 letters of its keyed hash (:func:`stridelab.pipeline.privacy.name_token`): a user's file name may hold
    a name or a birth date, and the inbox, the catalog and the reports keep what the importer writes. Public data
    sets (study ``public``) keep their authors' names."""
    from dataclasses import replace as _replace
    from stridelab.pipeline.privacy import name_token
    slug, token = _slug(path.stem), "f" + name_token(path.name)
    defaults = {k: (token if k in ("trial", "session") and v == slug else v) for k, v in c.defaults.items()}
    stem = c.stem[:-len(slug)] + token if c.stem.endswith(slug) else c.stem
    return _replace(c, defaults=defaults, stem=stem)


def events_json(events: list[dict]) -> str:
    return json.dumps(events, sort_keys=True)
