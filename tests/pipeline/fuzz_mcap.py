"""Seeded fuzzing of MCAP ingest: corrupted copies of real recordings must be refused or stored unchanged.

Run by ``tests/pipeline/test_fuzz.py`` in a fresh process (its peak memory is the figure reported):
``python -m tests.pipeline.fuzz_mcap --seed 17 --out DIR`` prints one JSON object with the outcome counts
per kind of mutation. Each mutant goes through :func:`stridelab.pipeline.ingest.prepare`, the worker-side half of
ingest that decodes, validates and writes the series; what it would hand to the catalog (session
metadata, sensors, events, ignored topics and the decoded series) is compared with the original's.

Outcomes: ``quarantined`` (refused with a non-empty one-line reason), ``same`` (stored, data identical
to the original), ``different`` (stored with other data: the failure this guards against), ``crash``
(prepare raised) and ``hang`` (more than ``HANG_S`` seconds).
"""
from __future__ import annotations

import argparse
import json
import re
import resource
import shutil
import signal
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

HANG_S = 30
#: a reason naming a low-level exception instead of what is wrong with the file
LOW_LEVEL = re.compile(r"internal error|Traceback|EndOfFile|UnicodeDecodeError|struct\.error|KeyError|IndexError|"
                       r"MemoryError|OverflowError|codec can't")


def _walk(buf: bytes) -> list[tuple[int, int, int]]:
    """(offset, opcode, body length) of every top-level record, data and summary sections."""
    out, p = [], 8
    while p + 9 <= len(buf) - 8:
        op, ln = buf[p], int.from_bytes(buf[p + 1:p + 9], "little")
        out.append((p, op, ln))
        if op == 0x02:          # footer
            break
        p += 9 + ln
    return out


def _controls(d: Path, orig: Path) -> list[tuple[str, bytes]]:
    """Valid files whose expected outcome is known: the comparison must call a real change 'different'
    and a mere re-chunking 'same' (else the campaign could not fail)."""
    from dataclasses import replace
    from stridelab.pipeline.formats.mcap_write import write_recording
    from tests.corpus import small_recording
    rec = small_recording(seconds=3.0, seed=0, session="P001-lab-1", participant="P001", trial="walk-1",
                          placements=("pelvis", "thigh_left", "shank_left"))
    rec = replace(rec, metadata=dict(rec.metadata, thigh_length_m="0.410", height_m="1.66"))
    out = []
    for name, r, kw in (("control_same_rechunked", rec, {"chunk_bytes": 20 << 10}),
                        ("control_other_participant", replace(rec, metadata=dict(rec.metadata, participant="P003")), {}),
                        ("control_other_thigh_length", replace(rec, metadata=dict(rec.metadata, thigh_length_m="0.510")), {})):
        f = write_recording(r, d / "control.tmp.mcap", **kw)
        out.append((name, f.read_bytes()))
        f.unlink()
    return out


def originals(d: Path) -> list[Path]:
    """Three recordings of the recording format (IMU + magnetometer + pose + events, session numbers),
    written by the project's writer in small chunks so that a file has many of them."""
    from dataclasses import replace
    from stridelab.pipeline.formats.mcap_write import write_recording
    from tests.corpus import small_recording
    d.mkdir(parents=True, exist_ok=True)
    specs = [dict(seconds=3.0, seed=0, session="P001-lab-1", participant="P001", trial="walk-1",
                  placements=("pelvis", "thigh_left", "shank_left")),
             dict(seconds=2.0, seed=1, session="P002-lab-1", participant="P002", trial="walk-2",
                  placements=("foot_left", "foot_right")),
             dict(seconds=2.5, seed=2, session="P003-lab-1", participant="P003", trial="calibration",
                  placements=("pelvis", "chest"))]
    out = []
    for k, spec in enumerate(specs):
        rec = small_recording(**spec)
        rec = replace(rec, metadata=dict(rec.metadata, thigh_length_m="0.410", height_m="1.66"))
        out.append(write_recording(rec, d / f"orig{k}.mcap", chunk_bytes=48 << 10))
    # a third-party file: mcap_ros2's writer (Schema/Channel inside chunks, chunk and summary CRCs, no
    # data-section CRC, like rosbag2's mcap storage)
    from tests.pipeline._interop import write_mcap_ros2
    rec = small_recording(seconds=2.0, seed=3, session="P004-lab-1", participant="P004", trial="walk-1",
                          placements=("pelvis", "thigh_left"))
    out.append(write_mcap_ros2(d / "orig3_mcap_ros2.mcap", rec, chunk_size=16 << 10))
    # a file without CRCs (allowed by MCAP; mcap_ros2's writer with enable_crcs=False): its mutants are counted
    # apart (kinds ending in _without_crc): a changed value there is undetectable, so it may be stored, but the
    # recording must then be marked unverified (crc_verified False), never passed off as checked (issue #47)
    out.append(_write_without_crcs(d / "orig4_without_crc.mcap"))
    return out


