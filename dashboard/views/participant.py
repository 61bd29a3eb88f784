"""Participant: sessions on a timeline, gait parameters across sessions, joint-angle cycles against a
normative band, foot trajectories, calibration QC, data quality."""
import streamlit as st

from stridelab.dashboard import figures as F
from stridelab.warehouse import queries as Q
from stridelab.dashboard.common import empty_warehouse_note, footer, hint, participant_picker, snapshot, warehouse_root

st.title("Participant")
snap = snapshot()
if snap is not None and not empty_warehouse_note(snap):
    study, pid = participant_picker(snap)
    if pid is None:
        st.info(f"No participants yet: {Q.RUN_HINT}.")
    else:
        st.header(f"{pid}  ·  {study}")
        ses = snap.q(Q.sessions, pid, study)
        c1, c2, c3 = st.columns(3)
        c1.metric("Sessions", len(ses))
        c2.metric("Lab sessions", int((ses["kind"] == "lab").sum()))
        c3.metric("Free-living hours", f"{ses.loc[ses['kind'] == 'free_living', 'hours'].sum():.1f}")
        if not ses.empty:
            st.plotly_chart(F.sessions_timeline(ses), key="sessions_timeline")
        st.dataframe(ses.drop(columns=["study", "participant_id"]), hide_index=True)

        tab_gait, tab_joint, tab_foot, tab_cal, tab_data = st.tabs(
            ["Gait parameters", "Joint angles", "Foot trajectory", "Calibration QC", "Recordings & quality"])
        with tab_gait:
            strides = snap.q(Q.strides, pid, study)
            if strides is None:
                hint("strides")
            elif strides.empty:
                st.caption("No strides detected in this participant's sessions.")
            else:
                summ = snap.q(Q.gait_summary, pid, study)
                if summ is None or summ.empty:
                    st.caption("No gait summary for this participant's sessions yet (the gait stage writes it).")
                else:
                    avail = [p for p in ("speed_m_s", "cadence_steps_min", "stride_length_m", "stance_pct")
                             if p in summ]
                    st.plotly_chart(F.gait_trend(summ, avail), key="gait_trend")
                    show = ["session_id", "protocol", "strides"] + [c for c in Q.GAIT_PARAMS if c in summ]
                    st.dataframe(summ[show], hide_index=True,
                                 column_config={c: st.column_config.NumberColumn(format="%.3f") for c in show[3:]})
                    st.caption("The gait stage's own summary per session (both feet). Left/right asymmetry (step "
                               "time, swing, stance, single support, step length: paretic ratio and symmetry ratio) "
                               "and its change between visits: the Programme page.")
        with tab_joint:
            jc = snap.q(Q.joint_cycles, pid, study)
            if jc is None:
                hint("joint_cycles")
            elif jc.empty:
                st.caption("No joint-angle cycles for this participant.")
            else:
                joints = sorted(jc["joint"].unique())
                planes = sorted(jc["plane"].dropna().unique()) if "plane" in jc else [None]
                c1, c2 = st.columns(2)
                joint = c1.selectbox("Joint", joints, key="joint")
                plane = c2.selectbox("Plane", planes, key="plane") if planes != [None] else None
                sel = jc[(jc["joint"] == joint) & ((jc["plane"] == plane) if plane is not None else True)]
                st.plotly_chart(F.joint_cycles(sel, joint, plane), key="joint_cycles")
                st.caption("Grey band: approximate adult normative mean ± SD (sagittal plane only; see "
                           "reports/normative.py). Curves: mean ± SD over the session's gait cycles.")
        with tab_foot:
            traj = snap.q(Q.foot_trajectories, str(warehouse_root()), pid, study)
            if traj is None:
                hint("foot_trajectory")
            elif traj.empty:
                st.caption("No foot trajectory for this participant.")
            else:
                st.plotly_chart(F.foot_trajectory(traj), key="foot_trajectory")
        with tab_cal:
            cal = snap.q(Q.calibration_qc, pid, study)
            if cal is None:
                hint("calibration")
            else:
                st.dataframe(cal, hide_index=True)
            ori = snap.q(Q.orientation_coverage, pid, study)
            st.subheader("Orientation")
            if ori.empty:
                st.caption(f"No orientation computed yet for this participant: {Q.RUN_HINT}.")
            else:
                st.dataframe(ori, hide_index=True)
        with tab_data:
            st.dataframe(snap.q(Q.recordings, pid, study), hide_index=True)
            iss = snap.q(Q.participant_issues, pid, study)
            if iss.empty:
                st.caption("No quality flags for this participant.")
            else:
                st.dataframe(iss, hide_index=True)
footer(snap)
