-- 003: sensor-to-segment calibration (one row per session and IMU) and clinical joint angles
-- (one row per walking-trial recording and joint; samples in Parquet), gait-cycle curves and ROM.
CREATE TABLE calibration (
    session_id VARCHAR NOT NULL,
    placement VARCHAR NOT NULL,
    content_hash VARCHAR,             -- the calibration trial recording (NULL when it is missing)
    status VARCHAR NOT NULL,          -- pass | warn | fail
    reasons JSON,                     -- list of one-line reasons (empty when pass)
    method VARCHAR,                   -- hip_fe | walking | pelvis_thighs | pelvis_sway | none
    quality JSON,                     -- planarity, gamma_deg, standing_s, gravity_m_s2, gravity_spread_deg,
                                      -- axis_tilt_deg, x_vertical_deg
    n_reps INTEGER,                   -- hip FE repetitions or straight-walking swings used
    qw DOUBLE,                        -- quat_sensor_af [w x y z]: q_segment = q_sensor ⊗ q_sensor_af
    qx DOUBLE,                        -- (NULL when no rotation could be computed)
    qy DOUBLE,
    qz DOUBLE,
    session_status VARCHAR,           -- worst status of the session's calibration
    session_reasons JSON,
    windows JSON,                     -- windows used, in seconds from the trial start, and their source
    params JSON,                      -- CalibrationParams that produced it
    stage_version VARCHAR,
    PRIMARY KEY (session_id, placement)
);
CREATE TABLE joint_angles (
    session_id VARCHAR NOT NULL,
    content_hash VARCHAR NOT NULL,    -- the walking-trial recording
    trial VARCHAR,
    joint VARCHAR NOT NULL,           -- hip | knee | ankle
    side VARCHAR NOT NULL,            -- left | right
    status VARCHAR NOT NULL,          -- pass | warn | fail: worse calibration of the two segments
    reasons JSON,
    angle_names JSON,                 -- clinical names of the sagittal, frontal, transverse columns
    offset_sagittal_deg DOUBLE,       -- quiet-standing offsets removed (NULL when not removed)
    offset_frontal_deg DOUBLE,
    offset_transverse_deg DOUBLE,
    standing_start_ns BIGINT,         -- the quiet standing used for the offsets
    standing_end_ns BIGINT,
    n_samples BIGINT,
    series_path VARCHAR,              -- Parquet: t_ns, sagittal_deg, frontal_deg, transverse_deg
    PRIMARY KEY (content_hash, joint, side)
);
CREATE TABLE joint_angle_curves (
    session_id VARCHAR NOT NULL,
    joint VARCHAR NOT NULL,
    side VARCHAR NOT NULL,
    plane VARCHAR NOT NULL,           -- sagittal | frontal | transverse
    angle VARCHAR,                    -- flexion, dorsiflexion, adduction, ...
    pct INTEGER NOT NULL,             -- 0..100 % of the gait cycle (initial contact to initial contact)
    mean_deg DOUBLE,
    sd_deg DOUBLE,
    n_cycles INTEGER,
    status VARCHAR,
    PRIMARY KEY (session_id, joint, side, plane, pct)
);
CREATE TABLE joint_rom (
    session_id VARCHAR NOT NULL,
    joint VARCHAR NOT NULL,
    side VARCHAR NOT NULL,
    plane VARCHAR NOT NULL,
    angle VARCHAR,
    rom_deg DOUBLE,                   -- mean over cycles of (max - min) within a cycle
    rom_sd_deg DOUBLE,
    n_cycles INTEGER,
    status VARCHAR,
    PRIMARY KEY (session_id, joint, side, plane)
);
