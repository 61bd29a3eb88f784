-- 001: catalog of participants, sessions, recordings, sensors, series and the run ledger.
CREATE TABLE participants (
    study VARCHAR NOT NULL,
    participant_id VARCHAR NOT NULL,
    PRIMARY KEY (study, participant_id)
);
CREATE TABLE sessions (
    session_id VARCHAR PRIMARY KEY,
    study VARCHAR NOT NULL,
    participant_id VARCHAR NOT NULL,
    kind VARCHAR NOT NULL,            -- lab | free_living | calibration
    protocol VARCHAR,
    timezone VARCHAR,
    start_ns BIGINT,
    end_ns BIGINT
);
CREATE TABLE recordings (
    content_hash VARCHAR PRIMARY KEY, -- sha256 of the file bytes: the identity of a recording
    file_name VARCHAR NOT NULL,
    source_path VARCHAR,
    size_bytes BIGINT,
    status VARCHAR NOT NULL,          -- ingested | quarantined
    reason VARCHAR,                   -- one line, for quarantined files
    session_id VARCHAR,
    trial VARCHAR,
    metadata JSON,
    start_ns BIGINT,
    end_ns BIGINT,
    n_samples BIGINT,
    ingested_at TIMESTAMP
);
CREATE TABLE sensors (
    content_hash VARCHAR NOT NULL,    -- recording
    topic VARCHAR NOT NULL,
    placement VARCHAR NOT NULL,
    kind VARCHAR NOT NULL,            -- imu | mag | range | reference_pose
    n_samples BIGINT NOT NULL,
    sampling_rate_hz DOUBLE,
    start_ns BIGINT,
    end_ns BIGINT,
    series_path VARCHAR NOT NULL,     -- relative to the warehouse root
    PRIMARY KEY (content_hash, topic)
);
CREATE TABLE recording_issues (
    content_hash VARCHAR NOT NULL,
    severity VARCHAR NOT NULL,        -- warning
    topic VARCHAR,
    message VARCHAR NOT NULL
);
CREATE TABLE reference_events (
    content_hash VARCHAR NOT NULL,
    session_id VARCHAR NOT NULL,
    t_ns BIGINT NOT NULL,
    end_ns BIGINT,
    type VARCHAR NOT NULL,
    side VARCHAR,
    placement VARCHAR,
    label VARCHAR,
    payload JSON
);
CREATE TABLE pipeline_runs (
    run_id VARCHAR PRIMARY KEY,
    command VARCHAR,
    started_at TIMESTAMP,
    finished_at TIMESTAMP,
    status VARCHAR,                   -- running | ok | failed | interrupted
    jobs INTEGER,
    n_ingested INTEGER,
    n_quarantined INTEGER,
    n_stage_runs INTEGER,
    n_failed INTEGER,
    version VARCHAR,
    host VARCHAR,
    pid INTEGER
);
CREATE TABLE stage_runs (
    run_id VARCHAR NOT NULL,
    session_id VARCHAR NOT NULL,
    stage VARCHAR NOT NULL,
    stage_version VARCHAR NOT NULL,
    params_hash VARCHAR,
    input_hash VARCHAR,
    stamp VARCHAR,
    status VARCHAR NOT NULL,          -- ok | failed
    started_at TIMESTAMP,
    duration_s DOUBLE,
    error VARCHAR,
    note VARCHAR
);
CREATE TABLE stage_state (            -- the stamp each stage last committed per session
    session_id VARCHAR NOT NULL,
    stage VARCHAR NOT NULL,
    stamp VARCHAR NOT NULL,
    PRIMARY KEY (session_id, stage)
);
CREATE TABLE inbox_seen (             -- cheap re-ingest check: same path, size and mtime => same content
    source_path VARCHAR NOT NULL,
    size_bytes BIGINT NOT NULL,
    mtime_ns BIGINT NOT NULL,
    content_hash VARCHAR NOT NULL,
    PRIMARY KEY (source_path, size_bytes, mtime_ns)
);
