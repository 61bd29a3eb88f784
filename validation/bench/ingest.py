"""``stridelab bench ingest``: MCAP -> committed warehouse throughput and peak memory.

A synthetic 24 h, 100 Hz chest IMU recording (ROS 2 ``sensor_msgs/Imu`` CDR, one message per sample)
is written twice: with the project's vectorised writer (``samples_per_s``) and with ``mcap_ros2``'s
``Writer`` (``third_party_samples_per_s``: 1 MiB zstd chunks with the Schema and Channel records
inside them, as the ROS 2 tools write). Each is ingested into a fresh warehouse in its own child
process, whose peak resident memory is reported. The child first imports the pipeline and ingests a 36 s
recording into a new warehouse (``startup_seconds``: imports, numba's first-call initialisation of its
cached kernels, creating the catalog, DuckDB and Parquet writer set-up: what a worker process or a
warehouse pays once, not per file); ``seconds`` is the 24 h file's ingest run into that warehouse (a run
of its own: lock, run ledger, commit and snapshot included), and ``cold_samples_per_s`` counts the
start-up too.
``decompress_floor_samples_per_s`` is the
single-core zstd decompression of the third-party file's chunks alone, timed in the same run: the
ratio to it shows how close the reader is to the cost of merely inflating the data.

mcap_ros2's writer handles ~10-40k messages/s, so its 24 h file (8.6 M messages) takes minutes to
write; it is cached in ``--cache`` (default ``~/.cache/stridelab/bench``) and reused by later runs.
Its payloads are this project's CDR encoding handed through the writer (mcap_ros2's own encoder would
add ~8 minutes); the bench checks on a sample of messages that mcap_ros2's encoder produces the same
bytes, so the file is byte-for-byte what mcap_ros2 writes for these messages.
The ``mcap`` library's own per-message ROS 2 decoding and bare message iteration are timed on a
slice of the same file, in the same run, for comparison.
"""
from __future__ import annotations

import multiprocessing as mp
import os
import resource
import tempfile
import time
from pathlib import Path

import click
import numpy as np

from stridelab.pipeline.console import emit_json, err_console

T0_NS = 1_772_409_600_000_000_000   # 2026-03-02 00:00 UTC


def synthetic_imu_day(hours: float, rate_hz: float, seed: int = 0):
    """A chest IMU with gravity, slow posture drift and noise (values only need to be plausible SI)."""
    from stridelab.estimators.recording import ImuData, Recording
    rng = np.random.default_rng(seed)
    n = int(hours * 3600 * rate_hz)
    t = T0_NS + np.round(np.arange(n) * (1e9 / rate_hz)).astype(np.int64)
    tilt = 0.3 * np.sin(np.arange(n) / (rate_hz * 900.0))
    acc = np.empty((n, 3))
    acc[:, 0] = 9.81 * np.sin(tilt)
    acc[:, 1] = 0.0
    acc[:, 2] = 9.81 * np.cos(tilt)
    acc += rng.normal(0, 0.05, (n, 3))
    gyr = rng.normal(0, 0.01, (n, 3))
    meta = {"study": "bench", "participant": "B001", "session": "B001-day", "kind": "free_living",
            "trial": "day", "timezone": "Europe/Zurich"}
    return Recording(meta, imu={"chest": ImuData(t, acc, gyr, None)}, name="bench_day")


def _ingest_child(path: str, root: str, q) -> None:
    t_start = time.perf_counter()
    from stridelab.pipeline import runner
    from stridelab.pipeline.formats.mcap_write import write_recording
    warm = Path(root).with_name(Path(root).name + "-startup")
    warm.mkdir()
    rec = synthetic_imu_day(0.01, 100.0, seed=1)
    rec.metadata.update(participant="B000", session="B000-startup")
    small = write_recording(rec, warm / "warm.mcap")
    s = runner.run(Path(root), None, files=[small], stages=False, command="bench ingest")
    if len(s.ingested) != 1:
        q.put({"ingested": 0, "quarantined": s.quarantined})
        return
    t0 = time.perf_counter()
    s = runner.run(Path(root), None, files=[Path(path)], stages=False, command="bench ingest")
    q.put({"seconds": time.perf_counter() - t0, "startup_seconds": t0 - t_start, "ingested": len(s.ingested),
           "quarantined": s.quarantined, "peak_kb": _peak_kb()})


def _peak_kb() -> int:
    """Peak resident memory of this process. VmHWM belongs to the process's own address space; getrusage's
    ru_maxrss survives exec on Linux, so a spawned child would report the parent's peak at fork time."""
    try:
        for line in open("/proc/self/status"):
            if line.startswith("VmHWM:"):
                return int(line.split()[1])
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def _ingest_in_child(path: Path, root: Path) -> dict:
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=_ingest_child, args=(str(path), str(root), q))
    p.start()
    res = q.get()
    p.join()
    if res["ingested"] != 1:
        raise click.ClickException(f"ingest of {path.name} failed: {res['quarantined']}")
    return res


