"""``stridelab export table`` and ``stridelab export bids`` on a warehouse made the real way; the BIDS dataset is
checked by the official BIDS validator (npm bids-validator, installed by ``make bids-validator``)."""
from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
VALIDATOR = ROOT / "tools" / "bids-validator" / "node_modules" / ".bin" / "bids-validator"


def _cli(*args, check=True):
    r = subprocess.run([sys.executable, "-m", "stridelab", *map(str, args)], capture_output=True, text=True,
                       cwd=ROOT, timeout=900, env={**os.environ, "PYTHONPATH": str(ROOT)})
    if check:
        assert r.returncode == 0, r.stderr
    return r


def test_export_table_to_csv_and_parquet_equals_the_snapshot(small_home, tmp_path):
    import stridelab
    wh = small_home / "warehouse"
    r = json.loads(_cli("export", "table", "strides", tmp_path / "s.parquet", "--warehouse", wh, "--json").stdout)
    r_csv = _cli("export", "table", "strides", tmp_path / "s.csv", "--warehouse", wh)
    assert "Warning" not in r_csv.stderr, r_csv.stderr
    with stridelab.open(wh) as w:
        ref = w.table("strides")
    pqt = pq.read_table(tmp_path / "s.parquet").to_pandas()
    assert r["rows"] == len(ref) == len(pqt) > 0
    assert list(pqt.columns) == list(ref.columns)
    np.testing.assert_allclose(pqt["stride_length_m"], ref["stride_length_m"])
    with open(tmp_path / "s.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(ref)
    np.testing.assert_allclose([float(x["stride_length_m"]) for x in rows], ref["stride_length_m"], rtol=1e-12)


def test_export_table_leaves_source_paths_out_and_refuses_bad_names(small_home, tmp_path):
    wh = small_home / "warehouse"
    r = json.loads(_cli("export", "table", "recordings", tmp_path / "r.csv", "--warehouse", wh, "--json").stdout)
    assert r["left_out"] == ["source_path"] and "source_path" not in r["columns"]
    bad = _cli("export", "table", "nope", tmp_path / "x.csv", "--warehouse", wh, check=False)
    assert bad.returncode == 2 and "no table 'nope'" in bad.stderr and "strides" in bad.stderr
    bad = _cli("export", "table", "strides", tmp_path / "x.xlsx", "--warehouse", wh, check=False)
    assert bad.returncode == 2 and "name the file .csv or .parquet" in bad.stderr


@pytest.fixture(scope="module")
def bids(small_home, tmp_path_factory):
    out = tmp_path_factory.mktemp("bids") / "ds"
    key = out.parent / "key.tsv"
    s = json.loads(_cli("export", "bids", small_home / "warehouse", out, "--subject-map", key, "--author", "A. Researcher",
                        "--author", "B. Clinician", "--json").stdout)
    return out, key, s


def test_bids_layout_units_and_pseudonyms(bids, small_home):
    import stridelab
    out, key, s = bids
    assert s["subjects"] == 1 and s["sessions"] == 4 and s["recordings"] == 8 and s["events"] > 0
    assert (out / "participants.tsv").read_text().splitlines()[1].startswith("sub-01\t")
    assert json.loads((out / "dataset_description.json").read_text())["Authors"] == ["A. Researcher", "B. Clinician"]
    motion = sorted(out.rglob("*_motion.tsv"))
    assert len(motion) == s["motion_files"] == 8
    walk = next(p for p in motion if "ses-lab1_task-walk_tracksys-IMU_run-1" in p.name)
    chans = list(csv.DictReader(open(str(walk).replace("_motion.tsv", "_channels.tsv")), delimiter="\t"))
    data = np.loadtxt(walk, delimiter="\t")
    assert data.shape[1] == len(chans)
    i = next(k for k, c in enumerate(chans) if c["name"] == "foot_left_acc_z")
    assert chans[i]["units"] == "m/s^2" and chans[i]["type"] == "ACCEL" and chans[i]["tracked_point"] == "foot_left"
    with stridelab.open(small_home) as wh:
        stored = wh.imu("P001-lab-1", "foot_left", trial="walk-1")
    np.testing.assert_allclose(data[:, i], stored.acc[:, 2], atol=1e-6)
    side = json.loads(Path(str(walk).replace(".tsv", ".json")).read_text())
    assert side["SamplingFrequency"] == pytest.approx(stored.sampling_rate_hz)
    ev = list(csv.DictReader(open(next(walk.parent.glob("*task-walk_run-1_events.tsv"))), delimiter="\t"))
    assert {e["source"] for e in ev} == {"reference", "stridelab"} and {"IC", "TC"} <= {e["trial_type"] for e in ev}
    # nothing of the warehouse's identity, file names or dates leaks into the dataset
    text = "".join(p.read_text() for p in out.rglob("*") if p.is_file() and p.suffix in (".json", ".tsv", "")
                   and not p.name.endswith("_motion.tsv"))
    for leaked in ("P001", "demo", ".mcap", "2026-"):
        assert leaked not in text, leaked
    assert "P001" in key.read_text()


def test_bids_export_refuses_to_overwrite_and_bad_kinds(bids, small_home):
    out, _, _ = bids
    r = _cli("export", "bids", small_home / "warehouse", out, check=False)
    assert r.returncode == 2 and "not empty" in r.stderr and "--overwrite" in r.stderr


@pytest.mark.skipif(not VALIDATOR.exists(), reason=f"BIDS validator not installed at {VALIDATOR}: run `make bids-validator` "
                                                   "(needs Node.js and npm)")
def test_the_official_bids_validator_finds_no_error(bids, tmp_path):
    out, _, _ = bids

    def validate(d):
        r = subprocess.run([str(VALIDATOR), "--json", str(d)], capture_output=True, text=True, timeout=600)
        return json.loads(r.stdout)

    report = validate(out)
    assert report["issues"]["errors"] == [], [e["key"] for e in report["issues"]["errors"]]
    # the one warning left is the legacy validator reading the first row of a (headerless) *_motion.tsv as a header
    assert {w["key"] for w in report["issues"]["warnings"]} <= {"CUSTOM_COLUMN_WITHOUT_DESCRIPTION"}
    assert set(report["summary"]["dataTypes"]) >= {"motion", "channels", "events"}
    # the validator is not a rubber stamp: a motion sidecar without its sampling frequency is an error
    broken = tmp_path / "broken"
    shutil.copytree(out, broken)
    side = next(broken.rglob("*_motion.json"))
    d = json.loads(side.read_text())
    del d["SamplingFrequency"]
    side.write_text(json.dumps(d))
    assert validate(broken)["issues"]["errors"]


def test_exports_take_output_names_up_to_255_bytes(small_home, tmp_path):
    """Both exports write beside the output under a temporary name first: it must not pass 255 bytes when the
    output's does not (names above ~240 bytes failed with 'File name too long', as the MCAP writer's did)."""
    from stridelab.pipeline.export.bids import export_bids
    from stridelab.pipeline.export.tables import export_table
    wh = small_home / "warehouse"
    for name in ("Ł" * 125 + ".csv", "L" * 243 + ".parquet"):                     # 254 and 251 bytes
        out = tmp_path / "t" / name
        assert len(os.fsencode(name)) <= 255 < len(os.fsencode(f".{name}.tmp-{os.getpid()}"))
        assert export_table(wh, "strides", out)["rows"] > 0
        assert [p.name for p in out.parent.iterdir()] == [name]                   # no temporary left
        out.unlink()
    out = tmp_path / "b" / ("B" * 250)
    out.parent.mkdir()
    export_bids(wh, out)
    assert (out / "dataset_description.json").is_file() and [p.name for p in out.parent.iterdir()] == [out.name]
