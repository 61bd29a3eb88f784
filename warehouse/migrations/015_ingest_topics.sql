-- 015: the ingest ledger per topic (issue #47, docs/integrity.md "Nothing dropped without a record").
-- One row per topic of every file a run read: ingested (with its placement and samples), skipped (with the
-- reason: --skip-topic, no placement, a schema StrideLab does not read, no messages) or, when the whole file was
-- refused or recognised as a re-export, that outcome with the file's reason. Topic names as the catalog may keep
-- them (pipeline.privacy.shown_topic); file_name is the keyed hash the recordings table keeps.
CREATE TABLE ingest_topics (
    run_id VARCHAR NOT NULL,
    content_hash VARCHAR NOT NULL,
    file_name VARCHAR,
    topic VARCHAR NOT NULL,
    outcome VARCHAR NOT NULL,        -- ingested | skipped | quarantined | reexport | duplicate
    placement VARCHAR,
    n_samples BIGINT,
    reason VARCHAR
);
