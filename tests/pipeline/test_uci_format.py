"""The UCI chest reader (stridelab.pipeline.formats.uci_chest) on files written here: any participant file in the
format works, anything else is refused with one line naming the file."""
from __future__ import annotations

import numpy as np
import pytest

from stridelab.pipeline.formats.uci_chest import G, load_uci_chest, load_uci_participant

FS = 52.0


def _write(path, counts, labels):
    seq = np.arange(counts.shape[0])
    np.savetxt(path, np.column_stack([seq, counts, labels]), delimiter=",", fmt="%d")


def _counts(n_s=120, cpg=400.0, seed=0):
    """Still, then walking at 1.8 Hz, sensor y up, 12-bit counts around mid-scale 2048."""
    rng = np.random.default_rng(seed)
    n = int(n_s * FS)
    t = np.arange(n) / FS
    g = np.tile([0.0, 1.0, 0.0], (n, 1))
    g[n // 2:, 1] += 0.3 * np.sin(2 * np.pi * 1.8 * t[n // 2:])
    return np.round(2048 + cpg * g + rng.normal(0, 2, g.shape)), np.where(np.arange(n) < n // 2, 3, 4)


def test_any_participant_number_is_read_and_scaled_to_m_s2(tmp_path):
    c, lab = _counts()
    _write(tmp_path / "12.csv", c, lab)
    _write(tmp_path / "3.csv", c, lab)
    parts = load_uci_chest(tmp_path)
    assert [u.participant for u in parts] == ["3", "12"]            # numeric order, not "12" < "3"
    u = parts[1]
    assert u.acc.shape == (c.shape[0], 3) and u.labels.dtype.kind == "i"
    assert u.counts_per_g == pytest.approx(400.0, rel=0.01)
    still = np.linalg.norm(u.acc[: int(50 * FS)], axis=1)
    assert np.median(still) == pytest.approx(G, rel=0.01)           # still samples read 1 g in m/s²


@pytest.mark.parametrize("text, what", [
    ("1,2000,2000,2000\n2,2000,2000,2000\n", "5 columns"),
    ("1,2000,2000,2000,1\n2,9000,2000,2000,1\n", "ADC range"),
    ("1,2000,nan,2000,1\n2,2000,2000,2000,1\n", "non-finite"),
    ("seq;x;y;z;label\n1;2;3;4;5\n", "not a UCI chest CSV"),
])
def test_bad_files_are_refused_with_one_line_naming_the_file(tmp_path, text, what):
    f = tmp_path / "7.csv"
    f.write_text(text)
    with pytest.raises(ValueError) as e:
        load_uci_participant(f)
    msg = str(e.value)
    assert what in msg and "7.csv" in msg and "\n" not in msg


def test_an_empty_folder_is_refused(tmp_path):
    with pytest.raises(ValueError, match="no UCI chest CSV"):
        load_uci_chest(tmp_path)


def _protocol(seed):
    """A short UCI-like participant: sitting (label 1, leaning 25°), standing (3), walking (4), stairs (5, slower
    steps, more lean), standing (7); 12-bit counts."""
    rng = np.random.default_rng(seed)
    parts = []
    for lab, n_s, lean, f in ((1, 120, 25.0, 0), (3, 60, 3.0, 0), (4, 120, 3.0, 1.9), (5, 60, 12.0, 1.5), (7, 60, 3.0, 0)):
        n = int(n_s * FS)
        t = np.arange(n) / FS
        th = np.deg2rad(lean)
        a = np.tile([-np.sin(th), np.cos(th), 0.0], (n, 1))
        if f:
            a[:, 1] += 0.3 * np.sin(2 * np.pi * f * t)
            a[:, 0] += 0.12 * np.sin(2 * np.pi * f * t + 0.8)
            a[:, 2] += 0.06 * np.sin(np.pi * f * t)
        parts.append((a, np.full(n, lab)))
    g = np.vstack([p[0] for p in parts])
    return np.round(2048 + 400 * g + rng.normal(0, 2, g.shape)), np.concatenate([p[1] for p in parts])


@pytest.mark.slow
def test_bench_activity_runs_on_any_participant_files(tmp_path):
    import json

    from click.testing import CliRunner

    from stridelab.validation.bench.activity import command
    for k, name in enumerate(("21", "22")):
        _write(tmp_path / f"{name}.csv", *_protocol(k))
    res = CliRunner().invoke(command, ["--uci-chest", str(tmp_path), "--no-speed", "--simulated", "0", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    # no participant of the shipped model's training set here: the default runs the shipped model on both and
    # the tuned forest (fitted on training participants only) is left out
    assert set(out["methods"]) == {"thesis", "rules", "default", "learned_loso"} and out["default"] == "default"
    assert all(v["scored_by"].startswith("shipped model") for v in out["methods"]["default"]["per_participant"].values())
    for m in out["methods"].values():
        assert set(m["per_participant"]) == {"21", "22"} and np.array(m["confusion"]).shape == (4, 4)
    assert out["methods"]["default"]["windows"] == 2 * (12 + 6 + 12 + 6 + 6)
    lc = out["label_consistency"]
    assert lc["windows"] == [24, 24, 24, 12] and lc["contradicted"] == [0, 0, 0, 0]
    assert lc["ceiling_balanced_accuracy"] == 1.0


def test_bench_activity_names_a_bad_file(tmp_path):
    from click.testing import CliRunner

    from stridelab.validation.bench.activity import command
    (tmp_path / "5.csv").write_text("not,a,uci,file\n")
    res = CliRunner().invoke(command, ["--uci-chest", str(tmp_path), "--no-speed", "--simulated", "0"])
    assert res.exit_code != 0 and "5.csv" in res.output
