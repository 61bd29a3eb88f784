"""``stridelab export bids WAREHOUSE OUT/``: recordings and their events as a Motion-BIDS dataset (BIDS 1.9).

One ``motion`` datatype folder per subject and session; per recording (task) and tracking system (the IMUs of
the recording that share one sample clock):

* ``*_tracksys-<label>_motion.tsv``: the samples, no header, one column per channel, in SI units as stored
  (acc m/s², gyr rad/s, magnetometer µT on the IMU's stamps);
* ``*_tracksys-<label>_channels.tsv``: name, component, type, tracked_point (the placement), units;
* ``*_tracksys-<label>_motion.json``: sampling frequency, task, channel counts, duration;
* ``*_events.tsv``: onset and duration in seconds from the recording's first sample, ``trial_type`` (IC, TC, an
  activity label ...), ``side``, ``source`` (``reference``: annotated with the recording, e.g. by an optical
  system; ``stridelab``: the gait stage's estimate);
* at the top: ``dataset_description.json``, ``participants.tsv`` (+ ``.json``), ``README``,
  ``task-<label>_events.json`` describing the event columns.

Pseudonymised: subjects are renumbered (``sub-01`` ...) unless ``keep_ids``; the mapping to the warehouse's
pseudonyms is written only where ``subject_map`` asks. Sessions are named by kind and order (``ses-lab1``,
``ses-freeliving1``), never by date; no dates, clock times, file names, device serials or free-text metadata are
exported (onsets are relative to each recording's start). Participants' ``condition`` and ``paretic_side`` are
kept when the recordings carry them.
"""
from __future__ import annotations

import json
import os
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from stridelab.pipeline.temp_names import temporary_name

BIDS_VERSION = "1.9.0"
#: the recording's session metadata fields exported to participants.tsv (an allow-list)
PARTICIPANT_FIELDS = ("condition", "paretic_side")
KINDS = ("lab", "free_living", "calibration")


def _label(s: str) -> str:
    """A BIDS label: letters and digits only."""
    out = re.sub(r"[^A-Za-z0-9]", "", str(s))
    return out or "x"


@dataclass
class ExportSummary:
    out: str
    subjects: int = 0
    sessions: int = 0
    recordings: int = 0
    motion_files: int = 0
    samples: int = 0
    events: int = 0
    skipped: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        return dict(self.__dict__)


def export_bids(warehouse: str | Path, out: str | Path, *, study: str | None = None,
                participants: tuple[str, ...] = (), kinds: tuple[str, ...] = (), keep_ids: bool = False,
                subject_map: str | Path | None = None, overwrite: bool = False, authors: tuple[str, ...] = (),
                name: str = "StrideLab export", on_progress=None) -> ExportSummary:
    """Write the recordings of ``warehouse`` (newest snapshot) with their events to ``out`` as Motion-BIDS.

    ``study``/``participants``/``kinds`` narrow what is exported; ``authors`` and ``name`` go into
    ``dataset_description.json``; ``keep_ids`` keeps the warehouse's
    pseudonyms as subject labels (letters and digits only) instead of renumbering. Raises ValueError (one line)
    on bad arguments, a non-empty ``out`` without ``overwrite``, or a warehouse with nothing to export."""
    from stridelab.warehouse.read import connect_snapshot
    out = Path(out)
    bad = [k for k in kinds if k not in KINDS]
    if bad:
        raise ValueError(f"--kind {bad[0]}: expected one of {', '.join(KINDS)}")
    if out.exists() and any(out.iterdir()):
        if not overwrite:
            raise ValueError(f"{out} is not empty; choose a new folder or pass --overwrite")
        if not (out / "dataset_description.json").exists():
            raise ValueError(f"{out} is not empty and not a BIDS dataset; refusing to overwrite it")
        shutil.rmtree(out)
    con = connect_snapshot(warehouse)
    if con is None:
        raise ValueError(f"{warehouse}: no published snapshot (not a warehouse, or nothing ran yet); "
                         f"run `stridelab run` first")
    try:
        return _export(con, Path(warehouse), out, study, participants, kinds, keep_ids, subject_map, on_progress,
                       {"Name": name, "Authors": list(authors)})
    finally:
        con.close()


