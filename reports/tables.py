"""The report's tables as DataFrames (column names are the printed headers) and the cell format they share."""
from __future__ import annotations

import numpy as np
import pandas as pd

from stridelab.reports.normative import CLINICAL_BANDS, band_label
from stridelab.warehouse import queries as Q

#: page-1 rows from the clinical measures: (measure, quantity, label, band key)
SUMMARY_GAIT = [("gait_speed_m_s", "value", "Gait speed (m/s)", "gait_speed_m_s"),
                ("cadence_steps_min", "value", "Cadence (steps/min)", None),
                ("step_time_s", "symmetry_ratio", "Step time symmetry ratio", None),
                ("swing_time_s", "symmetry_ratio", "Swing time symmetry ratio", "swing_time_s_symmetry"),
                ("stance_time_s", "symmetry_ratio", "Stance time symmetry ratio", "stance_time_s_symmetry"),
                ("single_support_s", "symmetry_ratio", "Single support symmetry ratio", None),
                ("step_length_m", "symmetry_ratio", "Step length symmetry ratio *", "step_length_m_symmetry"),
                ("double_support_pct", "value", "Double support (% of stride)", "double_support_pct")]
UPRIGHT = ("standing", "level_walking", "stairs_up", "stairs_down")

def home_days_table(days: pd.DataFrame) -> pd.DataFrame:
    return pd.DataFrame({"Day": days["date"], "Walking min": (days["walking_time_s"] / 60).round(1),
                         "Bouts": days["n_bouts"], **{f"{k}": days[v] for k, v in Q.BOUT_CLASSES.items()},
                         "Speed median m/s": days["speed_median_m_s"].round(2),
                         "Speed p95 m/s": days["speed_p95_m_s"].round(2),
                         "Stride length median m": days["stride_length_median_m"].round(2),
                         "Cadence median /min": days["cadence_median_spm"].round(0),
                         "Stride velocity p95 m/s": days["stride_velocity_p95_m_s"].round(2)})


def fmt(v) -> str:
    if v is None or (isinstance(v, float) and np.isnan(v)):
        return "—"
    if isinstance(v, (float, np.floating)):
        return f"{v:.3g}" if abs(v) < 1000 else f"{v:.0f}"
    if isinstance(v, pd.Timestamp):
        return v.strftime("%Y-%m-%d %H:%M")
    return str(v)


def sessions_table(d) -> pd.DataFrame:
    s = d["sessions"]
    if s.empty:
        return pd.DataFrame(columns=["session", "kind", "protocol", "start", "hours", "recordings"])
    return pd.DataFrame({"Session": s["session_id"], "Kind": s["kind"].str.replace("_", " "), "Protocol": s["protocol"],
                         "Start (UTC)": pd.to_datetime(s["start"], utc=True).dt.strftime("%Y-%m-%d %H:%M"),
                         "Hours": s["hours"].round(2), "Recordings": s["recordings"], "Trials": s["trials"]})


def gait_table(gait: pd.DataFrame) -> pd.DataFrame:
    cols = {"session_id": "Session", "strides": "Strides", "speed_m_s": "Mean stride speed m/s",
            "cadence_steps_min": "Cadence /min", "stride_length_m": "Stride length m", "stance_pct": "Stance % of stride"}
    return gait[[c for c in cols if c in gait]].rename(columns=cols)


def quality_table(d) -> pd.DataFrame:
    rec, iss = d["recordings"], d["issues"]
    rows = [("recordings ingested", int((rec["status"] == "ingested").sum()) if not rec.empty else 0),
            ("recording warnings (gaps, …)", int((iss["source"] == "recording").sum()) if not iss.empty else 0),
            ("failed pipeline stages", int((iss["source"] == "stage").sum()) if not iss.empty else 0),
            ("calibration QC flags", int((iss["source"] == "calibration").sum()) if not iss.empty else 0),
            ("IMUs with orientation", len(d["orientation"]))]
    return pd.DataFrame(rows, columns=["Check", "Count"])