NO_CRC = "orig4_without_crc.mcap"


def _write_without_crcs(path: Path) -> Path:
    from mcap_ros2.writer import Writer
    from tests.corpus import small_recording
    from tests.pipeline._interop import IMU_DEF, imu_dict
    rec = small_recording(seconds=2.0, seed=4, session="P005-lab-1", participant="P005", trial="walk-1",
                          placements=("pelvis", "shank_left"))
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=16 << 10, enable_crcs=False)
        w.add_metadata("session", dict(rec.metadata))
        s = w.register_msgdef("sensor_msgs/msg/Imu", IMU_DEF)
        msgs = sorted((t, pl, i) for pl, x in rec.imu.items() for i, t in enumerate(x.t_ns.tolist()))
        for k, (t, pl, i) in enumerate(msgs):
            x = rec.imu[pl]
            w.write_message(f"/imu/{pl}", s, imu_dict(t, x.acc[i], x.gyr[i], pl), log_time=t, publish_time=t,
                            sequence=k)
        w.finish()
    return path


def _data_crc(buf: bytes) -> int:
    for p, op, ln in _walk(buf):
        if op == 0x0F:          # DataEnd
            return int.from_bytes(buf[p + 9:p + 13], "little")
    return 0


def _special_mutants(d: Path, orig: Path, rng) -> list[tuple[str, bytes]]:
    """Hand-made corruptions: an oversized chunk, zip bombs, wrong payload sizes."""
    import zstandard
    from mcap.records import Chunk, DataEnd
    from mcap.writer import Writer
    from stridelab.pipeline.formats import ros2_cdr
    from tests.corpus import small_recording
    from tests.pipeline.test_mcap_corruption import _records, _schema_channel
    buf = orig.read_bytes()
    out = []
    chunks = [(p, ln) for p, op, ln in _walk(buf) if op == 0x06]
    for p, _ in chunks[:2]:                     # a chunk declaring 2^40 uncompressed bytes
        b = bytearray(buf)
        b[p + 9 + 16:p + 9 + 24] = (1 << 40).to_bytes(8, "little")
        out.append(("oversized_chunk", bytes(b)))
    for content_size in (True, False):          # 200 MB of zeros in a ~6 kB zstd frame, declared as 1 MB
        bomb = zstandard.ZstdCompressor(level=3, write_content_size=content_size).compress(bytes(200 << 20))
        out.append(("zip_bomb", _records(*_schema_channel(), Chunk(
            message_start_time=0, message_end_time=0, uncompressed_size=1 << 20, uncompressed_crc=0,
            compression="zstd", data=bomb), DataEnd(data_section_crc=0))))
    rec = small_recording(seconds=2.0, placements=("foot_left",))
    x = rec.imu["foot_left"]
    imu = ros2_cdr.encode_imu(x.t_ns, x.acc, x.gyr, "foot_left")
    mag = ros2_cdr.encode_mag(x.t_ns, x.mag, "foot_left")
    cases = [("sensor_msgs/msg/MagneticField", "/mag/foot_left", [p.tobytes() for p in imu]),    # Imu on a mag channel
             ("sensor_msgs/msg/Imu", "/imu/foot_left", [p.tobytes()[:-8] for p in imu]),         # 8 bytes short
             ("sensor_msgs/msg/Imu", "/imu/foot_left", [p.tobytes() + bytes(8) for p in imu])]   # 8 bytes long
    cases.append(("sensor_msgs/msg/Imu", "/imu/foot_left", [p.tobytes() for p in mag]))          # mag on an IMU channel
    for schema, topic, payloads in cases:
        f = d / "payload.tmp"
        with open(f, "wb") as fh:
            w = Writer(fh)
            w.start("ros2", "fuzz")
            sid = w.register_schema(schema, "ros2msg", ros2_cdr.SCHEMAS[schema].encode())
            cid = w.register_channel(topic, "cdr", sid)
            w.add_metadata("session", dict(rec.metadata))
            for t, pl in zip(x.t_ns.tolist(), payloads):
                w.add_message(cid, t, pl, t)
            w.finish()
        out.append(("wrong_payload_size", f.read_bytes()))
        f.unlink()
    return out