def _export(con, root, out, study, participants, kinds, keep_ids, subject_map, on_progress,
            description: dict) -> ExportSummary:
    from stridelab.warehouse.read import read_imu
    recs = con.execute("""
        SELECT s.study, s.participant_id, s.session_id, s.kind, s.start_ns, r.content_hash, r.trial, r.start_ns,
               r.metadata
        FROM recordings r JOIN sessions s USING (session_id)
        WHERE r.status = 'ingested' AND (? IS NULL OR s.study = ?)
        ORDER BY s.study, s.participant_id, s.start_ns, s.session_id, r.start_ns, r.trial""",
                       [study, study]).fetchall()
    if participants:
        recs = [r for r in recs if r[1] in participants]
    if kinds:
        recs = [r for r in recs if r[3] in kinds]
    if not recs:
        raise ValueError("nothing to export: no ingested recording matches (check --study, --participant, --kind)")
    summary = ExportSummary(out=str(out))
    tmp = temporary_name(out)
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)

    subjects: dict[tuple[str, str], str] = {}
    for st, pid, *_ in recs:
        if (st, pid) not in subjects:
            subjects[(st, pid)] = _label(pid) if keep_ids else f"{len(subjects) + 1:02d}"
    if keep_ids and len(set(subjects.values())) < len(subjects):
        raise ValueError("--keep-ids: two participants map to the same BIDS label (letters and digits only); "
                         "export without --keep-ids")
    sessions: dict[str, str] = {}
    kind_counter: dict[tuple, int] = {}
    participant_rows: dict[str, dict] = {}
    tasks: set[str] = set()
    runs: dict[tuple, int] = {}
    for st, pid, sid, kind, _s0, chash, trial, _r0, meta_json in recs:
        sub = subjects[(st, pid)]
        if sid not in sessions:
            k = (sub, kind)
            kind_counter[k] = kind_counter.get(k, 0) + 1
            sessions[sid] = f"{_label(kind)}{kind_counter[k]}"
        ses = sessions[sid]
        meta = json.loads(meta_json) if isinstance(meta_json, str) and meta_json else (meta_json or {})
        prow = participant_rows.setdefault(sub, {"participant_id": f"sub-{sub}"})
        for f in PARTICIPANT_FIELDS:
            if meta.get(f) is not None and f not in prow:
                prow[f] = str(meta[f])
        task = _label(re.sub(r"[-_ ]?\d+$", "", trial or "") or kind)
        tasks.add(task)
        rk = (sub, ses, task)
        runs[rk] = runs.get(rk, 0) + 1
        stem = f"sub-{sub}_ses-{ses}_task-{task}"           # entity order: sub, ses, task, tracksys, acq, run
        run = f"run-{runs[rk]}"
        d = tmp / f"sub-{sub}" / f"ses-{ses}" / "motion"
        d.mkdir(parents=True, exist_ok=True)
        placements = [r[0] for r in con.execute(
            "SELECT placement FROM sensors WHERE content_hash = ? AND kind = 'imu' ORDER BY placement",
            [chash]).fetchall()]
        series = {p: read_imu(con, root, chash, p) for p in placements}
        series = {p: s for p, s in series.items() if s is not None and len(s.t_ns)}
        if not series:
            summary.skipped.append(f"{stem}_{run}: no IMU samples")
            continue
        groups = _clock_groups(series)
        t0 = min(int(s.t_ns[0]) for s in series.values())
        for label, members in groups.items():
            tracksys = label if len(groups) > 1 else "IMU"
            n = _write_tracksys(d, f"{stem}_tracksys-{tracksys}_{run}", members, series, task, tracksys)
            summary.motion_files += 1
            summary.samples += n
        summary.events += _write_events(con, d / f"{stem}_{run}_events.tsv", chash, sid, t0)
        summary.recordings += 1
        if on_progress:
            on_progress(f"{stem}_{run}: {len(series)} IMUs")

    _write_top(tmp, participant_rows, tasks, description)
    summary.subjects, summary.sessions = len(subjects), len(sessions)
    if subject_map:
        m = Path(subject_map)
        m.parent.mkdir(parents=True, exist_ok=True)
        m.write_text("participant_id\tstudy\twarehouse_pseudonym\n" + "".join(
            f"sub-{v}\t{st}\t{pid}\n" for (st, pid), v in subjects.items()))
    if out.exists():
        out.rmdir()                                   # empty (checked above)
    os.replace(tmp, out)
    return summary


