-- 008: participant reports as a tracked output. One row per report (participant x output folder) with the
-- hash of the inputs it was built from; a run rewrites every report whose row is missing, whose inputs
-- changed or whose files are gone (pipeline/reports.py).
CREATE TABLE reports (
    study VARCHAR NOT NULL,
    participant_id VARCHAR NOT NULL,
    out_dir VARCHAR NOT NULL,         -- absolute folder the files were written to
    inputs_hash VARCHAR NOT NULL,     -- stage stamps + recordings of the participant + report format
    html_path VARCHAR NOT NULL,
    pdf_path VARCHAR NOT NULL,
    run_id VARCHAR,
    written_at TIMESTAMP,
    PRIMARY KEY (study, participant_id, out_dir)
);
