-- 004: gait stage output: contacts, strides, foot trajectories (samples in Parquet), per-session summary,
-- and accuracy against reference annotations. Rows are replaced per session by the stage (see
-- pipeline/stages/gait.py). Only session_id is NOT NULL so that other writers (the dashboard benchmark's
-- synthetic results) can fill the columns they know.
CREATE TABLE gait_events (
    session_id VARCHAR NOT NULL,
    content_hash VARCHAR,             -- the walking-trial recording
    trial VARCHAR,
    placement VARCHAR,                -- foot_left | foot_right
    side VARCHAR,                     -- left | right
    type VARCHAR,                     -- IC (initial contact) | TC (terminal contact)
    t_ns BIGINT                       -- the IMU sample of the event (pitch extremum, thesis ch. 6)
);
CREATE TABLE strides (
    session_id VARCHAR NOT NULL,
    content_hash VARCHAR,
    trial VARCHAR,
    placement VARCHAR,
    side VARCHAR,
    start_ns BIGINT,                  -- stride borders: mid-stance to mid-stance
    end_ns BIGINT,
    pre_ic_ns BIGINT,                 -- the previous initial contact (stride time = ic - pre_ic; NULL if none)
    tc_ns BIGINT,                     -- terminal contact (toe-off) inside the stride
    ic_ns BIGINT,                     -- initial contact (heel strike) inside the stride
    stride_time_s DOUBLE,
    stance_time_s DOUBLE,
    swing_time_s DOUBLE,
    stance_pct DOUBLE,
    swing_pct DOUBLE,
    stride_length_m DOUBLE,           -- horizontal displacement of the sensor between the borders
    speed_m_s DOUBLE,
    clearance_m DOUBLE,               -- max height of the sensor point in swing above its stance height
    turning_deg DOUBLE,               -- + = to the left
    stride_length_ref_m DOUBLE,       -- same from the optical reference of the foot (NULL without one)
    status VARCHAR
);
CREATE TABLE gait_summary (
    session_id VARCHAR NOT NULL,
    side VARCHAR NOT NULL,            -- left | right | both
    cadence_steps_min DOUBLE,
    speed_m_s DOUBLE,
    stride_length_m DOUBLE,
    stride_time_s DOUBLE,
    stance_pct DOUBLE,
    swing_pct DOUBLE,
    double_support_pct DOUBLE,
    clearance_m DOUBLE,
    si_stride_length_pct DOUBLE,      -- symmetry index 200|L-R|/(L+R) %, on the 'both' row only
    si_stride_time_pct DOUBLE,
    si_stance_pct DOUBLE,
    si_swing_time_pct DOUBLE,
    si_clearance_pct DOUBLE,
    n_strides INTEGER,
    status VARCHAR,                   -- ok | partial | no_strides | no_stance | too_short | missing_sensor | no_walking_trial
    note VARCHAR,
    PRIMARY KEY (session_id, side)
);
CREATE TABLE foot_trajectories (
    session_id VARCHAR NOT NULL,
    content_hash VARCHAR,
    trial VARCHAR,
    placement VARCHAR,
    side VARCHAR,
    estimator VARCHAR,
    n_samples BIGINT,
    sampling_rate_hz DOUBLE,
    status VARCHAR,                   -- ok | no_stance
    range_estimator VARCHAR,          -- duong_suh_21 | duong_suh_9 when the shoe distance sensors were used
    range_status VARCHAR,             -- ok | no_valid_range (out of range / saturated / not downward) | no_stance
    range_geometry VARCHAR,           -- configured (study manifest) | guessed (beams along gravity, lever arms 0)
    range_used_fraction DOUBLE,       -- share of the samples carrying a reading whose reading was used (first segment)
    series_path VARCHAR               -- Parquet: t_ns, px, py, pz (m), vx, vy, vz (m/s), stance (bool)
                                      -- [+ pz_floor (m, Duong & Suh height above the floor), range_used_a/_b]
);
CREATE TABLE IF NOT EXISTS accuracy_metrics (
    session_id VARCHAR,
    stage VARCHAR,                    -- gait_events | strides | ...
    estimator VARCHAR,
    placement VARCHAR,                -- foot_left | foot_right | both
    metric VARCHAR,                   -- ic_sensitivity, ic_timing_mae_ms, ...
    value DOUBLE,
    unit VARCHAR
);
CREATE TABLE IF NOT EXISTS accuracy_pairs (
    session_id VARCHAR,
    stage VARCHAR,
    estimator VARCHAR,
    placement VARCHAR,
    quantity VARCHAR,                 -- IC | TC (times in s, unit 's')
    estimate DOUBLE,
    reference DOUBLE,
    unit VARCHAR
);