def activity_table(daily: pd.DataFrame) -> pd.DataFrame:
    d = daily.copy()
    t = d[d["class"] != "_transitions"].pivot_table(index="day", columns="class", values="hours", aggfunc="sum",
                                                    fill_value=0.0)
    out = pd.DataFrame(index=t.index)
    out["lying h"] = t.get("lying", 0.0)
    out["sitting h"] = t.get("sitting", 0.0)
    out["standing h"] = t.get("standing", 0.0)
    out["walking h"] = sum(t.get(c, 0.0) for c in ("level_walking", "stairs_up", "stairs_down"))
    steps = d[d["class"] != "_transitions"].groupby("day")["steps"].sum(min_count=1)
    out["steps"] = steps.reindex(out.index)
    tr = d[d["class"] == "_transitions"].set_index("day")["bouts"]
    out["transitions"] = tr.reindex(out.index).fillna(0).astype(int)
    out = out.round(2).reset_index()
    out["day"] = out["day"].astype(str)
    return out.rename(columns={"day": "Day", "lying h": "Lying h", "sitting h": "Sitting h", "standing h": "Standing h",
                               "walking h": "Walking h", "steps": "Steps (all)", "transitions": "Posture transitions"})


def _num(v, digits: int = 2) -> str:
    return "—" if v is None or not np.isfinite(v) else f"{v:.{digits}f}"


def _band_text(key: str | None, value: float) -> str:
    """'healthy ≤ 1.06 (Patterson et al. 2010)' or the class a value falls in, with its source."""
    if key is None or key not in CLINICAL_BANDS:
        return ""
    if key.endswith("_symmetry"):
        lo, hi, _what, src = CLINICAL_BANDS[key][0]
        return f"healthy ≤ {hi:.2f} ({src})"
    what = band_label(key, value)
    src = next((b[3] for b in CLINICAL_BANDS[key] if b[2] == what), "")
    return f"{what} ({src})" if what else ""


def free_living_by_visit(d) -> pd.DataFrame:
    """Per lab visit: the chest days after it (before the next visit): steps/day, upright h/day, recorded h/day,
    walking bouts ≥ 1 min per day, longest walking bout (min)."""
    daily, walking, ses = d["daily"], d["walking"], d["sessions"]
    cols = ["visit", "days", "steps/day", "upright h/day", "recorded h/day", "bouts ≥ 1 min/day",
            "longest bout (min)"]
    if daily is None or daily.empty:
        return pd.DataFrame(columns=cols)
    lab = ses[ses["kind"] == "lab"].sort_values("start")
    starts = [pd.Timestamp(t).tz_convert("UTC").date() for t in lab["start"]] if len(lab) else []
    dd = daily[daily["class"] != "_transitions"].copy()
    dd["day"] = pd.to_datetime(dd["day"].astype(str).str[:10]).dt.date
    per_day = dd.groupby("day").agg(steps=("steps", lambda x: x.sum(min_count=1)), recorded=("hours", "sum"))
    per_day["upright"] = dd[dd["class"].isin(UPRIGHT)].groupby("day")["hours"].sum().reindex(per_day.index).fillna(0)
    if walking is not None and not walking.empty:
        w = walking.assign(day=pd.to_datetime(walking["day"]).dt.date)
        per_day["long_bouts"] = w[w["seconds"] >= 60].groupby("day").size().reindex(per_day.index).fillna(0)
        per_day["longest"] = w.groupby("day")["seconds"].max().reindex(per_day.index) / 60
    else:
        per_day["long_bouts"], per_day["longest"] = np.nan, np.nan
    per_day["visit"] = [sum(1 for s0 in starts if s0 <= day) or 1 for day in per_day.index]
    rows = []
    for v, g in per_day.groupby("visit"):
        rows.append([v, len(g), g["steps"].mean(), g["upright"].mean(), g["recorded"].mean(), g["long_bouts"].mean(),
                     g["longest"].max()])
    return pd.DataFrame(rows, columns=cols)


