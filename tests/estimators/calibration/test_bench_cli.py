"""``stridelab bench calibration --json`` runs and prints the figures (small, fast configuration)."""
import json

import pytest
from click.testing import CliRunner

from stridelab.cli import main


@pytest.mark.slow
def test_bench_calibration_json():
    r = CliRunner().invoke(main, ["bench", "calibration", "-n", "1", "--reps", "10", "--minutes", "0.5",
                                  "--scene", "synthetic", "--json"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert set(d["calibration_error_deg"]) == {"hip_fe", "walking"}
    assert {"thigh", "shank", "foot", "pelvis"} <= set(d["calibration_error_deg"]["walking"])
    assert d["error_vs_repetitions"]["k"] == list(range(1, 11))
    assert 0.0 < d["speed"]["seconds"] < float("inf") and d["speed"]["imus"] == 7   # speed is the bench's figure, not a test
