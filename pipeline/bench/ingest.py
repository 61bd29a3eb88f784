"""``stridelab bench ingest``: MCAP -> committed warehouse throughput and peak memory.

A synthetic 24 h, 100 Hz chest IMU recording (ROS 2 ``sensor_msgs/Imu`` CDR, one message per sample)
is written with the vectorised writer, then ingested into a fresh warehouse in a child process
whose peak resident memory is reported. The ``mcap`` library's own per-message ROS 2 decoding and
bare message iteration are timed on a slice of the same file, in the same run, for comparison.
"""
from __future__ import annotations

import multiprocessing as mp
import resource
import tempfile
import time
from pathlib import Path

import click
import numpy as np

from pipeline.console import emit_json, err_console

T0_NS = 1_772_409_600_000_000_000   # 2026-03-02 00:00 UTC


def synthetic_imu_day(hours: float, rate_hz: float, seed: int = 0):
    """A chest IMU with gravity, slow posture drift and noise (values only need to be plausible SI)."""
    from estimators.recording import ImuData, Recording
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
    from pipeline import runner
    t0 = time.perf_counter()
    s = runner.run(Path(root), None, files=[Path(path)], stages=False, command="bench ingest")
    q.put({"seconds": time.perf_counter() - t0, "ingested": len(s.ingested), "quarantined": s.quarantined})


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
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
def command(hours, rate_hz, naive_samples, workdir, as_json) -> None:
    """Ingest speed (samples/s into the committed warehouse) and peak memory of the ingest process.

    \b
    Examples:
      stridelab bench ingest --json
      stridelab bench ingest --hours 1 --json
    """
    from pipeline.formats.mcap_write import write_recording
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        tmp = Path(tmp)
        err_console.print(f"simulating {hours:g} h at {rate_hz:g} Hz …")
        rec = synthetic_imu_day(hours, rate_hz)
        n = len(rec.imu["chest"].t_ns)
        t0 = time.perf_counter()
        path = write_recording(rec, tmp / "bench_day.mcap")
        write_s = time.perf_counter() - t0
        del rec
        err_console.print(f"wrote {n:,} messages ({path.stat().st_size / 1e6:.0f} MB) in {write_s:.1f} s; ingesting …")
        ctx = mp.get_context("spawn")
        q = ctx.Queue()
        p = ctx.Process(target=_ingest_child, args=(str(path), str(tmp / "wh"), q))
        p.start()
        res = q.get()
        p.join()
        peak_kb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
        if res["ingested"] != 1:
            raise click.ClickException(f"ingest failed: {res['quarantined']}")
        err_console.print("timing the mcap library on a slice of the same file …")
        naive = _naive(path, naive_samples)
        out = {
            "n_samples": n,
            "file_mb": path.stat().st_size / 1e6,
            "seconds": res["seconds"],
            "samples_per_s": n / res["seconds"],
            "peak_rss_mb": peak_kb / 1024,
            "writer_samples_per_s": n / write_s,
            **naive,
        }
        out["speedup_vs_naive_decode"] = out["samples_per_s"] / out["naive_decode_samples_per_s"]
    if as_json:
        emit_json({k: (round(v, 2) if isinstance(v, float) else v) for k, v in out.items()})
    else:
        for k, v in out.items():
            err_console.print(f"{k:>30}: {v:,.1f}" if isinstance(v, float) else f"{k:>30}: {v:,}")