def mutants(d: Path, origs: list[Path], seed: int, per_file: dict[str, int]) -> list[tuple[str, int, bytes]]:
    """(kind, index of the original or -1, bytes) of every mutant; the same seed gives the same list."""
    rng = np.random.default_rng(seed)
    out: list[tuple[str, int, bytes]] = []
    for k, f in enumerate(origs):
        buf = f.read_bytes()
        recs = _walk(buf)
        suffix = "_without_crc" if f.name == NO_CRC else ""
        meta = [(p, ln) for p, op, ln in recs if op in (0x03, 0x04, 0x0C) and ln > 0]   # Schema, Channel, Metadata
        for _ in range(per_file["bit_flip"]):
            b = bytearray(buf)
            i = int(rng.integers(0, len(b)))
            b[i] ^= 1 << int(rng.integers(0, 8))
            out.append(("bit_flip" + suffix, k, bytes(b)))
        unprotected = _data_crc(buf) == 0
        for _ in range(per_file["bit_flip_in_schema_channel_metadata"]):
            p, ln = meta[int(rng.integers(0, len(meta)))]
            b = bytearray(buf)
            i = p + 9 + int(rng.integers(0, ln))
            b[i] ^= 1 << int(rng.integers(0, 8))
            # a top-level Metadata record of a file without a data-section CRC is covered by no checksum:
            # a flipped value cannot be detected by any reader (counted apart, see docs/operations.md)
            kind = ("bit_flip_in_schema_channel_metadata" + suffix if suffix else
                    "bit_flip_in_metadata_without_data_crc" if unprotected and buf[p] == 0x0C
                    else "bit_flip_in_schema_channel_metadata")
            out.append((kind, k, bytes(b)))
        for _ in range(per_file["truncation"]):
            out.append(("truncation" + suffix, k, buf[:int(rng.integers(0, len(buf)))]))
        for _ in range(per_file["zeroed_range"]):
            b = bytearray(buf)
            i = int(rng.integers(0, len(b)))
            n = int(rng.integers(1, 4097))
            b[i:i + n] = bytes(len(b[i:i + n]))
            out.append(("zeroed_range" + suffix, k, bytes(b)))
    for kind, data in _special_mutants(d, origs[0], rng):
        out.append((kind, 0 if kind == "oversized_chunk" else -1, data))
    for kind, data in _controls(d, origs[0]):
        out.append((kind, 0, data))
    return out


def stored(p, root: Path) -> dict | None:
    """What the catalog and the series store would hold for a prepared file (None when quarantined)."""
    if p.status != "ingested":
        return None
    sensors = []
    for s in sorted(p.sensors, key=lambda s: s["topic"]):
        tbl = pq.read_table(root / s["series_path"])
        sensors.append(({k: v for k, v in s.items() if k != "series_path"}, tbl))
    return {"metadata": p.metadata, "events": p.events, "ignored": sorted(p.ignored_topics), "sensors": sensors}


