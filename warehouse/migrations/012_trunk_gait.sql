-- 012: real-world gait from one trunk sensor (pipeline/stages/trunk_gait.py, estimators/trunk_gait,
-- docs/walking_at_home.md). walking_bouts: one row per walking bout found by the trunk-gait estimators on a
-- lower_back or chest IMU of a lab or free-living session; daily_gait_outcomes: one row per free-living session
-- and local calendar day (the participant's day within that session), the Mobilise-D digital mobility outcomes.
CREATE TABLE walking_bouts (
    session_id VARCHAR NOT NULL,
    content_hash VARCHAR,             -- the recording
    placement VARCHAR NOT NULL,       -- lower_back | chest
    start_ns BIGINT NOT NULL,         -- first initial contact of the bout (UTC ns)
    end_ns BIGINT NOT NULL,           -- last initial contact
    duration_s DOUBLE,
    n_steps INTEGER,
    n_strides INTEGER,
    cadence_spm DOUBLE,               -- steps per minute
    stride_length_m DOUBLE,           -- mean over the bout's strides
    walking_speed_m_s DOUBLE,
    n_turns INTEGER,                  -- turns of at least the estimator's minimum angle overlapping the bout
    flags VARCHAR,                    -- comma-separated quality flags ('' = none): default_height, wrong_placement, ...
    frame_confidence DOUBLE,          -- 0..1, the detected sensor-to-body frame's confidence
    height_source VARCHAR             -- given | default (1.70 m, documented)
);
CREATE TABLE daily_gait_outcomes (
    session_id VARCHAR NOT NULL,
    date VARCHAR NOT NULL,            -- local calendar day (session timezone), YYYY-MM-DD
    placement VARCHAR NOT NULL,
    recorded_s DOUBLE,                -- seconds of that day the recording covers
    walking_time_s DOUBLE,            -- total duration of all walking bouts
    n_bouts INTEGER,
    n_bouts_10_30s INTEGER,           -- bouts by duration class [lo, hi) s
    n_bouts_30_60s INTEGER,
    n_bouts_60_120s INTEGER,
    n_bouts_over_120s INTEGER,
    n_bouts_over_10s INTEGER,
    speed_median_m_s DOUBLE,          -- median / 95th centile over bouts longer than 10 s
    speed_p95_m_s DOUBLE,
    stride_length_median_m DOUBLE,
    stride_length_p95_m DOUBLE,
    cadence_median_spm DOUBLE,
    cadence_p95_spm DOUBLE,
    stride_velocity_p95_m_s DOUBLE,   -- 95th centile of stride speeds in bouts > 10 s (SV95C)
    height_source VARCHAR
);
