"""Speed-matched normative bands (Schwartz et al. 2008, reports/normative.py) and the live walking-speed estimate."""
from __future__ import annotations

import numpy as np
import pytest

from stridelab.reports._schwartz2008 import CATEGORIES, DATA, RANGES
from stridelab.reports.normative import dimensionless_speed, speed_category_centres, speed_matched_band

G = 9.80665


def _speed_at(v_hat, leg=0.9):
    return v_hat * np.sqrt(G * leg)


def test_the_band_at_a_category_centre_is_that_category_and_between_two_it_is_their_mix():
    centres = speed_category_centres()
    assert centres["slow"] == pytest.approx((RANGES["slow"][0] + RANGES["slow"][1]) / 2)
    for cat in CATEGORIES:
        _p, mean, sd, info = speed_matched_band("knee", _speed_at(centres[cat]), 0.9, n=51)
        np.testing.assert_allclose(mean, DATA["knee"][cat][0], atol=1e-9)
        np.testing.assert_allclose(sd, DATA["knee"][cat][1], atol=1e-9)
    mid = (centres["slow"] + centres["free"]) / 2
    _p, mean, _sd, info = speed_matched_band("hip", _speed_at(mid), 0.9, n=51)
    np.testing.assert_allclose(mean, (np.asarray(DATA["hip"]["slow"][0]) + DATA["hip"]["free"][0]) / 2, atol=1e-9)
    assert (info["lower"], info["upper"], info["weight_upper"], info["clamped"]) == ("slow", "free", 0.5, False)
    # beyond the outer centres: held at the nearest category, and said so
    _p, mean, _sd, info = speed_matched_band("knee", 0.2, 0.9, n=51)
    np.testing.assert_allclose(mean, DATA["knee"]["very_slow"][0], atol=1e-9)
    assert info["clamped"]
    assert speed_matched_band("pelvis", 1.0) is None
    assert dimensionless_speed(1.0, 1.0) == pytest.approx(1 / np.sqrt(G))


def test_the_transcribed_data_behave_as_the_paper_reports():
    """Schwartz et al. 2008: faster walking, more knee flexion in swing and a larger hip range of motion; the supplement's
    free-speed knee flexion at initial contact is 5.55 deg (mean) and the cycle is sampled every 2 %."""
    knee_peak = [max(DATA["knee"][c][0]) for c in CATEGORIES]
    hip_rom = [max(DATA["hip"][c][0]) - min(DATA["hip"][c][0]) for c in CATEGORIES]
    assert all(np.diff(knee_peak) > 0) and all(np.diff(hip_rom) > 0), (knee_peak, hip_rom)
    assert DATA["knee"]["free"][0][0] == pytest.approx(5.55, abs=0.01)
    assert all(len(DATA[j][c][k]) == 51 for j in DATA for c in CATEGORIES for k in (0, 1))
    assert all(min(DATA[j][c][1]) > 0 for j in DATA for c in CATEGORIES)


@pytest.mark.slow
def test_live_walking_speed_is_the_gait_stage_speed_of_the_last_strides(lab_streams, lab_calibration):
    """The live estimate (foot kinematics of the gait stage on the last 6 s at each stride, in a worker process)
    against the same estimator over the whole walk: the median stride speeds agree within 10 %."""
    from stridelab.estimators.gait import PARAM_COLUMNS, foot_kinematics
    from stridelab.pipeline.live.engine import LEG_PLACEMENTS
    from stridelab.pipeline.live.session import LiveSession
    from stridelab.pipeline.live.sources import ReplaySource
    pl = [p for p in LEG_PLACEMENTS if p in lab_streams.sensors]
    fs = lab_streams.sampling_rate_hz
    session = LiveSession(ReplaySource(lab_streams, pl, speed=None), pl, sampling_rate_hz=fs,
                          calibration=lab_calibration, speed_estimate=True)
    summary = session.run()
    # the worker's last answers may still be in flight when the replay ends; the ones in are what the page showed
    live = summary["walking_speed"]
    assert live["n_strides"] >= 5, live
    col = list(PARAM_COLUMNS).index("gait_speed_m_s")
    whole = []
    for side in ("left", "right"):
        s = lab_streams.sensors[f"foot_{side}"]
        v = foot_kinematics(s.gyr, s.acc, sampling_rate_hz=fs).strides.values[:, col]
        whole += list(v[np.isfinite(v)])
    ref = float(np.median(whole))
    assert abs(live["speed_m_s"] - ref) <= 0.10 * ref, (live, ref)
