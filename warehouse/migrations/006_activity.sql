-- 006: daily activity from a chest accelerometer (free-living sessions).
CREATE TABLE activity_bouts (         -- runs of one class in the per-second timeline
    session_id VARCHAR NOT NULL,
    content_hash VARCHAR,
    start_ns BIGINT NOT NULL,
    end_ns BIGINT NOT NULL,
    class VARCHAR NOT NULL,           -- lying | sitting | standing | level_walking | stairs_up | stairs_down | non_wear
    steps INTEGER
);
CREATE TABLE activity_transitions (
    session_id VARCHAR NOT NULL,
    t_ns BIGINT NOT NULL,
    kind VARCHAR NOT NULL,            -- SiLy | LySi | StSi | SiSt
    dy_m DOUBLE
);
CREATE TABLE activity_daily (         -- one row per local calendar day and class
    session_id VARCHAR NOT NULL,
    date VARCHAR NOT NULL,
    day_length_s INTEGER,
    recorded_s INTEGER,
    wear_s INTEGER,
    class VARCHAR NOT NULL,
    seconds INTEGER,
    steps INTEGER,
    n_transitions INTEGER,
    n_bouts INTEGER,
    bout_s_median DOUBLE,
    bout_s_max DOUBLE
);
