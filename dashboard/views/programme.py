"""Programme: change of the clinical gait measures between lab visits, for the cohort and per participant, with
the measurement's own uncertainty (MDC95 from the stride-to-stride variation, docs/clinical_measures.md)."""
import streamlit as st

from stridelab.dashboard import figures as F
from stridelab.warehouse import queries as Q
from stridelab.dashboard.common import current_study, empty_warehouse_note, footer, snapshot
from stridelab.reports.normative import CLINICAL_BANDS

st.title("Programme: change between visits")
snap = snapshot()
if snap is not None and not empty_warehouse_note(snap):
    visits = snap.q(Q.clinical_visits, current_study())
    if visits is None:
        st.info(f"No clinical gait measures in this warehouse yet: they are computed by the clinical stage after the "
                f"gait stage; {Q.RUN_HINT}.")
    elif visits.empty:
        st.info("No lab session with clinical gait measures in this study yet.")
    else:
        keys = list(Q.CLINICAL_SHOWN)
        label = st.selectbox("Measure", [Q.CLINICAL_SHOWN[k] for k in keys], key="prog_measure")
        measure, quantity = keys[[Q.CLINICAL_SHOWN[k] for k in keys].index(label)]
        ch = Q.programme_change(visits, measure, quantity)
        n_multi = int((ch["visits"] > 1).sum())
        c1, c2, c3 = st.columns(3)
        c1.metric("Participants with ≥ 2 visits", f"{n_multi} / {len(ch)}")
        c2.metric("Change beyond MDC95", int(ch["beyond_mdc"].sum()))
        c3.metric("Lab visits", int(visits["session_id"].nunique()))
        st.subheader("Cohort: first → latest visit")
        if n_multi:
            st.plotly_chart(F.programme_change(ch, label), key="programme_change")
        else:
            st.caption("No participant has a second lab visit yet.")
        st.dataframe(ch.rename(columns={"participant_id": "participant", "baseline": "first visit",
                                        "latest": "latest visit", "mdc95": "MDC95", "mdc_source": "MDC95 from",
                                        "beyond_mdc": "beyond MDC95",
                                        "flag": "data-quality flags"}).drop(columns=["study", "mdc_known"]),
                     hide_index=True,
                     column_config={c: st.column_config.NumberColumn(format="%.3f")
                                    for c in ("first visit", "latest visit", "change", "MDC95")})
        st.caption("MDC95 of a change = between-session measurement error: from the study's repeated baseline "
                   "sessions when it has them (session field repeat_baseline = 1), else the published test-retest "
                   "value for the baseline (gait speed after stroke: 0.10 / 0.15 / 0.18 m/s for baseline < 0.4 / "
                   "0.4-0.8 / > 0.8 m/s, Lewek & Sykes 2019); empty where neither exists (beyond MDC95 then stays "
                   "unknown). Never the within-session stride-to-stride SEM (docs/clinical_measures.md). "
                   "Flags: few_strides = fewer than 6 used strides on a side.")

        st.subheader("Participant trend")
        who = sorted(visits["participant_id"].unique())
        qp = st.query_params.get("participant")
        pid = st.selectbox("Participant (pseudonym)", who, index=who.index(qp) if qp in who else 0, key="prog_pid")
        mine = visits[visits["participant_id"] == pid]
        cols = st.columns(2)
        for i, (m, q) in enumerate(k for k in keys if k in (("gait_speed_m_s", "value"),
                                                            ("step_time_s", "symmetry_ratio"),
                                                            ("swing_time_s", "symmetry_ratio"),
                                                            ("stance_time_s", "symmetry_ratio"))):
            s = Q.clinical_series(mine, m, q)
            band_key = m if q == "value" else f"{m}_symmetry"
            b = CLINICAL_BANDS.get(band_key if band_key != "gait_speed_m_s" else "gait_speed_healthy_m_s")
            band = (b[0][0], b[0][1], f"{b[0][2]} ({b[0][3]})") if b else None
            cols[i % 2].plotly_chart(F.clinical_trend(s, Q.CLINICAL_SHOWN[(m, q)], band), key=f"trend_{m}_{q}")
        st.caption("Error bars: ± 1.96 SEM of the session (stride-to-stride variation). Green band: orientation "
                   "values for healthy adults with their source (docs/clinical_measures.md).")
footer(snap)