def _clock_groups(series) -> dict[str, list[str]]:
    """Placements whose IMUs share identical stamps form one tracking system (label: IMU1, IMU2, ...)."""
    groups: list[list[str]] = []
    for p, s in series.items():
        for g in groups:
            ref = series[g[0]].t_ns
            if len(ref) == len(s.t_ns) and np.array_equal(ref, s.t_ns):
                g.append(p)
                break
        else:
            groups.append([p])
    return {f"IMU{i + 1}": g for i, g in enumerate(groups)}


_COMPONENTS = ("x", "y", "z")
_TYPES = (("ACCEL", "acc", "m/s^2"), ("GYRO", "gyr", "rad/s"), ("MAGN", "mag", "uT"))


def _write_tracksys(d: Path, stem: str, members: list[str], series, task: str, tracksys: str) -> int:
    import pyarrow as pa
    import pyarrow.csv as pcsv
    cols, names, rows = [], [], []
    counts = {"ACCEL": 0, "GYRO": 0, "MAGN": 0}
    for p in members:
        s = series[p]
        for typ, attr, unit in _TYPES:
            v = getattr(s, attr)
            if v is None:
                continue
            for j, comp in enumerate(_COMPONENTS):
                name = f"{p}_{attr}_{comp}"
                # 6 decimals (1e-6 m/s², rad/s, µT): far below any IMU's resolution, half the text of float64
                cols.append(pa.array(np.round(np.asarray(v[:, j], float), 6)))
                names.append(name)
                rows.append((name, comp, typ, p, unit))
                counts[typ] += 1
    s0 = series[members[0]]
    n = len(s0.t_ns)
    pcsv.write_csv(pa.table(cols, names=names), d / f"{stem}_motion.tsv",
                   write_options=pcsv.WriteOptions(include_header=False, delimiter="\t", quoting_style="none"))
    with open(d / f"{stem}_channels.tsv", "w", newline="\n") as f:
        f.write("name\tcomponent\ttype\ttracked_point\tunits\n")
        for r in rows:
            f.write("\t".join(r) + "\n")
    rate = float(s0.sampling_rate_hz) if s0.sampling_rate_hz else float(1e9 / np.median(np.diff(s0.t_ns)))
    side = {"TaskName": task, "SamplingFrequency": round(rate, 6),
            "SamplingFrequencyEffective": round(float((n - 1) * 1e9 / (s0.t_ns[-1] - s0.t_ns[0])), 6)
            if n > 1 and s0.t_ns[-1] > s0.t_ns[0] else round(rate, 6),
            "TrackingSystemName": tracksys,
            "MotionChannelCount": len(rows), "ACCELChannelCount": counts["ACCEL"],
            "GYROChannelCount": counts["GYRO"], "MAGNChannelCount": counts["MAGN"],
            "RecordingDuration": round(n / rate, 3) if rate else 0.0,
            "RecordingType": "continuous",
            "SoftwareVersions": f"StrideLab {_version()}",
            "TrackedPointsCount": len(members)}
    (d / f"{stem}_motion.json").write_text(json.dumps(side, indent=2) + "\n")
    return n