def same(a: dict, b: dict) -> bool:
    if (a["metadata"], a["events"], a["ignored"]) != (b["metadata"], b["events"], b["ignored"]):
        return False
    if len(a["sensors"]) != len(b["sensors"]):
        return False
    for (ma, ta), (mb, tb) in zip(a["sensors"], b["sensors"]):
        if ma != mb or not ta.equals(tb):
            return False
    return True


class _Hang(Exception):
    pass


def _alarm(signum, frame):
    raise _Hang()


def campaign(out_dir: Path, seed: int, per_file: dict[str, int]) -> dict:
    from stridelab.pipeline.ingest import prepare
    out_dir = Path(out_dir)
    origs = originals(out_dir / "originals")
    ref_root = out_dir / "ref"
    refs = []
    for f in origs:
        p = prepare(f, ref_root)
        assert p.status == "ingested", (f, p.reason)
        refs.append(stored(p, ref_root))
    muts = mutants(out_dir, origs, seed, per_file)
    counts: dict[str, Counter] = defaultdict(Counter)
    problems, slowest = [], 0.0
    signal.signal(signal.SIGALRM, _alarm)
    for n, (kind, k, data) in enumerate(muts):
        f = out_dir / f"mutant-{n:04d}.mcap"
        f.write_bytes(data)
        root = out_dir / f"wh-{n:04d}"
        t0 = time.perf_counter()
        signal.alarm(HANG_S)
        try:
            p = prepare(f, root)
            got = stored(p, root)
            if got is None:
                outcome = ("empty_reason" if not p.reason.strip() or "\n" in p.reason else
                           "low_level_reason" if LOW_LEVEL.search(p.reason) else "quarantined")
            else:
                outcome = "same" if k >= 0 and same(got, refs[k]) else "different"
                if outcome == "different" and kind.endswith("_without_crc") and p.crc_verified is False:
                    outcome = "different_unverified"      # undetectable without CRCs; marked as such
        except _Hang:
            outcome = "hang"
        except Exception as e:  # noqa: BLE001 - prepare must never raise for a bad file
            outcome = "crash"
            problems.append(f"{kind} #{n}: {type(e).__name__}: {str(e)[:120]}")
        finally:
            signal.alarm(0)
        slowest = max(slowest, time.perf_counter() - t0)
        if outcome in ("different", "empty_reason", "low_level_reason") and not kind.startswith("control_") \
                and not kind.endswith("_without_data_crc"):
            problems.append(f"{kind} #{n}: {outcome}" + (f": {p.reason[:160]}" if outcome != "different" else ""))
        counts[kind][outcome] += 1
        f.unlink()
        shutil.rmtree(root, ignore_errors=True)
    totals, totals_no_crc = Counter(), Counter()
    for kind, c in counts.items():
        if kind.endswith("_without_crc"):
            totals_no_crc.update(c)
        elif not kind.startswith("control_") and not kind.endswith("_without_data_crc"):
            totals.update(c)
    return {"seed": seed, "mutants": len(muts), "counts": {k: dict(v) for k, v in sorted(counts.items())},
            "totals": dict(totals), "totals_without_crc": dict(totals_no_crc), "problems": problems,
            "slowest_s": round(slowest, 2),
            "peak_rss_mb": _peak_rss_mb()}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, default=17)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--per-file", type=int, default=12, help="random bit flips per original (others scale)")
    a = ap.parse_args(argv)
    n = a.per_file
    per_file = {"bit_flip": n, "bit_flip_in_schema_channel_metadata": n, "truncation": max(2, n // 4),
                "zeroed_range": max(2, n // 4)}
    json.dump(campaign(a.out, a.seed, per_file), sys.stdout)
    sys.stdout.write("\n")


def _peak_rss_mb() -> float:
    """This process's own peak RSS: VmHWM restarts at exec, ru_maxrss keeps the forking parent's peak (a
    pytest process of 2 GB made every child report 2 GB)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return round(int(line.split()[1]) / 1024, 1)
    except OSError:
        pass
    return round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)


if __name__ == "__main__":
    main()

