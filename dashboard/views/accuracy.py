"""Accuracy against references, per stage and algorithm: error distributions, Bland–Altman (stride
length, joint range of motion), event timing error histograms, posture confusion matrix."""
import streamlit as st

from stridelab.dashboard import figures as F
from stridelab.warehouse import queries as Q
from stridelab.dashboard.common import current_study, empty_warehouse_note, footer, hint, snapshot

st.title("Accuracy against references")
snap = snapshot()
if snap is not None and not empty_warehouse_note(snap):
    opts = snap.q(Q.accuracy_filters)
    with st.sidebar:
        st.subheader("Filters")
        chosen = current_study()
        study = [chosen] if chosen else st.multiselect("Studies to compare", opts["study"], key="acc_study")
        estimator = st.multiselect("Estimator", opts["estimator"], key="acc_estimator")
        placement = st.multiselect("Placement / joint", opts["placement"], key="acc_placement")
        trial = st.multiselect("Trial type", opts["trial"], key="acc_trial")
    filt = (tuple(study), tuple(estimator), tuple(placement), tuple(trial))
    metrics = snap.q(Q.accuracy_metrics, *filt)
    pairs = snap.q(Q.accuracy_pairs, *filt)
    stages = ["orientation", "calibration", "joint_angles", "gait_events", "strides", "foot_trajectory", "activity"]
    if metrics is not None and not metrics.empty:
        stages += [s for s in sorted(metrics["stage"].unique()) if s not in stages]
    tabs = st.tabs([s.replace("_", " ") for s in stages])
    for stage, tab in zip(stages, tabs):
        with tab:
            m = None if metrics is None else metrics[metrics["stage"].astype(str).str.startswith(stage.rstrip("s"))]
            if metrics is None:
                hint("accuracy")
            elif m.empty:
                st.caption(f"No {stage.replace('_', ' ')} accuracy rows for these filters (a reference is needed; "
                           f"check the filters or run the stage).")
            else:
                group = [c for c in ("dataset", "reference", "estimator", "placement", "metric", "unit")
                         if c in m and m[c].notna().any()]
                table = m.groupby(group, dropna=False)["value"].agg(["count", "mean", "std", "median", "min", "max"])
                table = table.reset_index().rename(columns={"count": "sessions"})
                first = [c for c in ("metric", "placement", "mean", "median", "std", "min", "max", "unit", "sessions")
                         if c in table]
                st.dataframe(table[first + [c for c in table if c not in first]], hide_index=True,
                             column_config={"dataset": "data (study · protocol)", "reference": "scored against"})
                if "data" in m:
                    with st.expander(f"{m['session_id'].nunique() if 'session_id' in m else len(m)} sessions: "
                                     f"every row with its recording and reference"):
                        cols = [c for c in ("data", "reference", "estimator", "placement", "metric", "value", "unit")
                                if c in m]
                        st.dataframe(m[cols], hide_index=True, key=f"rows_{stage}")
                for metric in [x for x in sorted(m["metric"].unique()) if not str(x).startswith("n_")][:4]:
                    st.plotly_chart(F.error_distribution(m, metric), key=f"dist_{stage}_{metric}")
            p = None if pairs is None else pairs[pairs["stage"].astype(str).str.startswith(stage.rstrip("s"))] \
                if "stage" in pairs else pairs
            if stage == "strides":
                sl = snap.q(Q.stride_length_pairs, study[0] if len(study) == 1 else None)
                src = sl if sl is not None and not sl.empty else \
                    (p[p["quantity"].str.contains("stride_length")] if p is not None else None)
                if src is not None and not src.empty:
                    st.plotly_chart(F.bland_altman(src, "stride length", "(m)"), key="ba_stride")
            if stage in ("joint_angles", "calibration") and p is not None:
                rom = p[p["quantity"].str.contains("rom")]
                for q, g in rom.groupby("quantity"):
                    st.plotly_chart(F.bland_altman(g, q.replace("_", " "), "(deg)"), key=f"ba_{stage}_{q}")
            if stage == "gait_events" and p is not None:
                ev = p[p["quantity"].str.upper().str.match(r"^(IC|TC)")].copy()
                if not ev.empty:
                    scale = ev["unit"].map({"ns": 1e-6, "s": 1e3, "ms": 1.0}).fillna(1.0) if "unit" in ev else 1.0
                    ev["error_ms"] = (ev["estimate"] - ev["reference"]) * scale
                    st.plotly_chart(F.timing_histogram(ev), key="timing_hist")
            if stage == "activity":
                conf = snap.q(Q.posture_confusion, study[0] if len(study) == 1 else None)
                if conf is None:
                    hint("activity_bouts")
                elif conf.empty:
                    st.caption("No reference activity labels overlap the classified bouts.")
                else:
                    st.plotly_chart(F.confusion(conf), key="confusion")
footer(snap)
