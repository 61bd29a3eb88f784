"""Xsens MT text exports that the reader used to refuse or abort on (issues 42, 43, 47): a repeated packet counter
(policy: keep the row order, warn naming the file, count), MT Manager's own ``//`` header layout, and a folder with
one bad file (listed with the reason, the others go on). Files are written here by hand."""
from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from stridelab.pipeline.formats.xsens_mt import (XsensPacketWarning, load_voisard_dir, load_xsens_mt_txt, on_packet_grid,
                                       packet_index)
from stridelab.pipeline.importers import import_paths

COLS = ["PacketCounter", "SampleTimeFine", "Acc_X", "Acc_Y", "Acc_Z", "Gyr_X", "Gyr_Y", "Gyr_Z", "Mag_X", "Mag_Y",
        "Mag_Z"]


def _row(counter, k):
    """Row k (file order): values that differ row by row (acc_x = k) so the order can be checked."""
    return [float(counter), 1000.0 * k, float(k), 0.2, 9.8, 0.01 * k, -0.02, 0.03, 0.5, 0.0, -0.8]


def _write(path, counters, *, preamble=("Acquisition frequency: 100 Hz",), trailing_tab=False):
    end = "\t" if trailing_tab else ""
    lines = list(preamble) + ["\t".join(COLS) + end]
    lines += ["\t".join(str(v) for v in _row(c, k)) + end for k, c in enumerate(counters)]
    path.write_text("\n".join(lines) + "\n")
    return path


REPEAT = list(range(0, 20)) + [19] + list(range(20, 40))       # row 20 repeats counter 19 (values differ)


def test_repeated_counter_is_kept_in_row_order_warned_and_counted(tmp_path):
    p = _write(tmp_path / "7-3_lf.txt", REPEAT)
    with pytest.warns(XsensPacketWarning, match=r"7-3_lf\.txt.*repeats.*1 row.*data line 23"):
        r = load_xsens_mt_txt(p)
    assert r.n_repeated == 1 and r.acc.shape == (41, 3)
    np.testing.assert_array_equal(r.acc[:, 0], np.arange(41))               # file order kept, nothing dropped
    assert np.all(np.diff(r.index) >= 1)                                    # strictly increasing grid places
    assert r.index[20] == 20 and r.index[21] == 21                          # placed after its predecessor
    g = on_packet_grid(r)                                                   # old code: "packet counter repeats"
    assert g.acc.shape == (41, 3) and not g.filled.any() and g.n_repeated == 1


def test_repeat_absorbed_by_the_next_gap_and_step_back():
    # 0..9, 9 (repeat), 11.. : the repeated row fills the dropped packet 10, the rest keep their own counter
    idx, dropped, rep = packet_index(np.array(list(range(10)) + [9] + list(range(11, 20))))
    np.testing.assert_array_equal(idx, np.arange(20))
    assert dropped == 0 and list(rep) == [10]
    # a step back (5 after 7) is a repeated row too; the wrap of the 16-bit counter is not
    idx, dropped, rep = packet_index(np.array([65534, 65535, 0, 1, 2, 0, 3, 4]))
    np.testing.assert_array_equal(idx, [0, 1, 2, 3, 4, 5, 6, 7])
    assert list(rep) == [5] and dropped == 0


