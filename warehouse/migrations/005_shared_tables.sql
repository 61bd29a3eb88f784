-- 005: tables several stages write (accuracy) carry the name of the stage that produced each row,
-- so that a stage's rerun replaces its own rows only (the runner fills and filters `producer`).
ALTER TABLE accuracy_metrics ADD COLUMN producer VARCHAR;
ALTER TABLE accuracy_pairs ADD COLUMN producer VARCHAR;
UPDATE accuracy_metrics SET producer = 'gait' WHERE producer IS NULL;
UPDATE accuracy_pairs SET producer = 'gait' WHERE producer IS NULL;
