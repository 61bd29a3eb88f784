-- 013: integrity of what is ingested (issue #47, docs/integrity.md).
-- crc_verified: every message of the file was covered by a CRC that was checked; false for an MCAP written
--   without CRCs (allowed by the format; shown "unverified"), NULL for recordings ingested before.
-- settings_hash / ingest_settings: the ingest settings (topic map, session fields given on the command line,
--   clock policy) the recording was ingested with; with the content hash they form the idempotency key.
-- skipped_topics: topics of the file that were not ingested, each with the reason ([{"topic", "reason"}]).
ALTER TABLE recordings ADD COLUMN crc_verified BOOLEAN;
ALTER TABLE recordings ADD COLUMN settings_hash VARCHAR;
ALTER TABLE recordings ADD COLUMN ingest_settings JSON;
ALTER TABLE recordings ADD COLUMN skipped_topics JSON;
-- an ingest of a file superseded by a re-ingest of the same file (other settings, or --replace): the rows of
-- the recording as they were (the recordings row itself is the newest ingest)
CREATE TABLE superseded_ingests (
    content_hash VARCHAR NOT NULL,
    settings_hash VARCHAR,
    ingest_settings JSON,
    file_name VARCHAR,
    session_id VARCHAR,
    n_samples BIGINT,
    sensors JSON,                    -- [{topic, placement, kind, n_samples}] of the superseded ingest
    ingested_at TIMESTAMP,
    superseded_at TIMESTAMP,
    reason VARCHAR
);