def _write_events(con, path: Path, chash: str, session_id: str, t0: int) -> int:
    rows = con.execute("""
        SELECT t_ns, end_ns, type, side, coalesce(label, ''), 'reference' FROM reference_events
        WHERE content_hash = ?""", [chash]).fetchall()
    have = {r[0] for r in con.execute("SELECT table_name FROM information_schema.tables").fetchall()}
    if "gait_events" in have:
        rows += con.execute("""
            SELECT t_ns, NULL, type, side, '', 'stridelab' FROM gait_events WHERE content_hash = ?""",
                            [chash]).fetchall()
    rows.sort(key=lambda r: (r[0], r[5], r[2]))
    with open(path, "w", newline="\n") as f:
        f.write("onset\tduration\ttrial_type\tside\tsource\n")
        for t, end, typ, side, label, src in rows:
            onset = (int(t) - t0) / 1e9
            dur = (int(end) - int(t)) / 1e9 if end is not None else 0.0
            trial_type = label if (typ == "activity" and label) else typ
            f.write(f"{onset:.3f}\t{dur:.3f}\t{_cell(trial_type)}\t{_cell(side)}\t{src}\n")
    return len(rows)


def _cell(v) -> str:
    if v is None or v == "":
        return "n/a"
    return re.sub(r"[\t\r\n]", " ", str(v))


def _version() -> str:
    try:
        from importlib.metadata import version
        return version("stridelab")
    except Exception:  # noqa: BLE001 - running from a source tree without metadata
        return "unknown"


def _write_top(d: Path, participant_rows: dict[str, dict], tasks: set[str], description: dict) -> None:
    desc = {"Name": description.get("Name") or "StrideLab export", "BIDSVersion": BIDS_VERSION, "DatasetType": "raw",
            "License": "n/a",
            "GeneratedBy": [{"Name": "StrideLab", "Version": _version(),
                             "Description": "stridelab export bids: wearable IMU recordings and their events"}],
            "HowToAcknowledge": "Cite the study that collected the data and StrideLab (README, 'How to cite')."}
    if description.get("Authors"):
        desc["Authors"] = description["Authors"]
    (d / "dataset_description.json").write_text(json.dumps(desc, indent=2) + "\n")
    fields = [f for f in PARTICIPANT_FIELDS if any(f in r for r in participant_rows.values())]
    with open(d / "participants.tsv", "w", newline="\n") as f:
        f.write("\t".join(["participant_id", *fields]) + "\n")
        for sub in sorted(participant_rows):
            r = participant_rows[sub]
            f.write("\t".join([r["participant_id"], *(_cell(r.get(k)) for k in fields)]) + "\n")
    pj = {"participant_id": {"Description": "Subject label; renumbered at export unless --keep-ids"},
          "condition": {"Description": "Participant group as recorded with the data (e.g. healthy, hemiparetic)"},
          "paretic_side": {"Description": "Paretic side, where the participant has one",
                           "Levels": {"left": "left side", "right": "right side"}}}
    (d / "participants.json").write_text(json.dumps({k: pj[k] for k in ["participant_id", *fields]}, indent=2) + "\n")
    ev = {"onset": {"Description": "Time of the event from the recording's first sample", "Units": "s"},
          "duration": {"Description": "Duration of the event (0 for instantaneous gait events)", "Units": "s"},
          "trial_type": {"Description": "IC = initial contact (heel strike), TC = terminal contact (toe off); "
                                        "otherwise the activity or annotation label"},
          "side": {"Description": "Body side of a gait event", "Levels": {"left": "left", "right": "right"}},
          "source": {"Description": "Who marked the event",
                     "Levels": {"reference": "annotated with the recording (e.g. optical reference system)",
                                "stridelab": "estimated by StrideLab's gait stage from the foot IMUs"}}}
    for task in sorted(tasks):
        (d / f"task-{task}_events.json").write_text(json.dumps(ev, indent=2) + "\n")
    (d / "README").write_text(
        "StrideLab export (Motion-BIDS)\n\nWearable IMU recordings with their gait events and annotations, written "
        "by `stridelab export bids`.\nChannels: acc in m/s^2 (specific force, +9.81 up at rest), gyroscope in "
        "rad/s, magnetometer in uT,\nin each sensor's own frame. Subjects are pseudonymised; no dates or clock "
        "times are included.\n")
