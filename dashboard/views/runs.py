"""Runs: the ledger of nightly runs and stage runs with durations and errors."""
import streamlit as st

from stridelab.dashboard import figures as F
from stridelab.warehouse import queries as Q
from stridelab.dashboard.common import footer, snapshot

st.title("Pipeline runs")
snap = snapshot()
if snap is not None:
    runs = snap.q(Q.pipeline_runs)
    if runs.empty:
        st.info(f"No run recorded yet: {Q.RUN_HINT}.")
    else:
        st.plotly_chart(F.run_durations(runs), key="run_durations")
        st.dataframe(runs, hide_index=True)

        st.subheader("Stage runs")
        durs = snap.q(Q.stage_durations)
        if durs.empty:
            st.caption("No stage has run yet (ingest-only runs so far).")
        else:
            st.dataframe(durs, hide_index=True)
            st.caption("CPU seconds (`mean_cpu_s`, `total_cpu_s`, a run's `cpu_s`): the CPU time of the process that "
                       "ran the task, over the task; wall seconds minus CPU seconds is mostly time spent waiting (the "
                       "disk, another process on a shared core).")
            c1, c2, c3 = st.columns(3)
            run_id = c1.selectbox("Run", ["all"] + runs["run_id"].tolist(), key="runs_run")
            status = c2.selectbox("Status", ["all", "ok", "skipped", "failed"], key="runs_status",
                                  help="skipped: the session does not hold what the stage needs (the note says what)")
            stages = c3.multiselect("Stage", durs["stage"].tolist(), key="runs_stage")
            sr = snap.q(Q.stage_runs, None if run_id == "all" else run_id, None if status == "all" else status,
                        tuple(stages))
            st.dataframe(sr, hide_index=True)
            failed = sr[sr["status"] == "failed"]
            if not failed.empty:
                st.subheader("Errors")
                for _, r in failed.head(50).iterrows():
                    st.error(f"{r['stage']} · {r['session_id']} · run {r['run_id']}: {r['error']}", icon=":material/error:")
    live = snap.q(Q.live_agreement)
    if not live.empty:
        st.subheader("Live sessions beside the nightly")
        st.caption("What `stridelab live` computed during a session against the nightly run on the same recording "
                   "and calibration. **online filter**: the same online estimators rerun over the whole recording "
                   "(causal, so equal up to rounding); **offline smoothed**: the nightly's own outputs (offline "
                   "orientation, its standing offset, the gait stage's events): the price of computing live. "
                   "docs/live.md")
        sid = st.selectbox("Live session", sorted(live["session_id"].unique()), key="live_session")
        one = live[live["session_id"] == sid]
        for quantity, title, key_name, widget in (
                ("joint_angle", "**Joint angles (deg)**", "joint", "live_angles"),
                ("event", "**Gait events (live − other, ms; matched within 0.5 s)**", "foot · event", "live_events")):
            rows = one[one["quantity"] == quantity]
            if rows.empty:
                continue
            t = rows.pivot_table(index="key", columns=["comparison", "metric"], values="value", aggfunc="first")
            t.columns = [f"{c} · {m}" for c, m in t.columns]
            st.markdown(title)
            st.dataframe(t.reset_index().rename(columns={"key": key_name}), hide_index=True, key=widget)
        with st.expander("Per stride and joint plane"):
            st.dataframe(snap.q(Q.live_agreement_strides, sid), hide_index=True, key="live_strides")
    skipped = snap.q(Q.skipped_topics)
    if not skipped.empty:
        st.subheader("Skipped topics")
        st.caption("Topics of a file that were not ingested, with the reason (`stridelab ingest --skip-topic`, a topic "
                   "without a placement, a schema StrideLab does not read); a topic that looks like IMU data is never "
                   "skipped without being asked to.")
        st.dataframe(skipped, hide_index=True)
    ledger = snap.q(Q.ingest_topics)
    if not ledger.empty:
        st.subheader("Ingest ledger: every topic of every file")
        st.caption("Each topic of each file a run read: ingested (placement, samples), skipped or refused with the "
                   "reason (docs/integrity.md).")
        st.dataframe(ledger, hide_index=True)
footer(snap)
