"""``stridelab live``: build the source, calibration, recorder, server and session from the options, run it."""
from __future__ import annotations

import datetime as _dt
import json
import re
import secrets
import string
import signal
import threading
from pathlib import Path

from stridelab.pipeline.live.engine import LEG_PLACEMENTS, LiveParams

_CUE = re.compile(r"^([a-z_]+):(-?[0-9.]+):(-?[0-9.]+)$")


def parse_cue(text: str) -> dict:
    m = _CUE.match(text or "")
    if not m:
        raise ValueError(f"--cue {text!r}: expected MEASURE:LOW:HIGH, e.g. stance_asymmetry_pct:0:10")
    return {"measure": m.group(1), "low": float(m.group(2)), "high": float(m.group(3))}


def parse_osc(items) -> dict[str, int]:
    out = {}
    for it in items:
        p, _, port = it.partition("=")
        if p not in LEG_PLACEMENTS + ("chest", "lower_back") or not port.isdigit():
            raise ValueError(f"--osc {it!r}: expected PLACEMENT=PORT with a placement of {', '.join(LEG_PLACEMENTS)}")
        out[p] = int(port)
    return out


def run_live(*, replay=None, speed="1", minutes=None, osc=(), osc_host="127.0.0.1", osc_rate_hz=100.0,
             osc_clock="host",
             calibration=None, calibration_from=None, participant=None, inbox=None, name=None, record=True,
             host="127.0.0.1", port=8765, serve=True, cue="stance_asymmetry_pct:0:10", audio=False, session_fields=None,
             bands=None, band_note="", duration_s=None, on_ready=None, speed_estimate=False) -> dict:
    """Run one live session; returns the session summary (also what ``--json`` prints)."""
    from stridelab.pipeline.live.calibration import calibration_from_trial, calibration_from_warehouse
    from stridelab.pipeline.live.recorder import McapRecorder
    from stridelab.pipeline.live.server import LiveServer
    from stridelab.pipeline.live.session import LiveSession
    from stridelab.pipeline.live.sources import NgimuUdpSource, ReplaySource
    from stridelab.pipeline.live.streams import read_streams
    if (replay is None) == (not osc):
        raise ValueError("give either --replay FILE or --osc PLACEMENT=PORT (one or more)")
    cue_cfg = parse_cue(cue)
    cue_cfg["audio"] = bool(audio)
    meta = {}
    if replay is not None:
        streams = read_streams(replay)
        meta = dict(streams.metadata)
        placements = [p for p in LEG_PLACEMENTS if p in streams.sensors]
        fs = streams.sampling_rate_hz
        sp = None if str(speed) == "max" else float(speed)
        if sp is not None and sp <= 0:
            raise ValueError(f"--speed {speed}: must be > 0 or 'max'")
        source = ReplaySource(streams, placements, speed=sp, minutes=minutes)
        clock = "shared"
    else:
        ports = parse_osc(osc)
        placements = [p for p in LEG_PLACEMENTS if p in ports]
        fs = float(osc_rate_hz)
        source = NgimuUdpSource({p: ports[p] for p in placements}, host=osc_host,
                                timeout_s=duration_s)
        clock = osc_clock
    if not placements:
        raise ValueError("no lower-limb sensor (pelvis, thigh, shank, foot) in the input")
    cal, cal_note = None, "none"
    if calibration is not None:
        cal = calibration_from_trial(calibration)
        cal_note = f"{cal.status} (from {Path(calibration).name})"
    elif calibration_from is not None:
        who = participant or meta.get("participant")
        if not who:
            raise ValueError("--calibration-from needs --participant (the replayed file names none)")
        cal, sid = calibration_from_warehouse(calibration_from, who)
        cal_note = f"{cal.status} (stored, session {sid})"
    if participant:
        meta["participant"] = participant
    today = _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%dT%H%M%S")
    meta.setdefault("study", "live")
    meta.setdefault("participant", "P000")
    # letters only: the ingest refuses ids that look like dates (personal data)
    meta["session"] = f"{meta['participant']}-live-" + "".join(secrets.choice(string.ascii_lowercase) for _ in range(8))
    meta["kind"] = "lab"
    meta["trial"] = "live"
    meta["live_source"] = "replay" if replay is not None else "ngimu_osc"
    for k, v in (session_fields or {}).items():
        meta[k] = v
    recorder = None
    if record:
        if inbox is None:
            raise ValueError("--inbox is needed to record the session (or --no-record)")
        recorder = McapRecorder(inbox, name or f"{meta['participant']}_live_{today}", placements,
                                {k: v for k, v in meta.items()})
    session = LiveSession(source, placements, sampling_rate_hz=fs, calibration=cal, params=LiveParams(),
                          recorder=recorder, clock=clock, speed_estimate=bool(speed_estimate and serve))
    server = None
    if serve:
        server = LiveServer(session.hub, host=host, port=port, config={
            "participant": meta.get("participant"), "sampling_rate_hz": fs, "calibration": cal_note,
            "cue": cue_cfg, "bands": bands or {}, "band_note": band_note}, summary=session.summary)
        server.start()
    stop = threading.Event()
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, lambda *_: (stop.set(), session.stop()))
    if on_ready is not None:
        on_ready(server.url if server else None, source)
    try:
        summary = session.run(until=stop.is_set)
    finally:
        path = recorder.close() if recorder is not None else None
        if server is not None:
            server.stop()
    summary.update({"recording": str(path) if path else None, "calibration": cal_note,
                    "placements": placements, "bad_packets": getattr(source, "bad_packets", 0)})
    return summary


def print_summary(summary: dict, as_json: bool) -> None:
    if as_json:
        print(json.dumps(summary, default=str))
        return
    lat = summary["latency"]
    print(f"{summary['frames']} frames, {summary['samples_in']} samples, dropped {summary['samples_dropped']}, "
          f"lost {sum(summary['gaps'].values())}; latency p50 {lat['p50_ms']:.2f} ms, p99 {lat['p99_ms']:.2f} ms, "
          f"max {lat['max_ms']:.2f} ms; calibration {summary['calibration']}")
    if summary.get("recording"):
        print(f"recorded {summary['recording']}")
