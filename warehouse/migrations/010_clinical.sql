-- 010: clinical gait measures (pipeline/stages/clinical.py, estimators/gait/clinical.py, docs/clinical_measures.md).
-- clinical_steps: one row per stride of the gait stage's `strides` with its step and phase measures from the
-- contralateral events (so any session measure can be recomputed); clinical_measures: one row per session and
-- measure with both sides, paretic / non-paretic ratio, symmetry ratio (larger/smaller), variability and the
-- within-session uncertainty (SEM, MDC95 = 1.96 * sqrt(2) * SEM).
CREATE TABLE clinical_steps (
    session_id VARCHAR NOT NULL,
    content_hash VARCHAR,             -- the walking-trial recording
    trial VARCHAR,
    side VARCHAR,                     -- left | right: the foot whose stride (previous IC -> IC) this is
    paretic BOOLEAN,                  -- that foot is the paretic one (NULL: paretic side unknown)
    pre_ic_ns BIGINT,
    tc_ns BIGINT,
    ic_ns BIGINT,
    contra_ic_ns BIGINT,              -- the other foot's IC inside the stride (NULL if not exactly one)
    contra_tc_ns BIGINT,              -- the other foot's TC before that IC
    stride_time_s DOUBLE,
    stance_time_s DOUBLE,
    swing_time_s DOUBLE,
    step_time_s DOUBLE,               -- IC - contra IC: the step ending with this foot's contact
    step_length_m DOUBLE,             -- anterior distance of the two flat feet after this foot's contact
    step_length_ref_m DOUBLE,         -- the same from the optical reference (NULL without one)
    single_support_s DOUBLE,          -- contra IC - contra TC: this foot alone on the ground
    ds_initial_s DOUBLE,
    ds_terminal_s DOUBLE,
    double_support_pct DOUBLE,        -- (initial + terminal double support) / stride time
    stride_length_m DOUBLE,
    turning_deg DOUBLE,
    used BOOLEAN,                     -- counted in the session measures (straight walking, events complete)
    reason VARCHAR                    -- ok | turn | no_previous_ic | no_contralateral_ic | several_contralateral_ic | ...
);
CREATE TABLE clinical_measures (
    session_id VARCHAR NOT NULL,
    measure VARCHAR NOT NULL,         -- step_length_m, step_time_s, swing_time_s, ..., gait_speed_m_s, cadence_steps_min
    unit VARCHAR,
    value DOUBLE,                     -- session value (per-side measures: mean of the two side means)
    left_value DOUBLE,
    right_value DOUBLE,
    sd_left DOUBLE,
    sd_right DOUBLE,
    n_left INTEGER,
    n_right INTEGER,
    cv_left_pct DOUBLE,
    cv_right_pct DOUBLE,
    paretic_side VARCHAR,             -- left | right | NULL (unknown: no paretic ratios)
    paretic_value DOUBLE,
    non_paretic_value DOUBLE,
    paretic_ratio DOUBLE,             -- paretic / non-paretic
    symmetry_ratio DOUBLE,            -- larger / smaller side mean (Patterson et al. 2010), >= 1
    sem DOUBLE,                       -- of `value`, from the stride-to-stride variation
    mdc95 DOUBLE,                     -- 1.96 * sqrt(2) * sem
    sem_symmetry_ratio DOUBLE,
    mdc95_symmetry_ratio DOUBLE,
    flag VARCHAR,                     -- '' | few_strides | one_side | no_data
    note VARCHAR,
    PRIMARY KEY (session_id, measure)
);
