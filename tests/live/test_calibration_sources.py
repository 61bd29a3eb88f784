"""A live session's calibration: from the session's calibration trial, or a previous visit's stored one."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest


@pytest.mark.slow
def test_stored_calibration_of_a_previous_visit_is_the_one_the_nightly_computed(tmp_path, lab_files,
                                                                                lab_calibration):
    from stridelab.pipeline.live.calibration import calibration_from_warehouse
    from stridelab.pipeline.stages import calibration as cal_stage
    from tests.pipeline._lab import run_with
    mp = pytest.MonkeyPatch()
    root = tmp_path / "wh"
    try:
        run_with(mp, root, list(lab_files), [replace(cal_stage.STAGE, needs=())])
    finally:
        mp.undo()
    stored, sid = calibration_from_warehouse(root, "P003")
    assert sid.startswith("P003") and stored.status != "fail"
    # leg IMUs do not depend on the orientation the pelvis heading may use: equal to the trial's
    for p in ("thigh_left", "thigh_right", "shank_left", "shank_right", "foot_left", "foot_right"):
        np.testing.assert_allclose(stored.imus[p].R_sensor_af, lab_calibration.imus[p].R_sensor_af, atol=1e-9)
    with pytest.raises(ValueError, match="no usable calibration stored for participant P999"):
        calibration_from_warehouse(root, "P999")
    with pytest.raises(ValueError, match="no published warehouse snapshot"):
        calibration_from_warehouse(tmp_path / "empty", "P003")