def summary_table(d) -> tuple[pd.DataFrame, list[str]]:
    """Page 1: each headline measure at the latest visit, the previous visit, the change and its MDC95, and the
    normative band with its source; plus the flags where data quality limits a number."""
    visits, flags = d["clinical"], []
    cols = ["Measure", "Latest visit", "Previous visit", "Change", "MDC95 of the change", "Beyond noise?",
            "Reference band (source)"]
    rows = []
    n_visits = 0
    if visits is not None and not visits.empty:
        n_visits = int(visits["visit"].max())
        latest = visits[visits["visit"] == n_visits]
        for m, q, label, band in SUMMARY_GAIT:
            ch = Q.programme_change(visits, m, q, against="previous")
            if ch.empty:
                continue
            r = ch.iloc[0]
            has_prev = r["visits"] > 1
            rows.append([label, _num(r["latest"] if has_prev else r["baseline"]), _num(r["baseline"]) if has_prev
                         else "—", f"{r['change']:+.2f}" if has_prev and np.isfinite(r["change"]) else "—",
                         _num(r["mdc95"]) if has_prev and r["mdc_known"] else "—",
                         ("see *" if m == "step_length_m" else "yes" if r["beyond_mdc"] else "no")
                         if has_prev and np.isfinite(r["change"]) and r["mdc_known"] else "—",
                         _band_text(band, r["latest"] if has_prev else r["baseline"])])
        fl = sorted({f for f in latest["flag"].fillna("") if f})
        if "few_strides" in fl:
            few = latest.loc[latest["flag"] == "few_strides", "measure"].tolist()
            flags.append(f"Fewer than 6 usable strides on a side at the latest visit ({', '.join(few)}): those "
                         f"numbers are less certain.")
        if "one_side" in fl:
            flags.append("Strides on one side only at the latest visit: no ratios for the measures concerned.")
        side = latest["paretic_side"].dropna().unique()
        flags.append(f"Paretic side: {side[0]} (session metadata or study manifest)." if len(side) else
                     "Paretic side unknown: symmetry ratios only (larger / smaller side), no paretic ratios.")
        note = latest["note"].dropna()
        if len(note) and any(k in note.iloc[0] for k in ("contralateral", "out of order", "no step length")):
            flags.append("Gait events: " + note.iloc[0][:240])
        flags.append("* Step length comes from two separately integrated foot sensors: the ratio is uncertain by "
                     "about ±0.1 (docs/clinical_measures.md); the temporal ratios are the more reliable asymmetry "
                     "measures.")
    fl_v = free_living_by_visit(d)
    if not fl_v.empty:
        last = fl_v.iloc[-1]
        prev = fl_v.iloc[-2] if len(fl_v) > 1 else None
        for col, label, band, digits in (("steps/day", "Steps per day (free living)", "steps_per_day", 0),
                                         ("upright h/day", "Upright time (h/day)", None, 1),
                                         ("longest bout (min)", "Longest walking bout (min)", None, 1)):
            a, b = float(last[col]), (float(prev[col]) if prev is not None else np.nan)
            rows.append([label, _num(a, digits), _num(b, digits), f"{a - b:+.{digits}f}" if np.isfinite(b) and
                         np.isfinite(a) else "—", "—", "—", _band_text(band, a)])
        if float(last["recorded h/day"]) < 23.0:
            flags.append(f"Free-living days recorded {last['recorded h/day']:.1f} h on average (not whole days): "
                         f"steps and upright time are per recorded day.")
    iss = d["issues"]
    if not iss.empty:
        n_stage = int((iss["source"] == "stage").sum())
        n_rec = int((iss["source"] == "recording").sum())
        if n_stage:
            flags.append(f"{n_stage} pipeline stage(s) failed for this participant: some numbers are missing.")
        if n_rec:
            flags.append(f"{n_rec} recording warning(s) (gaps, clock issues): see page 5.")
    return pd.DataFrame(rows, columns=cols), flags


