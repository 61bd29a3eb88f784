"""A simulated lab session of the hemiparetic demo participant (P003): calibration trial + one 30-s walk."""
from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def lab_files(tmp_path_factory):
    from tests.pipeline._lab import write_lab_session
    d = tmp_path_factory.mktemp("live_lab")
    files, _truths = write_lab_session(d, distance_sensors=False, optical_reference=False, participant=2)
    cal = next(f for f in files if "calibration" in f.name)
    walk = next(f for f in files if "walk" in f.name)
    return cal, walk


@pytest.fixture(scope="session")
def lab_calibration(lab_files):
    from stridelab.pipeline.live.calibration import calibration_from_trial
    return calibration_from_trial(lab_files[0])


@pytest.fixture(scope="session")
def lab_streams(lab_files):
    from stridelab.pipeline.live.streams import read_streams
    return read_streams(lab_files[1])
