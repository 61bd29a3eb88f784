"""The session calibration a live session starts with: computed from the session's calibration trial (quiet
standing + hip flexion/extension or straight walking, thesis ch. 3 / ch. 8 step 2), exactly as the nightly
calibration stage does, or taken from a previous visit stored in the warehouse."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from stridelab.pipeline.live.streams import read_streams


def calibration_from_trial(path: str | Path, topic_map: dict[str, str] | None = None):
    """:class:`SessionCalibration` of a calibration-trial recording (MCAP or bag): the sensors' shared
    stamps as one grid, orientation by the nightly's offline estimator for the pelvis heading, then
    ``calibrate_session`` with the stage's defaults (``stridelab.pipeline.stages.calibration``)."""
    from stridelab.estimators.calibration import CalibrationParams, calibrate_session
    from stridelab.estimators.calibration._session import DEFAULT_PLACEMENTS
    from stridelab.estimators.orientation import DEFAULT_OFFLINE, ESTIMATORS
    from stridelab.estimators.sync import common_grid
    st = read_streams(path, topic_map)
    sensors = {p: s for p, s in st.sensors.items() if p in DEFAULT_PLACEMENTS}
    if not sensors:
        raise ValueError(f"{path}: no pelvis/thigh/shank/foot IMU in the calibration trial")
    grid = common_grid({p: s.t_ns for p, s in sensors.items()})
    if len(grid) < 2:
        raise ValueError(f"{path}: the IMUs of the calibration trial share no time stamps; "
                         f"record them on one clock or give --calibration-from a warehouse")
    fs = st.sampling_rate_hz
    acc, gyr, quat = {}, {}, {}
    estimate = ESTIMATORS[DEFAULT_OFFLINE]
    for p, s in sensors.items():
        i = np.searchsorted(s.t_ns, grid)
        acc[p], gyr[p] = s.acc[i], s.gyr[i]
        quat[p] = estimate(s.gyr[i], s.acc[i], None if s.mag is None else s.mag[i], sampling_rate_hz=fs).quat
    return calibrate_session(acc, gyr, sampling_rate_hz=fs, params=CalibrationParams(), quats=quat,
                             placements=DEFAULT_PLACEMENTS)


def calibration_from_warehouse(root: str | Path, participant: str):
    """The newest stored calibration of ``participant`` that is not ``fail`` (a previous visit's), from the
    warehouse's published snapshot; ``ValueError`` saying what to do when there is none."""
    from stridelab.pipeline.stages._lab_read import session_calibration
    from stridelab.warehouse.read import connect_snapshot
    con = connect_snapshot(root)
    if con is None:
        raise ValueError(f"{root}: no published warehouse snapshot; run `stridelab run` first or give --calibration")
    try:
        sid = con.execute(
            "SELECT c.session_id FROM calibration c JOIN sessions s USING (session_id) "
            "WHERE s.participant_id = ? AND c.session_status <> 'fail' "
            "GROUP BY c.session_id, s.start_ns ORDER BY s.start_ns DESC LIMIT 1", [participant]).fetchone()
        if sid is None:
            raise ValueError(f"{root}: no usable calibration stored for participant {participant}; "
                             f"give the session's calibration trial with --calibration")
        cur = con.execute("SELECT * FROM calibration WHERE session_id = ?", [sid[0]])
        cols = [d[0] for d in cur.description]
        rows = [dict(zip(cols, r)) for r in cur.fetchall()]
    finally:
        con.close()
    return session_calibration(rows), sid[0]
