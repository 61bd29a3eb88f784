"""The live outputs a `stridelab live` recording carries, stored by the ingest beside the raw data.

The recorder (:mod:`stridelab.pipeline.live.recorder`) writes what it computed live as ``std_msgs/msg/String`` JSON topics
(docs/live.md "Recording"). At ingest they are decoded once into two Parquet series of the session and one
catalog row each in ``live_outputs`` (migration 014): ``angles`` (one row per frame: ``k``, ``t_ns``,
``offset_ready`` and ``<joint>_<side>_<plane>_deg``) and ``events`` (``side``, ``type``, ``k``, ``k_detect``,
``t_ns``); the ``angles`` row's ``meta`` holds the calibration the live angles used and the standing offsets the
live session subtracted. The nightly ``live_agreement`` stage compares them with its own outputs.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa

from stridelab.pipeline.live.recorder import JSON_TOPICS
from stridelab.warehouse.store import series_relpath, write_table

PLANES = ("sagittal", "frontal", "transverse")


def has_live_topics(topics) -> bool:
    return any(t in JSON_TOPICS for t in topics)


def read_live_topics(path: str | Path) -> dict:
    """Every live-output message of a recording: {"angles": [docs], "events": [docs], "calibration": doc | None,
    "standing": doc | None}. ``ValueError`` naming the file when a message is not the JSON the recorder writes."""
    from mcap.reader import make_reader

    from stridelab.pipeline.live.recorder import decode_string
    out = {"angles": [], "events": [], "calibration": None, "standing": None}
    with open(path, "rb") as fh:
        r = make_reader(fh)
        for _s, ch, m in r.iter_messages(topics=list(JSON_TOPICS), log_time_order=True):
            try:
                doc = json.loads(decode_string(m.data))
            except (ValueError, UnicodeDecodeError):
                raise ValueError(f"{Path(path).name}: {ch.topic} message at log time {m.log_time} is not JSON; "
                                 f"re-record the session with `stridelab live`") from None
            kind = ch.topic.rsplit("/", 1)[1]
            if kind == "joint_angles":
                out["angles"].append(doc)
            elif kind == "events":
                out["events"].append(doc)
            else:
                out[kind] = doc
    return out


def angles_table(docs: list[dict]) -> pa.Table | None:
    """One row per live frame (frames in order, a repeated frame once)."""
    if not docs:
        return None
    k, t, ready, cols = [], [], [], {}
    for d in docs:
        n = len(d["t_ns"])
        k += range(int(d["k0"]), int(d["k0"]) + n)
        t += [int(x) for x in d["t_ns"]]
        ready += [bool(x) for x in d.get("offset_ready", [False] * n)]
        for key, rows in d["angles_deg"].items():
            cols.setdefault(key, []).extend(rows)
    k = np.asarray(k, np.int64)
    order = np.argsort(k, kind="stable")
    keep = np.r_[True, np.diff(k[order]) > 0]
    idx = order[keep]
    data = {"k": k[idx], "t_ns": np.asarray(t, np.int64)[idx], "offset_ready": np.asarray(ready, bool)[idx]}
    for key in sorted(cols):
        a = np.array([[np.nan if v is None else float(v) for v in row] for row in cols[key]], float)
        if len(a) != len(k):
            raise ValueError(f"/live/joint_angles: joint {key} has {len(a)} frames, the messages {len(k)}")
        for j, plane in enumerate(PLANES):
            data[f"{key}_{plane}_deg"] = a[idx, j]
    return pa.table(data)


def events_table(docs: list[dict]) -> pa.Table:
    ev = sorted(docs, key=lambda e: (int(e["k"]), e["side"], e["type"]))
    return pa.table({"side": pa.array([e["side"] for e in ev], pa.string()),
                     "type": pa.array([e["type"] for e in ev], pa.string()),
                     "k": pa.array([int(e["k"]) for e in ev], pa.int64()),
                     "k_detect": pa.array([int(e["k_detect"]) for e in ev], pa.int64()),
                     "t_ns": pa.array([int(e["t_ns"]) for e in ev], pa.int64())})


def store_live_outputs(path: str | Path, root: str | Path, session: dict, content_hash: str,
                       settings_hash: str = "") -> list[dict]:
    """Decode the live topics of ``path`` and write them as series of the session; the ``live_outputs`` rows
    (without ``content_hash``/``session_id``, which the ingest's commit adds)."""
    live = read_live_topics(path)
    ang = angles_table(live["angles"])
    rows = []
    tag = f"{content_hash[:16]}{settings_hash[:8]}"
    if ang is not None:
        rel = series_relpath(session["study"], session["participant"], session["session"], "live", f"live_angles-{tag}")
        write_table(Path(root), rel, ang)
        rows.append({"kind": "angles", "n_rows": ang.num_rows, "series_path": rel,
                     "meta": json.dumps({"calibration": live["calibration"], "standing": live["standing"]})})
    if live["events"] or ang is not None:
        ev = events_table(live["events"])
        rel = series_relpath(session["study"], session["participant"], session["session"], "live", f"live_events-{tag}")
        write_table(Path(root), rel, ev)
        rows.append({"kind": "events", "n_rows": ev.num_rows, "series_path": rel, "meta": None})
    return rows