def write_third_party(rec, path: Path, sample_check: int = 2000) -> Path:
    """``rec``'s chest IMU written with mcap_ros2's Writer (1 MiB zstd chunks, Schema/Channel in chunks)."""
    from mcap_ros2._dynamic import serialize_dynamic
    from mcap_ros2.writer import Writer
    from stridelab.pipeline.formats import ros2_cdr
    x = rec.imu["chest"]
    schema_text = ros2_cdr.SCHEMAS["sensor_msgs/msg/Imu"]
    enc = serialize_dynamic("sensor_msgs/msg/Imu", schema_text)["sensor_msgs/msg/Imu"]
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    with open(tmp, "wb") as f:
        w = Writer(f)
        schema = w.register_msgdef("sensor_msgs/msg/Imu", schema_text)
        w._encoders[schema.id] = bytes          # payloads below are already CDR (checked against `enc`)
        step = 1 << 16
        for a in range(0, len(x.t_ns), step):
            b = min(a + step, len(x.t_ns))
            pay = ros2_cdr.encode_imu(x.t_ns[a:b], x.acc[a:b], x.gyr[a:b], "chest")
            ts = x.t_ns[a:b].tolist()
            if a == 0:
                for i in range(min(sample_check, b)):
                    msg = {"header": {"stamp": {"sec": ts[i] // 10**9, "nanosec": ts[i] % 10**9}, "frame_id": "chest"},
                           "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
                           "orientation_covariance": [-1.0] + [0.0] * 8,
                           "angular_velocity": dict(zip("xyz", x.gyr[i].tolist())),
                           "angular_velocity_covariance": [0.0] * 9,
                           "linear_acceleration": dict(zip("xyz", x.acc[i].tolist())),
                           "linear_acceleration_covariance": [0.0] * 9}
                    if enc(msg) != pay[i].tobytes():
                        raise click.ClickException("mcap_ros2's encoder disagrees with the project's CDR bytes")
            for i, t in enumerate(ts):
                w.write_message("/imu/chest", schema, pay[i], log_time=t, publish_time=t, sequence=a + i)
        w.add_metadata("session", dict(rec.metadata))
        w.finish()
    os.replace(tmp, path)
    return path


def decompress_floor(path: Path, clock=time.perf_counter) -> tuple[float, int]:
    """(seconds, messages) of decompressing every chunk of ``path`` on one core (reading not timed); ``clock``:
    wall time by default (a rate beside the ingest's wall-time rate), ``time.thread_time`` for CPU seconds."""
    import zstandard
    from mcap.reader import make_reader
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
        dctx = zstandard.ZstdDecompressor()
        spent, n = 0.0, 0
        for ci in summary.chunk_indexes:
            f.seek(ci.chunk_start_offset + 9 + 8 + 8 + 8 + 4)
            clen = int.from_bytes(f.read(4), "little")
            f.seek(clen + 8, 1)
            data = f.read(ci.compressed_size)
            t0 = clock()
            dctx.decompress(data, max_output_size=ci.uncompressed_size)
            spent += clock() - t0
        n = sum(summary.statistics.channel_message_counts.values())
    return spent, n


def reading_floor(paths: list[Path]) -> float:
    """CPU-seconds (one core) that no ingest of ``paths`` can go below without storing something else: the
    SHA-256 of every file's bytes (the warehouse's ``content_hash``, a key of every table) and the zstd
    decompression of every chunk (:func:`decompress_floor`). Reading the bytes is not timed; the work is timed
    with this thread's CPU clock (``time.thread_time``), so a loaded machine does not inflate it."""
    import hashlib
    spent = 0.0
    for path in paths:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            while block := f.read(8 << 20):
                t0 = time.thread_time()
                h.update(block)
                spent += time.thread_time() - t0
        spent += decompress_floor(path, clock=time.thread_time)[0]
    return spent


def _naive(path: Path, limit: int) -> dict:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    with open(path, "rb") as f:
        r = make_reader(f, decoder_factories=[DecoderFactory()])
        t0 = time.perf_counter()
        n = 0
        for _s, _c, _m, dec in r.iter_decoded_messages(topics=["/imu/chest"]):
            _ = (dec.linear_acceleration.x, dec.angular_velocity.x)
            n += 1
            if n >= limit:
                break
        decode = n / (time.perf_counter() - t0)
    with open(path, "rb") as f:
        r = make_reader(f)
        t0 = time.perf_counter()
        n = 0
        for _m in r.iter_messages(topics=["/imu/chest"]):
            n += 1
            if n >= 10 * limit:
                break
        bare = n / (time.perf_counter() - t0)
    return {"naive_decode_samples_per_s": decode, "naive_iterate_messages_per_s": bare}


@click.command("ingest")
@click.option("--hours", type=click.FloatRange(0.01, 48), default=24.0, show_default=True,
              help="Length of the synthetic recording.")
@click.option("--rate", "rate_hz", type=click.FloatRange(1, 2000), default=100.0, show_default=True)
@click.option("--naive-samples", type=int, default=30000, show_default=True,
              help="Messages decoded with the mcap library for the comparison.")
@click.option("--workdir", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Where to write the temporary file and warehouse [default: a temp dir].")
@click.option("--cache", "cache_dir", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Where the mcap_ros2-written file is kept between runs [default: ~/.cache/stridelab/bench].")
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
def command(hours, rate_hz, naive_samples, workdir, cache_dir, as_json) -> None:
    """Ingest speed (samples/s into the committed warehouse) and peak memory of the ingest process.

    \b
    Examples:
      stridelab bench ingest --json
      stridelab bench ingest --hours 1 --json
    """
    try:
        import mcap_ros2  # noqa: F401  (the third-party writer and decoder the bench compares with)
    except ImportError:
        raise click.ClickException("bench ingest compares with mcap_ros2's writer and decoder, which is not installed: "
                                   "pip install 'stridelab[bench]' (make install does)") from None
    from stridelab.pipeline.formats.mcap_write import write_recording
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        tmp = Path(tmp)
        err_console.print(f"simulating {hours:g} h at {rate_hz:g} Hz …")
        rec = synthetic_imu_day(hours, rate_hz)
        n = len(rec.imu["chest"].t_ns)
        t0 = time.perf_counter()
        path = write_recording(rec, tmp / "bench_day.mcap")
        write_s = time.perf_counter() - t0
        err_console.print(f"wrote {n:,} messages ({path.stat().st_size / 1e6:.0f} MB) in {write_s:.1f} s")
        cache = Path(cache_dir or Path.home() / ".cache" / "stridelab" / "bench")
        cache.mkdir(parents=True, exist_ok=True)
        third = cache / f"mcap_ros2_chest_{hours:g}h_{rate_hz:g}hz_v1.mcap"
        if not third.is_file():
            err_console.print(f"writing the same recording with mcap_ros2's Writer into {third} (once; minutes) …")
            write_third_party(rec, third)
        del rec
        err_console.print("ingesting the project's file …")
        res = _ingest_in_child(path, tmp / "wh")
        err_console.print("ingesting the mcap_ros2 file …")
        res3 = _ingest_in_child(third, tmp / "wh3")
        err_console.print("single-core decompression floor of the mcap_ros2 file …")
        floor_s, floor_n = decompress_floor(third)
        err_console.print("timing the mcap library on a slice of the same file …")
        naive = _naive(path, naive_samples)
        from stridelab.pipeline.formats.mcap_read import read_threads
        out = {
            "n_samples": n,
            "file_mb": path.stat().st_size / 1e6,
            "seconds": res["seconds"],
            "samples_per_s": n / res["seconds"],
            "startup_seconds": res["startup_seconds"],
            "cold_samples_per_s": n / (res["seconds"] + res["startup_seconds"]),
            "peak_rss_mb": res["peak_kb"] / 1024,
            "third_party_file_mb": third.stat().st_size / 1e6,
            "third_party_seconds": res3["seconds"],
            "third_party_samples_per_s": floor_n / res3["seconds"],
            "third_party_cold_samples_per_s": floor_n / (res3["seconds"] + res3["startup_seconds"]),
            "third_party_peak_rss_mb": res3["peak_kb"] / 1024,
            "decompress_floor_samples_per_s": floor_n / floor_s,
            "read_threads": read_threads(),
            "writer_samples_per_s": n / write_s,
            **naive,
        }
        out["third_party_ratio_to_floor"] = out["third_party_samples_per_s"] / out["decompress_floor_samples_per_s"]
        out["speedup_vs_naive_decode"] = out["samples_per_s"] / out["naive_decode_samples_per_s"]
    out["ratio_to_floor"] = out["samples_per_s"] / out["decompress_floor_samples_per_s"]
    err_console.print(f"ingest / single-core decompression floor: project file {out['ratio_to_floor']:.2f}, "
                      f"third-party file {out['third_party_ratio_to_floor']:.2f}")
    if as_json:
        emit_json({k: (round(v, 2) if isinstance(v, float) else v) for k, v in out.items()})
    else:
        for k, v in out.items():
            err_console.print(f"{k:>30}: {v:,.2f}" if isinstance(v, float) else f"{k:>30}: {v:,}")
