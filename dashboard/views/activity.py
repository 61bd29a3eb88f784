"""Activity: day-by-day posture timeline, daily totals (time per class, steps per modality,
transitions) and trends across weeks."""
import pandas as pd
import streamlit as st

from stridelab.dashboard import figures as F
from stridelab.warehouse import queries as Q
from stridelab.dashboard.common import current_study, empty_warehouse_note, footer, hint, snapshot

st.title("Daily activity")
snap = snapshot()
if snap is not None and not empty_warehouse_note(snap):
    if not snap.q(Q.available)["activity_bouts"]:
        hint("activity_bouts")
    else:
        who = snap.q(Q.activity_participants)
        if current_study() is not None:
            who = who[who["study"] == current_study()].reset_index(drop=True)
        if who.empty and current_study() is not None:
            st.info(f"No free-living chest recording classified in study {current_study()}; choose another study "
                    f"in the sidebar.")
        elif who.empty:
            st.info("The activity stage has run but found no free-living chest recording to classify.")
        else:
            labels = (who["participant_id"] + " · " + who["study"]).tolist()
            qp = st.query_params.get("participant")
            idx = next((i for i, p in enumerate(who["participant_id"]) if p == qp), 0)
            choice = st.sidebar.selectbox("Participant (pseudonym)", labels, index=idx, key="act_pid")
            row = who.iloc[labels.index(choice)]
            pid, study = row["participant_id"], row["study"]
            daily = snap.q(Q.activity_daily, pid, study)
            daily = daily.assign(day=daily["day"].astype(str).str[:10])          # ISO local dates
            days = sorted(daily["day"].unique())
            day = st.select_slider("Day", options=days, value=days[0], key="act_day",
                                   format_func=lambda v: f"{pd.Timestamp(v):%a %d %b %Y}") if len(days) > 1 else days[0]
            bouts = snap.q(Q.activity_bouts, pid, study, day)
            st.plotly_chart(F.activity_timeline(bouts), key="activity_timeline")
            d = daily[daily["day"] == day]
            cols = st.columns(4)
            hours = d.set_index("class")["hours"]
            cols[0].metric("Walking (h)", f"{hours.reindex(['level_walking', 'stairs_up', 'stairs_down']).sum():.2f}")
            cols[1].metric("Upright (h)", f"{hours.reindex(['standing', 'level_walking', 'stairs_up', 'stairs_down']).sum():.2f}")
            steps = d["steps"].sum()
            cols[2].metric("Steps", f"{steps:.0f}" if steps == steps and steps > 0 else "—")
            tr = d.loc[d["class"] == "_transitions", "bouts"]
            cols[3].metric("Posture transitions", int(tr.iloc[0]) if len(tr) else 0)

            st.subheader("Daily totals")
            st.plotly_chart(F.daily_totals(daily), key="daily_totals")
            if daily["steps"].fillna(0).gt(0).any():
                st.plotly_chart(F.daily_steps(daily), key="daily_steps")
            table = daily.pivot_table(index="day", columns="class", values="hours", aggfunc="sum").round(2)
            trans = daily[daily["class"] == "_transitions"].set_index("day")["bouts"]
            table["transitions"] = trans.reindex(table.index).fillna(0).astype(int)
            table = table.drop(columns=["_transitions"], errors="ignore")
            st.dataframe(table.reset_index(), hide_index=True)
            walk = snap.q(Q.walking_bouts, pid, study)
            if walk is not None and not walk.empty:
                st.subheader("Free-living walking bouts")
                ws = Q.walking_summary(walk)
                today = ws[ws["day"] == day]
                c = st.columns(4)
                if len(today):
                    t = today.iloc[0]
                    c[0].metric("Walking bouts", int(t["bouts"]))
                    c[1].metric("Longest bout (min)", f"{t['longest_bout_s'] / 60:.1f}")
                    c[2].metric("Bouts ≥ 1 min: cadence", "—" if t["cadence_long_bouts_spm"] != t["cadence_long_bouts_spm"]
                                else f"{t['cadence_long_bouts_spm']:.0f} /min")
                    c[3].metric("Walking in bouts ≥ 1 min", f"{t['share_in_long_bouts_pct']:.0f} %")
                g1, g2 = st.columns(2)
                g1.plotly_chart(F.walking_bout_durations(walk), key="walking_durations")
                g2.plotly_chart(F.walking_by_hour(walk), key="walking_by_hour")
                st.dataframe(ws.rename(columns={"session_id": "session", "walking_min": "walking min",
                                                "median_bout_s": "median bout s", "longest_bout_s": "longest bout s",
                                                "cadence_long_bouts_spm": "cadence in bouts ≥ 1 min (/min)",
                                                "share_in_long_bouts_pct": "% walking in bouts ≥ 1 min"}),
                             hide_index=True)
                st.caption("Walking bouts = the activity stage's runs of level walking and stairs (joined when "
                           "consecutive); cadence = steps / bout duration. Steps per day: < 5,000 sedentary, "
                           "≥ 10,000 active (Tudor-Locke & Bassett 2004).")
            if len(days) > 1:
                st.subheader("Trend across weeks")
                st.plotly_chart(F.weekly_trend(daily), key="weekly_trend")
footer(snap)
