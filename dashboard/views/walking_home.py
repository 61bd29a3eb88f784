"""Walking at home: the trunk-gait stage's walking bouts and daily gait outcomes of a participant (per day, per
bout-duration class), and lab capacity beside home performance for the same participant and period
(docs/walking_at_home.md)."""
import pandas as pd
import plotly.graph_objects as go
import streamlit as st

from stridelab.dashboard.common import current_study, empty_warehouse_note, footer, snapshot
from stridelab.warehouse import queries as Q

st.title("Walking at home")
snap = snapshot()


def _days_figure(d: pd.DataFrame) -> go.Figure:
    fig = go.Figure()
    for col, name in (("speed_median_m_s", "median speed"), ("speed_p95_m_s", "95th centile speed")):
        fig.add_trace(go.Scatter(x=d["date"], y=d[col], mode="lines+markers", name=name))
    fig.update_yaxes(title="walking speed (m/s), bouts > 10 s")
    fig.update_layout(height=300, margin=dict(l=40, r=10, t=40, b=40), title="Walking speed per home day")
    return fig


def _classes_figure(d: pd.DataFrame) -> go.Figure:
    fig = go.Figure()
    for label, col in Q.BOUT_CLASSES.items():
        fig.add_trace(go.Bar(x=d["date"], y=d[col], name=label))
    fig.update_layout(barmode="stack", height=300, margin=dict(l=40, r=10, t=40, b=40),
                      title="Walking bouts per day by duration", yaxis_title="bouts")
    return fig


def _capacity_figure(c: pd.DataFrame) -> go.Figure:
    fig = go.Figure()
    x = [f"visit {v} ({d})" for v, d in zip(c["visit"], c["lab_date"])]
    fig.add_trace(go.Bar(x=x, y=c["lab_speed_m_s"], name="lab gait speed (capacity)"))
    fig.add_trace(go.Bar(x=x, y=c["home_speed_median_m_s"], name="home: median speed (performance)"))
    fig.add_trace(go.Bar(x=x, y=c["home_speed_p95_m_s"], name="home: 95th centile speed"))
    fig.update_layout(barmode="group", height=320, margin=dict(l=40, r=10, t=40, b=40), yaxis_title="m/s",
                      title="Capacity (lab) beside performance (home, the days after each visit)")
    return fig


if snap is not None and not empty_warehouse_note(snap):
    who = snap.q(Q.trunk_gait_participants, current_study())
    if who is None:
        st.caption(":material/hourglass_empty: No walking bouts in this warehouse yet: they are computed by the "
                   f"trunk_gait stage from a lower_back or chest IMU; {Q.RUN_HINT}.")
    elif who.empty:
        st.info("The trunk-gait stage found no walking bouts yet (no session with a lower_back or chest IMU"
                + (f" in study {current_study()}" if current_study() else "") + ").")
    else:
        labels = (who["participant_id"] + " · " + who["study"]).tolist()
        qp = st.query_params.get("participant")
        idx = next((i for i, p in enumerate(who["participant_id"]) if p == qp), 0)
        choice = st.sidebar.selectbox("Participant (pseudonym)", labels, index=idx, key="home_pid")
        row = who.iloc[labels.index(choice)]
        pid, study = row["participant_id"], row["study"]
        days = snap.q(Q.daily_gait_outcomes, pid, study)
        bouts = snap.q(Q.trunk_walking_bouts, pid, study)
        cap = snap.q(Q.capacity_and_performance, pid, study)
        c = st.columns(4)
        c[0].metric("Home days", int(len(days)))
        c[1].metric("Walking bouts at home", int((bouts["kind"] == "free_living").sum()))
        c[2].metric("Walking per day (min)", f"{days['walking_time_s'].mean() / 60:.1f}" if len(days) else "—")
        flagged = bouts["flags"].fillna("").str.contains("wrong_placement|upside_down").sum()
        c[3].metric("Bouts with placement warnings", int(flagged))

        st.subheader("Lab capacity beside home performance")
        if cap is not None and len(cap):
            st.plotly_chart(_capacity_figure(cap), key="home_capacity")
            st.dataframe(cap.rename(columns={"lab_speed_m_s": "lab gait speed (m/s)",
                                             "home_speed_median_m_s": "home median speed (m/s)",
                                             "home_speed_p95_m_s": "home p95 speed (m/s)",
                                             "walking_min_per_day": "walking min/day"}),
                         hide_index=True)
            st.caption("Lab gait speed = the clinical gait speed of the lab visit (foot IMUs, gait stage). Home = "
                       "the daily outcomes of the free-living days from that visit to the next: median over the "
                       "days of each day's median and 95th centile walking speed over bouts longer than 10 s.")
        else:
            st.caption("No lab visit for this participant.")

        st.subheader("Per day")
        if len(days):
            g1, g2 = st.columns(2)
            g1.plotly_chart(_days_figure(days), key="home_days_speed")
            g2.plotly_chart(_classes_figure(days), key="home_days_classes")
            show = ["date", "placement", "walking_time_s", "n_bouts", *Q.BOUT_CLASSES.values(),
                    "speed_median_m_s", "speed_p95_m_s", "stride_length_median_m", "stride_length_p95_m",
                    "cadence_median_spm", "cadence_p95_spm", "stride_velocity_p95_m_s", "height_source"]
            st.dataframe(days[show].rename(columns={v: f"bouts {k}" for k, v in Q.BOUT_CLASSES.items()}),
                         hide_index=True)
        else:
            st.caption("No free-living day with a trunk sensor for this participant.")

        st.subheader("Walking bouts")
        st.dataframe(bouts[["kind", "start_local", "placement", "duration_s", "n_steps", "cadence_spm",
                            "stride_length_m", "walking_speed_m_s", "n_turns", "flags", "height_source"]],
                     hide_index=True)
        st.caption("Bouts by the trunk-gait estimators (Mobilise-D consensus rules: a minimum number of strides "
                   "and a longest break per bout, docs/trunk_gait.md). Flags: default_height = no body height known (1.70 m used); wrong_placement / "
                   "upside_down = the sensor frame detected from the data (docs/walking_at_home.md).")
footer(snap)
