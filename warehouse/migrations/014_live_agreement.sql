-- 014: live sessions beside the nightly (issue #46, docs/live.md "Live beside offline").
-- live_outputs: what a `stridelab live` recording computed live, stored by the ingest (pipeline/live/stored.py):
--   kind 'angles' (one Parquet row per frame; meta = the calibration and standing offsets the live angles used)
--   or 'events' (one row per gait event).
CREATE TABLE live_outputs (
    content_hash VARCHAR NOT NULL,   -- the recording
    session_id VARCHAR,
    kind VARCHAR NOT NULL,           -- angles | events
    n_rows BIGINT,
    series_path VARCHAR NOT NULL,
    meta JSON
);
-- live_agreement: one figure per recording, comparison and key. comparison 'online_filter' = the same online
--   estimators run by the nightly over the whole recording (causal: equal up to rounding); 'offline_smoothed' =
--   the nightly's own outputs (offline orientation, its standing offset; the gait stage's events).
CREATE TABLE live_agreement (
    session_id VARCHAR NOT NULL,
    content_hash VARCHAR NOT NULL,
    comparison VARCHAR NOT NULL,     -- online_filter | offline_smoothed
    quantity VARCHAR NOT NULL,       -- joint_angle | event
    key VARCHAR NOT NULL,            -- hip_left ... | left_IC ...
    metric VARCHAR NOT NULL,         -- max_abs_diff_deg, rmse_deg_sagittal, matched, mean_diff_ms, max_abs_diff_ms ...
    value DOUBLE,
    unit VARCHAR
);
-- per stride (live initial contact to the next, per side) and joint: live minus each offline computation
CREATE TABLE live_agreement_strides (
    session_id VARCHAR NOT NULL,
    content_hash VARCHAR NOT NULL,
    side VARCHAR,
    joint VARCHAR,                   -- hip | knee | ankle
    plane VARCHAR,                   -- sagittal | frontal | transverse
    start_ns BIGINT,
    end_ns BIGINT,
    n_frames INTEGER,
    max_abs_diff_online_deg DOUBLE,
    max_abs_diff_offline_deg DOUBLE,
    rmse_offline_deg DOUBLE
);
-- per live gait event: its time, the matching event of each offline computation (NULL: none within 0.5 s)
CREATE TABLE live_agreement_events (
    session_id VARCHAR NOT NULL,
    content_hash VARCHAR NOT NULL,
    side VARCHAR,
    type VARCHAR,                    -- IC | TC
    live_ns BIGINT,
    online_ns BIGINT,
    offline_ns BIGINT,
    online_diff_ms DOUBLE,           -- live - offline online filter
    offline_diff_ms DOUBLE           -- live - nightly gait stage
);
