-- 009: the identity of a recording by content: sha256 over the decoded samples of every topic (pipeline/ingest.py
-- sample_hash). A file with the samples of an ingested recording is stored as status 'reexport' (not ingested
-- again); `--replace` marks the recordings a file supersedes 'superseded' (pipeline/supersede.py).
ALTER TABLE recordings ADD COLUMN sample_hash VARCHAR;