def test_mt_manager_header_lines_are_read(tmp_path):
    pre = ("// Start Time: Unknown", "// Update Rate: 60.0Hz", "// Filter Profile: human (46.1)",
           "// Option Flags: AHS Disabled ICC Disabled", "// Firmware Version: 4.0.2")
    p = _write(tmp_path / "mtm.txt", range(100, 130), preamble=pre, trailing_tab=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = load_xsens_mt_txt(p)
    assert r.sampling_rate_hz == 60.0 and r.acc.shape == (30, 3) and r.n_dropped == 0
    np.testing.assert_allclose(r.gyr[:, 0], 0.01 * np.arange(30))           # SampleTimeFine skipped by name
    q = _write(tmp_path / "norate.txt", range(30), preamble=("// Start Time: Unknown",))
    with pytest.raises(ValueError, match=r"norate\.txt.*Update Rate"):
        load_xsens_mt_txt(q)


def _voisard_trial(d, name, counters_lf=tuple(range(60))):
    (d / f"{name}.json").write_text(json.dumps({
        "Subject": int(name.split("-")[0]), "Trial": int(name.split("-")[1]), "TrialBoundaries": [5, 55],
        "UTurnBoundaries": [25, 30], "LeftFootEvents": [[10, 15]], "RightFootEvents": [[20, 24]]}))
    _write(d / f"{name}_lf.txt", list(counters_lf))
    _write(d / f"{name}_rf.txt", list(range(60)))


def test_voisard_folder_goes_on_past_a_bad_trial(tmp_path):
    _voisard_trial(tmp_path, "1-1")
    _voisard_trial(tmp_path, "1-2", counters_lf=list(range(30)) + [29] + list(range(30, 59)))
    _voisard_trial(tmp_path, "2-1")
    (tmp_path / "2-1_rf.txt").write_text("Acquisition frequency: 100 Hz\nPacketCounter\tAcc_X\n1\t2\n")
    skipped = []
    with pytest.warns(XsensPacketWarning, match=r"1-2_lf\.txt"):
        trials = load_voisard_dir(tmp_path, skipped=skipped)
    assert [t.name for t in trials] == ["1-1", "1-2"] and trials[1].left.n_repeated == 1
    assert len(skipped) == 1 and skipped[0][0] == "2-1" and "2-1_rf.txt" in skipped[0][1]
    with warnings.catch_warnings(), pytest.raises(ValueError, match=r"2-1_rf\.txt"):   # no list: the first bad raises
        warnings.simplefilter("ignore", XsensPacketWarning)
        load_voisard_dir(tmp_path)


def test_a_trial_that_is_a_truncated_copy_of_another_of_its_subject_is_named(tmp_path):
    from stridelab.pipeline.formats.xsens_mt import voisard_truncated_copies
    _voisard_trial(tmp_path, "3-1", counters_lf=range(60))
    _voisard_trial(tmp_path, "3-2", counters_lf=range(40))      # rows 0-39 of 3-1: a truncated copy
    _voisard_trial(tmp_path, "3-3", counters_lf=range(5, 60))   # other rows: not a copy
    _voisard_trial(tmp_path, "4-1", counters_lf=range(30))      # another subject: never compared
    found = voisard_truncated_copies(tmp_path)
    assert len(found) == 1 and "trial 3-2 is a truncated copy of trial 3-1" in found[0], found


def test_import_of_a_folder_names_the_bad_file_and_imports_the_repeated_one(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    _voisard_trial(src, "1-1")
    _voisard_trial(src, "1-2", counters_lf=list(range(30)) + [29] + list(range(30, 59)))
    _voisard_trial(src, "2-1")
    (src / "2-1_rf.txt").write_text("garbage\n")
    lines = []
    res = import_paths("voisard", [src], tmp_path / "inbox", on_file=lines.append)
    assert len(res.written) == 2
    assert len(res.errors) == 1 and "2-1" in res.errors[0] and "2-1_rf.txt" in res.errors[0]
    assert len(res.warnings) == 1 and "1-2_lf.txt" in res.warnings[0] and "repeats" in res.warnings[0]
    from stridelab.pipeline.formats.mcap_read import ReadResult, iter_blocks
    rr = ReadResult()
    # a study's imports are named by a token, not the export's file name (docs/privacy.md): the console line says
    # which written file came from trial 1-2
    out = [ln.split()[1] for ln in lines if ln.startswith("wrote ") and " from 1-2." in ln]
    assert len(out) == 1 and "1-2" not in Path(out[0]).name
    t = np.concatenate([b.t_ns for b in iter_blocks(Path(out[0]), rr)
                        if b.topic == "/imu/foot_left"])
    assert len(t) == 60 and np.all(np.diff(t) > 0)                          # every row, times increasing


def test_import_of_an_mt_manager_export(tmp_path):
    pre = ("// Start Time: Unknown", "// Update Rate: 60.0Hz", "// Filter Profile: human (46.1)",
           "// Option Flags: AHS Disabled ICC Disabled", "// Firmware Version: 4.0.2")
    p = _write(tmp_path / "walk_lf.txt", range(100, 130), preamble=pre, trailing_tab=True)
    res = import_paths("xsens", [p], tmp_path / "inbox")
    assert not res.errors and not res.warnings and len(res.written) == 1
    from stridelab.pipeline.formats.mcap_read import ReadResult, iter_blocks
    blocks = [b for b in iter_blocks(res.written[0], ReadResult()) if b.topic == "/imu/foot_left"]
    t = np.concatenate([b.t_ns for b in blocks])
    acc_x = np.concatenate([b.values[:, 3] for b in blocks])                # gyr then acc (m/s²)
    assert len(t) == 30 and np.allclose(np.diff(t), 1e9 / 60.0, atol=1)
    np.testing.assert_allclose(acc_x, np.arange(30))
