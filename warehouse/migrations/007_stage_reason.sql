-- 007: the ledger says why each stage ran on a session: what consumes its output there (a later stage,
-- the study's request, the session kind's pages and reports) and what changed since its last run.
ALTER TABLE stage_runs ADD COLUMN reason VARCHAR;
