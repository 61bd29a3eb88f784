-- 002: orientation stage output (one row per recording and IMU; samples in Parquet).
CREATE TABLE orientation (
    session_id VARCHAR NOT NULL,
    content_hash VARCHAR NOT NULL,
    placement VARCHAR NOT NULL,
    estimator VARCHAR NOT NULL,
    estimator_version VARCHAR NOT NULL,
    params JSON,
    n_samples BIGINT,
    sampling_rate_hz DOUBLE,
    mag_used BOOLEAN,
    series_path VARCHAR NOT NULL,
    PRIMARY KEY (content_hash, placement)
);
