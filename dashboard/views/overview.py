"""Overview: studies, participants, sessions, last nightly run, quarantined files, QC flags."""
import streamlit as st

from stridelab.warehouse import queries as Q
from stridelab.dashboard.common import current_study, empty_warehouse_note, footer, snapshot

st.title("StrideLab overview")
snap = snapshot()
if snap is not None:
    c = snap.q(Q.counts)
    cols = st.columns(6)
    for col, (label, key) in zip(cols, (("Studies", "studies"), ("Participants", "participants"),
                                        ("Sessions", "sessions"), ("Recordings", "recordings"),
                                        ("Quarantined", "quarantined"), ("Recording issues", "issues"))):
        col.metric(label, c[key])

    run = snap.q(Q.last_run)
    st.subheader("Last nightly run")
    if run is None:
        st.info(f"No pipeline run recorded yet: {Q.RUN_HINT}.")
    else:
        dur = f"{run['duration_s']:.1f} s" if run["duration_s"] is not None else "still running"
        msg = (f"`{run['run_id']}` ({run['command']}) **{run['status']}** · started {run['started_at']:%Y-%m-%d %H:%M} UTC · "
               f"{dur} · {run['n_ingested'] or 0} ingested · {run['n_quarantined'] or 0} quarantined · "
               f"{run['n_stage_runs'] or 0} stage runs · {run['n_failed'] or 0} failed")
        (st.success if run["status"] == "ok" else st.warning)(msg)

    if not empty_warehouse_note(snap):
        st.subheader("Studies")
        st.dataframe(snap.q(Q.studies), hide_index=True)
        st.subheader("Participants" + (f" of {current_study()}" if current_study() else ""))
        parts = snap.q(Q.participants, current_study())
        st.dataframe(parts, hide_index=True, column_config={"participant_id": "participant (pseudonym)"})
        st.subheader("Pipeline stages")
        cov = snap.q(Q.stage_coverage)
        avail = snap.q(Q.available)
        if cov.empty:
            st.caption(f"No stage has run yet: {Q.RUN_HINT}.")
        else:
            st.dataframe(cov, hide_index=True)
        missing = [k for k, v in avail.items() if not v]
        if missing:
            with st.expander(f"{len(missing)} result types not computed yet"):
                for k in missing:
                    st.caption("• " + Q.missing_hint(k))

    st.subheader("Quarantined files")
    q = snap.q(Q.quarantined)
    if q.empty:
        st.caption("None: every file that arrived was ingested.")
    else:
        st.dataframe(q, hide_index=True)

    st.subheader("Quality flags")
    flags = snap.q(Q.qc_flags)
    if flags.empty:
        st.caption("No quality flags.")
    else:
        st.dataframe(flags, hide_index=True)
footer(snap)