def clinical_visit_table(visits: pd.DataFrame) -> pd.DataFrame:
    """One row per lab visit: speed, cadence, symmetry ratios, double support, usable strides per side."""
    out = []
    for v, g in visits.groupby("visit"):
        m = g.set_index("measure")
        get = lambda name, col="value": m[col].get(name, np.nan)                # noqa: E731
        out.append({"Visit": int(v), "Date": pd.Timestamp(g["date"].iloc[0]).strftime("%Y-%m-%d"),
                    "Speed m/s": _num(get("gait_speed_m_s")), "Cadence /min": _num(get("cadence_steps_min"), 0),
                    "Step time SR": _num(get("step_time_s", "symmetry_ratio")),
                    "Swing SR": _num(get("swing_time_s", "symmetry_ratio")),
                    "Stance SR": _num(get("stance_time_s", "symmetry_ratio")),
                    "Single supp. SR": _num(get("single_support_s", "symmetry_ratio")),
                    "Step length SR *": _num(get("step_length_m", "symmetry_ratio")),
                    "Double supp. %": _num(get("double_support_pct"), 1),
                    "Strides L / R": f"{int(get('step_time_s', 'n_left') or 0)} / {int(get('step_time_s', 'n_right') or 0)}"})
    return pd.DataFrame(out)


def clinical_side_table(visits: pd.DataFrame) -> pd.DataFrame:
    """Latest visit, per measure: the two sides (paretic / non-paretic when known), their ratio, symmetry ratio,
    stride-to-stride CV per side."""
    latest = visits[visits["visit"] == visits["visit"].max()]
    names = {"step_time_s": "Step time (s)", "step_length_m": "Step length (m) *", "swing_time_s": "Swing (s)",
             "stance_time_s": "Stance (s)", "single_support_s": "Single support (s)",
             "stride_time_s": "Stride time (s)", "stride_length_m": "Stride length (m)"}
    side = latest["paretic_side"].dropna()
    par = side.iloc[0] if len(side) else None
    a_lab, b_lab = ("Paretic", "Non-paretic") if par else ("Left", "Right")
    rows = []
    for name, label in names.items():
        r = latest[latest["measure"] == name]
        if r.empty:
            continue
        r = r.iloc[0]
        a, b = (r["left_value"], r["right_value"]) if par in (None, "left") else (r["right_value"], r["left_value"])
        ca, cb = (r["cv_left_pct"], r["cv_right_pct"]) if par in (None, "left") else (r["cv_right_pct"], r["cv_left_pct"])
        rows.append({"Measure": label, a_lab: _num(a, 3), b_lab: _num(b, 3),
                     f"{a_lab} / {b_lab.lower()}": _num(a / b if b else np.nan),
                     "Symmetry ratio": _num(r["symmetry_ratio"]), f"CV {a_lab.lower()} %": _num(ca, 1),
                     f"CV {b_lab.lower()} %": _num(cb, 1)})
    return pd.DataFrame(rows)


def walking_table(bouts: pd.DataFrame) -> pd.DataFrame:
    w = Q.walking_summary(bouts)
    return pd.DataFrame({"Day": w["day"], "Steps in bouts": w["steps"].round(0), "Walking min": w["walking_min"].round(1),
                         "Bouts": w["bouts"], "Median bout s": w["median_bout_s"].round(0),
                         "Longest bout s": w["longest_bout_s"].round(0),
                         "Cadence in bouts ≥ 1 min": w["cadence_long_bouts_spm"].round(0),
                         "% walking in bouts ≥ 1 min": w["share_in_long_bouts_pct"].round(0)})


def accuracy_table(acc: pd.DataFrame) -> pd.DataFrame:
    group = [c for c in ("stage", "estimator", "metric", "unit") if c in acc and acc[c].notna().any()]
    t = acc.groupby(group, dropna=False)["value"].agg(["count", "mean", "std"]).round(3).reset_index()
    return t.rename(columns={"stage": "Stage", "estimator": "Estimator", "metric": "Metric", "unit": "Unit",
                             "count": "N", "mean": "Mean", "std": "SD"})
