-- 011: the ledger records the CPU seconds of each stage run beside its wall seconds: the CPU time of the process
-- that ran the task (all its threads) from the task's start to its end. duration_s - cpu_s is roughly what the
-- task waited for (the disk, the other worker's use of a shared core); NULL for failed runs and older rows.
ALTER TABLE stage_runs ADD COLUMN cpu_s DOUBLE;
