"""Per-participant report: a self-contained HTML file and a PDF with the same content and a fixed layout.

Layout (always the same five A4 pages, so a study coordinator can file them; a section without data
says why and what to run):

1. summary for the clinician: speed, asymmetry ratios, steps/day, upright time at the latest visit, the change
   since the previous visit against its minimal detectable change, normative bands with their source, and the
   flags where data quality limits a number
2. gait: parameters across sessions (Figure 1), clinical measures per visit and per side (paretic /
   non-paretic ratio, symmetry ratio, variability) and their trend with uncertainty (Figure 2)
3. joint-angle cycles of the newest lab session against a normative band (Figure 3)
4. daily activity: time per class per day (Figure 4), a daily table, and free-living walking bouts
   (durations, time of day: Figure 5; steps, cadence within bouts, longest bout)
5. sessions, data quality, and accuracy against the reference where one was recorded (Figure 6)

Only the pseudonym identifies the participant; file names (which may carry site identifiers) are
not printed. Figures are drawn once with matplotlib and embedded in both outputs (inline SVG in
the HTML, 160 dpi images in the PDF). Reads only the newest published snapshot.
"""
from __future__ import annotations

import html
import io
import os
import re
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pandas as pd

from reports.normative import CLINICAL_BANDS, band_label, normative_band
from warehouse import queries as Q

A4 = (8.27, 11.69)
TITLES = {1: "Summary", 2: "Gait: speed, steps and asymmetry", 3: "Joint angles",
          4: "Daily activity and free-living walking", 5: "Sessions, data quality and accuracy against reference",
          6: "Walking at home (trunk sensor)"}
#: figures, numbered in the order they appear in the report
FIG_CAPTIONS = {"gait": "Figure 1: Gait parameters across sessions (the gait stage's summary per session)",
                "clinical": "Figure 2: Clinical measures per lab visit (error bars: ± 1.96 SEM within the session)",
                "joints": "Figure 3: Joint angles over the gait cycle, newest lab session, against a normative band",
                "activity": "Figure 4: Time per activity class and day",
                "walking": "Figure 5: Free-living walking bouts: duration and time of day",
                "bland_altman": "Figure 6: Bland-Altman plot of stride length (IMU vs reference)",
                "home": "Figure 7: Lab capacity beside home performance, and walking speed per home day"}
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


# ---- data -----------------------------------------------------------------------------------

def collect(con, root: Path, participant_id: str, study: str | None) -> dict:
    """Everything the report shows, as DataFrames (None = stage not run yet)."""
    studies = Q.participant_studies(con, participant_id)
    if not studies:
        raise LookupError(f"participant {participant_id!r} is not in the warehouse (check the pseudonym)")
    if study is None:
        if len(studies) > 1:
            raise ValueError(f"participant {participant_id!r} exists in studies {', '.join(studies)}: pass --study")
        study = studies[0]
    elif study not in studies:
        raise LookupError(f"participant {participant_id!r} is not in study {study!r} (found in: {', '.join(studies)})")
    ses = Q.sessions(con, participant_id, study)
    strides = Q.strides(con, participant_id, study)
    acc = Q.accuracy_metrics(con)
    if acc is not None and "session_id" in acc:
        acc = acc[acc["session_id"].isin(ses["session_id"])]
    pairs = Q.stride_length_pairs(con, study)
    if pairs is not None:
        pairs = pairs[pairs["participant_id"] == participant_id]
    if pairs is None or pairs.empty:
        ap = Q.accuracy_pairs(con)
        if ap is not None and "session_id" in ap:
            ap = ap[ap["session_id"].isin(ses["session_id"]) & ap["quantity"].str.contains("stride_length")]
            pairs = ap if not ap.empty else pairs
    return {
        "participant_id": participant_id, "study": study, "sessions": ses,
        "recordings": Q.recordings(con, participant_id, study),
        "issues": Q.participant_issues(con, participant_id, study),
        "strides": strides, "gait": Q.gait_summary(con, participant_id, study),
        "joints": Q.joint_cycles(con, participant_id, study), "calibration": Q.calibration_qc(con, participant_id, study),
        "daily": Q.activity_daily(con, participant_id, study), "accuracy": acc, "stride_pairs": pairs,
        "orientation": Q.orientation_coverage(con, participant_id, study),
        "clinical": Q.clinical_visits(con, study, participant_id),
        "walking": Q.walking_bouts(con, participant_id, study),
        "home_days": Q.daily_gait_outcomes(con, participant_id, study),
        "home_bouts": Q.trunk_walking_bouts(con, participant_id, study),
        "capacity": Q.capacity_and_performance(con, participant_id, study),
    }


# ---- figures (matplotlib) ----------------------------------------------------------------------

def _plt():
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    plt.rcParams.update({"pdf.fonttype": 42, "svg.fonttype": "none", "font.size": 8, "axes.titlesize": 9,
                         "figure.dpi": 100, "svg.hashsalt": "stridelab", "axes.spines.top": False,
                         "axes.spines.right": False})
    return plt


def fig_gait(gait: pd.DataFrame):
    plt = _plt()
    params = [p for p in ("speed_m_s", "cadence_steps_min", "stride_length_m", "stance_pct") if p in gait]
    fig, axes = plt.subplots(1, len(params), figsize=(7.4, 2.3), squeeze=False)
    x = np.arange(len(gait))
    for ax, p in zip(axes[0], params):
        ax.plot(x, gait[p], marker="o", lw=1.2, color="#4c78a8")
        ax.set_title(Q.GAIT_PARAMS[p])
        ax.set_xticks(x, [d.strftime("%d %b") for d in gait["date"]], rotation=45, ha="right")
    fig.tight_layout()
    return fig


def fig_joints(joints: pd.DataFrame):
    plt = _plt()
    sid = joints.sort_values("session_start_ns")["session_id"].iloc[-1]
    j = joints[joints["session_id"] == sid]
    if "plane" in j and j["plane"].notna().any():
        sag = j[j["plane"].astype(str).str.lower().str.contains("sag|flex")]
        j = sag if not sag.empty else j[j["plane"] == sorted(j["plane"].dropna().unique())[0]]
    names = [n for n in ("hip", "knee", "ankle") if j["joint"].astype(str).str.contains(n).any()] or \
        sorted(j["joint"].unique())[:3]
    fig, axes = plt.subplots(1, len(names), figsize=(7.4, 2.5), squeeze=False)
    colors = {"left": "#e45756", "right": "#4c78a8"}
    for ax, name in zip(axes[0], names):
        band = normative_band(name)
        if band is not None:
            pct, m, sd = band
            ax.fill_between(pct, m - sd, m + sd, color="0.8", label="normative ± SD")
        g = j[j["joint"].astype(str).str.contains(name)]
        for side, gs in (g.groupby("side") if "side" in g else [("", g)]):
            gs = gs.sort_values("cycle_pct")
            c = colors.get(str(side), "#333333")
            ax.plot(gs["cycle_pct"], gs["mean_deg"], color=c, lw=1.3, label=str(side) or "mean")
            if "sd_deg" in gs:
                ax.fill_between(gs["cycle_pct"], gs["mean_deg"] - gs["sd_deg"], gs["mean_deg"] + gs["sd_deg"],
                                color=c, alpha=0.15, lw=0)
        ax.set_title(f"{name} (deg)")
        ax.set_xlabel("gait cycle (%)")
    axes[0][0].legend(fontsize=6, frameon=False)
    fig.tight_layout()
    return fig, sid


def fig_activity(daily: pd.DataFrame):
    plt = _plt()
    d = daily[daily["class"] != "_transitions"].pivot_table(index="day", columns="class", values="hours",
                                                            aggfunc="sum", fill_value=0.0)
    cols = [c for c in Q.ACTIVITY_CLASSES if c in d] + [c for c in d if c not in Q.ACTIVITY_CLASSES]
    fig, ax = plt.subplots(figsize=(7.4, 2.8))
    bottom = np.zeros(len(d))
    x = np.arange(len(d))
    for c in cols:
        ax.bar(x, d[c], bottom=bottom, color=Q.ACTIVITY_COLORS.get(c, "#999999"), label=c.replace("_", " "))
        bottom += d[c].to_numpy()
    ax.set_xticks(x, [pd.Timestamp(v).strftime("%a %d %b") for v in d.index], rotation=45, ha="right")
    ax.set_ylabel("hours")
    ax.legend(fontsize=6, ncol=4, frameon=False, loc="upper center", bbox_to_anchor=(0.5, 1.18))
    fig.tight_layout()
    return fig


def fig_bland_altman(pairs: pd.DataFrame):
    plt = _plt()
    est, ref = pairs["estimate"].to_numpy(float), pairs["reference"].to_numpy(float)
    mean, diff = (est + ref) / 2, est - ref
    bias = float(np.nanmean(diff))
    sd = float(np.nanstd(diff, ddof=1)) if len(diff) > 1 else 0.0
    fig, ax = plt.subplots(figsize=(5.0, 2.8))
    ax.scatter(mean, diff * 100, s=8, alpha=0.6, color="#4c78a8")
    for y, ls, lab in ((bias, "-", f"bias {bias * 100:+.1f} cm"), (bias + 1.96 * sd, "--", f"+1.96 SD {(bias + 1.96 * sd) * 100:+.1f} cm"),
                       (bias - 1.96 * sd, "--", f"-1.96 SD {(bias - 1.96 * sd) * 100:+.1f} cm")):
        ax.axhline(y * 100, ls=ls, color="0.3", lw=0.9)
        ax.text(float(np.nanmax(mean)), y * 100, " " + lab, va="bottom", ha="right", fontsize=6)
    ax.set_xlabel("mean of IMU and reference stride length (m)")
    ax.set_ylabel("IMU - reference (cm)")
    fig.tight_layout()
    return fig, bias, sd


def fig_clinical(visits: pd.DataFrame):
    """Speed and the temporal symmetry ratios per lab visit, ± 1.96 SEM, with the healthy band where one exists."""
    plt = _plt()
    panels = [("gait_speed_m_s", "value", "gait speed (m/s)", "gait_speed_healthy_m_s"),
              ("step_time_s", "symmetry_ratio", "step time SR", None),
              ("swing_time_s", "symmetry_ratio", "swing time SR", "swing_time_s_symmetry"),
              ("stance_time_s", "symmetry_ratio", "stance time SR", "stance_time_s_symmetry")]
    fig, axes = plt.subplots(1, len(panels), figsize=(7.4, 2.2), squeeze=False)
    for ax, (m, q, title, band) in zip(axes[0], panels):
        sr = Q.clinical_series(visits, m, q).sort_values("visit")
        if band in CLINICAL_BANDS:
            lo, hi, _what, _src = CLINICAL_BANDS[band][0]
            ax.axhspan(lo, hi, color="#54a24b", alpha=0.15, lw=0)
        ax.errorbar(sr["visit"], sr["value"], yerr=1.96 * sr["sem"], marker="o", capsize=3, lw=1.2, color="#4c78a8")
        ax.set_title(title)
        ax.set_xticks(sr["visit"], [f"visit {v}" for v in sr["visit"]])
        ax.set_xlim(sr["visit"].min() - 0.5, sr["visit"].max() + 0.5)
    fig.tight_layout()
    return fig


def fig_walking(bouts: pd.DataFrame):
    """Histogram of walking-bout durations (log bins) and walking minutes per local hour, per chest day."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(7.4, 2.3))
    b = bouts[bouts["seconds"] > 0]
    edges = np.geomspace(max(1.0, float(b["seconds"].min())), float(b["seconds"].max()) * 1.01, 14)
    days = sorted(b["day"].unique())
    a1.hist([b.loc[b["day"] == d, "seconds"] for d in days], bins=edges, label=days, color=None)
    a1.set_xscale("log")
    a1.set_xlabel("bout duration (s)")
    a1.set_ylabel("bouts")
    width = 0.8 / max(1, len(days))
    for k, d in enumerate(days):
        m = b[b["day"] == d].groupby("hour")["seconds"].sum().reindex(range(24), fill_value=0) / 60
        a2.bar(np.arange(24) + (k - (len(days) - 1) / 2) * width, m.to_numpy(), width=width, label=d)
    a2.set_xlabel("hour of the day (local)")
    a2.set_ylabel("walking minutes")
    a2.set_xticks(range(0, 24, 3))
    a1.legend(fontsize=6, frameon=False)
    fig.tight_layout()
    return fig


def fig_home(cap: pd.DataFrame, days: pd.DataFrame):
    """Left: per lab visit, lab gait speed beside the home days' median and 95th centile speed; right: daily
    median and 95th centile walking speed (bouts > 10 s) per home day."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(7.4, 2.4))
    x = np.arange(len(cap))
    for k, (col, lab) in enumerate((("lab_speed_m_s", "lab gait speed"), ("home_speed_median_m_s", "home median"),
                                    ("home_speed_p95_m_s", "home 95th centile"))):
        a1.bar(x + (k - 1) * 0.27, cap[col].astype(float).fillna(0).to_numpy(), width=0.27, label=lab)
    a1.set_xticks(x, [f"visit {v}" for v in cap["visit"]])
    a1.set_ylabel("m/s")
    a1.legend(fontsize=6, frameon=False)
    if len(days):
        a2.plot(days["date"], days["speed_median_m_s"], "o-", label="median")
        a2.plot(days["date"], days["speed_p95_m_s"], "s--", label="95th centile")
        a2.tick_params(axis="x", labelrotation=30, labelsize=6)
        a2.legend(fontsize=6, frameon=False)
    a2.set_ylabel("walking speed (m/s)")
    fig.tight_layout()
    return fig


def home_days_table(days: pd.DataFrame) -> pd.DataFrame:
    return pd.DataFrame({"Day": days["date"], "Walking min": (days["walking_time_s"] / 60).round(1),
                         "Bouts": days["n_bouts"], **{f"{k}": days[v] for k, v in Q.BOUT_CLASSES.items()},
                         "Speed median m/s": days["speed_median_m_s"].round(2),
                         "Speed p95 m/s": days["speed_p95_m_s"].round(2),
                         "Stride length median m": days["stride_length_median_m"].round(2),
                         "Cadence median /min": days["cadence_median_spm"].round(0),
                         "Stride velocity p95 m/s": days["stride_velocity_p95_m_s"].round(2)})


def _home_blocks(d: dict) -> list[tuple]:
    """Page "Walking at home": lab capacity beside home performance, per-day outcomes, bout-duration classes."""
    days, bouts, cap = d.get("home_days"), d.get("home_bouts"), d.get("capacity")
    if days is None or bouts is None:
        return [("note", "No walking bouts from a trunk sensor yet: the trunk_gait stage computes them from a "
                         "lower_back or chest IMU; " + Q.RUN_HINT + ".")]
    if days.empty and bouts.empty:
        return [("note", "No session of this participant has a lower_back or chest IMU with walking.")]
    out = []
    has_cap = cap is not None and len(cap) and (cap["lab_speed_m_s"].notna().any() or len(days))
    if has_cap:
        out.append(("figure", FIG_CAPTIONS["home"], fig_home(cap, days)))
        out.append(("table", "Capacity (lab visit) beside performance (home days from that visit to the next)",
                    cap.drop(columns=["lab_session"]).rename(columns={
                        "visit": "Visit", "lab_date": "Lab date", "lab_speed_m_s": "Lab gait speed m/s",
                        "home_days": "Home days", "home_speed_median_m_s": "Home median speed m/s",
                        "home_speed_p95_m_s": "Home p95 speed m/s", "walking_min_per_day": "Walking min/day",
                        "days_with_long_bouts": "Days with bouts > 10 s"}).round(2)))
    lab = bouts[bouts["kind"] == "lab"] if len(bouts) else bouts
    if len(lab):
        g = lab.groupby("session_id").agg(bouts=("duration_s", "size"), walking_s=("duration_s", "sum"),
                                          speed=("walking_speed_m_s", "median"), cadence=("cadence_spm", "median"),
                                          stride=("stride_length_m", "median")).reset_index()
        out.append(("table", "Walking bouts in the lab sessions (trunk sensor; medians over the bouts)",
                    g.rename(columns={"session_id": "Session", "bouts": "Bouts", "walking_s": "Walking s",
                                      "speed": "Speed m/s", "cadence": "Cadence /min",
                                      "stride": "Stride length m"}).round(2)))
    if len(days):
        out.append(("table", "Per home day: walking, bouts by duration class, median / 95th centile over bouts "
                             "> 10 s", home_days_table(days)))
    else:
        out.append(("note", "No free-living day with a trunk sensor for this participant."))
    hs = sorted(set(bouts["height_source"].dropna())) if len(bouts) else []
    fl = bouts["flags"].fillna("") if len(bouts) else pd.Series([], dtype=str)
    out.append(("note", "Walking bouts by the trunk-gait estimators (lower back or chest; Mobilise-D consensus "
                        "rules). Speed, stride length and cadence centiles over bouts longer than 10 s; stride "
                        "velocity p95 = 95th centile of stride speeds (SV95C). Body height: " + (", ".join(hs) or "—")
                        + f". Bouts with a placement warning: {int(fl.str.contains('wrong_placement|upside_down').sum())}"
                        f" of {len(bouts)}. Definitions: docs/walking_at_home.md."))
    return out


def _svg(fig) -> str:
    buf = io.StringIO()
    fig.savefig(buf, format="svg", bbox_inches="tight", metadata={"Date": None})
    s = buf.getvalue()
    return s[s.index("<svg"):]


# ---- tables -----------------------------------------------------------------------------------

def _fmt(v) -> str:
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


# ---- the document model: five pages of blocks ------------------------------------------------------

def _blocks(d: dict) -> dict[int, list[tuple]]:
    """Page number -> list of blocks: ("text", str) | ("table", title, df) | ("figure", caption, fig) | ("note", str)."""
    pages: dict[int, list[tuple]] = {k: [] for k in TITLES}
    ses = d["sessions"]
    span = "—" if ses.empty else f"{pd.to_datetime(ses['start'].min(), utc=True):%Y-%m-%d} to " \
                                 f"{pd.to_datetime(ses['end'].max(), utc=True):%Y-%m-%d}"
    n_lab = int((ses["kind"] == "lab").sum())
    pages[1] += [("text", f"Participant (pseudonym): {d['participant_id']}    Study: {d['study']}"),
                 ("text", f"Lab visits: {n_lab}    Free-living sessions: {int((ses['kind'] == 'free_living').sum())}"
                          f"    Period: {span}")]
    summ, flags = summary_table(d)
    if summ.empty:
        pages[1].append(("note", "No clinical gait measures or free-living results for this participant yet: "
                                 + Q.RUN_HINT + "."))
    else:
        pages[1].append(("table", "At the latest visit, and the change since the previous visit", summ))
        pages[1].append(("note", "Change beyond noise = larger than the MDC95 of the change from between-session "
                                 "error: the study's repeated baseline sessions when it has them, else published "
                                 "test-retest values (gait speed after stroke, chronic: 0.10 / 0.15 / 0.18 m/s for a "
                                 "baseline < 0.4 / 0.4-0.8 / > 0.8 m/s, Lewek & Sykes 2019, J Neurol Phys Ther "
                                 "43:122); '—' where no between-session error is known. Symmetry ratio = larger / smaller side (1 = symmetric, Patterson "
                                 "et al. 2010). Bands are orientation values, not cut-offs for this device."))
    if flags:
        pages[1].append(("heading", "Where data quality limits a number"))
        pages[1] += [("text", f"• {f}") for f in flags]

    g = d["gait"]
    if d["strides"] is None:
        pages[2].append(("note", Q.missing_hint("strides")))
    elif g is None or g.empty:
        pages[2].append(("note", "No strides were detected in this participant's lab sessions."))
    else:
        pages[2].append(("figure", FIG_CAPTIONS["gait"], fig_gait(g)))
        pages[2].append(("table", "Per session, both feet", gait_table(g)))
        pages[2].append(("note", "Mean stride speed: the mean of every kept stride's length / time (turns and "
                                 "walk ends included). The gait speed of the clinical measures (page 1 and below) "
                                 "is total distance / total time of the straight, steady strides (docs: "
                                 "clinical measures C7-C8), so the two differ, most for a variable gait."))
    cv = d["clinical"]
    if cv is None:
        pages[2].append(("note", "No clinical gait measures yet (the clinical stage runs after the gait stage): "
                                 + Q.RUN_HINT + "."))
    elif not cv.empty:
        pages[2].append(("table", "Clinical measures per lab visit (SR: symmetry ratio, larger / smaller side)",
                         clinical_visit_table(cv)))
        pages[2].append(("table", "Latest visit per side", clinical_side_table(cv)))
        pages[2].append(("figure", FIG_CAPTIONS["clinical"] + "; green: healthy range (Bohannon & Williams Andrews 2011; "
                                                     "Patterson et al. 2010)", fig_clinical(cv)))
        pages[2].append(("note", "Step time: contralateral contact to this foot's contact; single support: the "
                                 "other foot's swing. * Step length: ±0.1 on its ratio from the method. Definitions "
                                 "and references: docs/clinical_measures.md."))

    j = d["joints"]
    if j is None:
        pages[3].append(("note", Q.missing_hint("joint_cycles")))
    elif j.empty:
        pages[3].append(("note", "No joint-angle cycles for this participant."))
    else:
        fig, sid = fig_joints(j)
        pages[3].append(("figure", FIG_CAPTIONS["joints"] + f" ({sid})", fig))
        pages[3].append(("note", "Grey: approximate adult normative mean ± SD, sagittal plane (reports/normative.py); "
                                 "coloured bands: ± SD over the session's cycles."))
        rom = j.groupby([c for c in ("session_id", "joint", "side", "plane") if c in j])["mean_deg"].agg(np.ptp)
        rom = rom.rename("range of motion deg").round(1).reset_index()
        if "plane" in rom:
            rom = rom[rom["plane"].astype(str).str.lower().str.contains("sag|flex")] if \
                rom["plane"].astype(str).str.lower().str.contains("sag|flex").any() else rom
        pages[3].append(("table", "Range of motion of the mean cycle", rom.tail(12)))
    cal = d["calibration"]
    if cal is not None and not cal.empty:
        cols = [c for c in cal.columns if c in ("session_id", "placement", "status", "reasons", "qc_status", "reason")]
        pages[3].append(("table", "Calibration QC", cal[cols or list(cal.columns[:4])].tail(8)))

    daily = d["daily"]
    if daily is None:
        pages[4].append(("note", Q.missing_hint("activity_bouts")))
    elif daily.empty:
        pages[4].append(("note", "No free-living chest recording classified for this participant."))
    else:
        pages[4].append(("figure", FIG_CAPTIONS["activity"], fig_activity(daily)))
        pages[4].append(("table", "Per day (hours per class, steps, posture transitions)",
                         activity_table(daily).head(14)))
    walk = d["walking"]
    if walk is not None and not walk.empty:
        pages[4].append(("figure", FIG_CAPTIONS["walking"], fig_walking(walk)))
        pages[4].append(("table", "Walking bouts per day (chest sensor; consecutive walking and stairs joined)",
                         walking_table(walk).head(14)))

    pages[6] += _home_blocks(d)

    pages[5] += [("table", "Sessions", sessions_table(d).head(10)), ("table", "Data quality", quality_table(d))]
    if len(ses) > 10:
        pages[5].append(("note", f"… and {len(ses) - 10} more sessions (see the dashboard)."))
    if not d["issues"].empty:
        pages[5].append(("table", "Quality flags", d["issues"][["source", "session_id", "what", "message"]].head(6)
                         .rename(columns={"source": "Source", "session_id": "Session", "what": "What",
                                          "message": "Message"})))
    acc, pairs = d["accuracy"], d["stride_pairs"]
    if acc is None and pairs is None:
        pages[5].append(("note", Q.missing_hint("accuracy")))
    else:
        if acc is not None and not acc.empty:
            pages[5].append(("table", "Accuracy metrics of this participant's sessions", accuracy_table(acc).head(10)))
        elif pairs is None or pairs.empty:
            pages[5].append(("note", "No reference was recorded in this participant's sessions."))
        if pairs is not None and not pairs.empty:
            fig, bias, sd = fig_bland_altman(pairs)
            pages[5].append(("figure", FIG_CAPTIONS["bland_altman"] + f": bias {bias * 100:+.1f} cm, limits of agreement "
                                                         f"± {1.96 * sd * 100:.1f} cm, n = {len(pairs)}", fig))
    return pages


# ---- HTML -------------------------------------------------------------------------------------

_CSS = """body{font-family:DejaVu Sans,Helvetica,Arial,sans-serif;font-size:11px;color:#222;max-width:820px;margin:20px auto}
h1{font-size:18px;margin:0} h2{font-size:14px;border-bottom:1px solid #888;margin-top:28px}
h3{font-size:12px;margin:10px 0 4px} table{border-collapse:collapse;margin:4px 0 10px}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:left} th{background:#f0f0f0}
.note{color:#555;font-style:italic} figure{margin:6px 0} figcaption{font-weight:bold;margin-top:2px}
section{page-break-after:always} header{border-bottom:2px solid #333;padding-bottom:4px}
svg{max-width:100%;height:auto}"""


def _html_table(df: pd.DataFrame) -> str:
    head = "".join(f"<th>{html.escape(str(c))}</th>" for c in df.columns)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(_fmt(v))}</td>" for v in row) + "</tr>"
                   for row in df.itertuples(index=False))
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def render_html(d: dict, pages: dict, meta: dict) -> str:
    e = html.escape
    out = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>StrideLab report {e(d['participant_id'])}"
           f"</title><style>{_CSS}</style></head><body>",
           f"<header><h1>StrideLab participant report: {e(d['participant_id'])}</h1>"
           f"<div>Study {e(d['study'])} · generated {e(meta['generated'])} · snapshot {e(meta['snapshot'])}</div></header>"]
    for n, title in TITLES.items():
        out.append(f"<section id='page-{n}'><h2>{n}. {e(title)}</h2>")
        for b in pages[n]:
            if b[0] == "heading":
                out.append(f"<h3>{e(b[1])}</h3>")
            elif b[0] == "text":
                out.append(f"<p>{e(b[1])}</p>")
            elif b[0] == "note":
                out.append(f"<p class='note'>{e(b[1])}</p>")
            elif b[0] == "table":
                out.append(f"<h3>{e(b[1])}</h3>{_html_table(b[2])}")
            elif b[0] == "figure":
                out.append(f"<figure>{_svg(b[2])}<figcaption>{e(b[1])}</figcaption></figure>")
        out.append("</section>")
    out.append("</body></html>")
    return "\n".join(out)


# ---- PDF (matplotlib PdfPages: fixed A4 pages) -------------------------------------------------

def _wrap(text: str, width: int = 110) -> list[str]:
    import textwrap
    return textwrap.wrap(text, width) or [""]


#: characters of DejaVu Sans at 6.5 pt that fit across the table width (0.88 of A4)
_TABLE_CHARS = 150


def _header_chars(label: str) -> int:
    """Characters a column header needs when it may take two lines (split at a space)."""
    words = label.split()
    best = len(label)
    for i in range(1, len(words)):
        best = min(best, max(len(" ".join(words[:i])), len(" ".join(words[i:]))))
    return best


def _header_lines(label: str, width: int) -> str:
    """The header in at most two lines of ``width`` characters (cut only when even two lines are too short)."""
    import textwrap
    lines = textwrap.wrap(label, max(1, width)) or [""]
    if len(lines) > 2:
        lines = [lines[0], " ".join(lines[1:])]
    return "\n".join(x[:width] for x in lines)


def _col_widths(df: pd.DataFrame) -> tuple[list[int], float]:
    """Column widths in characters from the content (header included, 4..60 each) and the font size (6.5 pt,
    smaller down to 5 pt when the columns need more than the page width; a header may take two lines, cells
    are cut to their width)."""
    w = [max([_header_chars(str(c))] + [len(_fmt(v)) for v in df[c]]) for c in df.columns] if len(df.columns) else [4]
    w = [min(max(4, x + 2), 60) for x in w]
    size = 6.5
    if sum(w) > _TABLE_CHARS:
        size = max(5.0, 6.5 * _TABLE_CHARS / sum(w))
        room = int(_TABLE_CHARS * 6.5 / size)
        while sum(w) > room:                     # cut the widest column until the rest fits
            i = int(np.argmax(w))
            w[i] -= 1
    return w, size


#: top of a page's content (below the header and the page title) and the lowest line content may use
_CONTENT_TOP, _CONTENT_BOTTOM = 0.872, 0.08
_ROW_H = 0.016


def _table_chunks(b: tuple) -> list[tuple]:
    """A table block split into pieces that each fit on an empty page (continued pieces say so)."""
    df = b[2]
    per_page = max(1, int((_CONTENT_TOP - _CONTENT_BOTTOM - 0.05) / _ROW_H) - 3)
    if len(df) <= per_page:
        return [b]
    return [("table", b[1] + ("" if i == 0 else " (continued)"), df.iloc[i:i + per_page])
            for i in range(0, len(df), per_page)]


def _height(b: tuple) -> float:
    """Height a block needs on the page (figure units), as the drawing below spends it."""
    if b[0] == "heading":
        return 0.02
    if b[0] in ("text", "note"):
        return _ROW_H * len(_wrap(b[1])) + 0.006
    if b[0] == "table":
        widths, _ = _col_widths(b[2])
        two = any("\n" in _header_lines(str(c), w - 1) for c, w in zip(b[2].columns, widths))
        return 0.008 + _ROW_H * (max(len(b[2]), 1) + 1 + two) + 0.03
    w_in, h_in = b[2].get_size_inches()
    return h_in / A4[1] + 0.012 + 0.015 * len(_wrap(b[1], 120)) + 0.015


def render_pdf(d: dict, pages: dict, meta: dict, path: Path) -> None:
    """One A4 page per report page; a page whose blocks do not fit continues on the next sheet ("continued"):
    nothing is dropped (tables longer than a sheet are split by rows)."""
    plt = _plt()
    from matplotlib.backends.backend_pdf import PdfPages

    def start(n: int, title: str, cont: bool):
        page = plt.figure(figsize=A4)
        y = 0.965
        page.text(0.06, y, f"StrideLab participant report: {d['participant_id']}", fontsize=12, weight="bold")
        page.text(0.94, y, f"page {n} / {len(TITLES)}" + (" (continued)" if cont else ""), fontsize=8, ha="right")
        y -= 0.018
        page.text(0.06, y, f"Study {d['study']} · generated {meta['generated']} · snapshot {meta['snapshot']}",
                  fontsize=7, color="0.35")
        page.add_artist(plt.Line2D([0.06, 0.94], [y - 0.008, y - 0.008], color="0.2", lw=0.8,
                                   transform=page.transFigure))
        y -= 0.045
        page.text(0.06, y, f"{n}. {title}" + (" (continued)" if cont else ""), fontsize=11, weight="bold")
        return page, y - 0.03

    def finish(page, pdf):
        page.text(0.5, 0.025, f"{d['participant_id']} · pseudonymised data · StrideLab {meta['version']}",
                  fontsize=6.5, ha="center", color="0.4")
        pdf.savefig(page)
        plt.close(page)

    with PdfPages(path, metadata={"Title": f"StrideLab report {d['participant_id']}", "Author": "StrideLab",
                                  "Subject": f"study {d['study']}", "CreationDate": None}) as pdf:
        for n, title in TITLES.items():
            page, y = start(n, title, False)
            blocks = [c for b in pages[n] for c in (_table_chunks(b) if b[0] == "table" else [b])]
            for b in blocks:
                if y - _height(b) < _CONTENT_BOTTOM and y < _CONTENT_TOP - 1e-9:
                    finish(page, pdf)
                    page, y = start(n, title, True)
                if b[0] == "heading":
                    page.text(0.06, y, b[1], fontsize=9, weight="bold")
                    y -= 0.02
                elif b[0] in ("text", "note"):
                    for line in _wrap(b[1]):
                        page.text(0.06, y, line, fontsize=8, style="italic" if b[0] == "note" else "normal",
                                  color="0.3" if b[0] == "note" else "0.0")
                        y -= _ROW_H
                    y -= 0.006
                elif b[0] == "table":
                    df = b[2]
                    page.text(0.06, y, b[1], fontsize=9, weight="bold")
                    y -= 0.008
                    widths, size = _col_widths(df)
                    labels = [_header_lines(str(c), w - 1) for c, w in zip(df.columns, widths)]
                    two_line = any("\n" in x for x in labels)
                    rows = max(len(df), 1) + 1 + two_line
                    h = _ROW_H * rows
                    ax = page.add_axes([0.06, y - h, 0.88, h])
                    ax.axis("off")
                    cells = [[_fmt(v)[:w] for v, w in zip(r, widths)] for r in df.itertuples(index=False)] or \
                        [["—"] * len(df.columns)]
                    tb = ax.table(cellText=cells, colLabels=labels,
                                  loc="upper left", cellLoc="left", colLoc="left", bbox=[0, 0, 1, 1],
                                  colWidths=[w / sum(widths) for w in widths])
                    tb.auto_set_font_size(False)
                    tb.set_fontsize(size)
                    for (r, _c), cell in tb.get_celld().items():
                        cell.set_linewidth(0.3)
                        if r == 0:
                            cell.set_facecolor("#eeeeee")
                            if two_line:                  # the bbox scales the rows: the header gets two of them
                                cell.set_height(2 * cell.get_height())
                    y -= h + 0.03
                elif b[0] == "figure":
                    fig = b[2]
                    w_in, h_in = fig.get_size_inches()
                    h = min(h_in / A4[1], y - 0.1)
                    buf = io.BytesIO()
                    fig.savefig(buf, format="png", dpi=160, bbox_inches="tight")
                    buf.seek(0)
                    img = plt.imread(buf)
                    ih, iw = img.shape[:2]
                    w = min(0.88, h * A4[1] * iw / ih / A4[0])
                    ax = page.add_axes([0.06, y - h, w, h])
                    ax.imshow(img, interpolation="antialiased")
                    ax.axis("off")
                    ax.set_label(b[1])
                    y -= h + 0.012
                    for line in _wrap(b[1], 120):
                        page.text(0.06, y, line, fontsize=8, weight="bold")
                        y -= 0.015
                    y -= 0.015
            finish(page, pdf)


# ---- entry point ----------------------------------------------------------------------------------

_SAFE = re.compile(r"[^A-Za-z0-9._-]")


def _replace_durably(tmp: Path, final: Path) -> None:
    with open(tmp, "rb") as f:
        os.fsync(f.fileno())
    os.replace(tmp, final)


def build_report(warehouse_root: Path, participant_id: str, out_dir: Path, *, study: str | None = None) -> dict:
    """Write ``<out_dir>/<study>_<participant>.html`` and ``.pdf`` from the newest snapshot.

    Raises LookupError (participant or snapshot not found) or ValueError (ambiguous participant).
    """
    from importlib.metadata import PackageNotFoundError, version
    from warehouse.read import connect_snapshot, latest_snapshot
    root = Path(warehouse_root)
    snap = latest_snapshot(root)
    con = connect_snapshot(root)
    if con is None or snap is None:
        raise LookupError(f"the warehouse at {root} has no published snapshot yet; run `stridelab run` first")
    try:
        d = collect(con, root, participant_id, study)
    finally:
        con.close()
    try:
        ver = version("stridelab")
    except PackageNotFoundError:
        ver = "dev"
    meta = {"generated": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"), "snapshot": snap.name,
            "version": ver}
    plt = _plt()
    pages = _blocks(d)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = f"{_SAFE.sub('_', d['study'])}_{_SAFE.sub('_', participant_id)}"
    html_path, pdf_path = out_dir / f"{stem}.html", out_dir / f"{stem}.pdf"
    try:
        # each file appears whole or not at all: temporary name (.tmp-<pid>-, removed by the next run if
        # this process is killed), fsync, rename
        text = render_html(d, pages, meta)
        tmp = html_path.with_name(f".tmp-{os.getpid()}-{html_path.name}")
        tmp.write_text(text, encoding="utf-8")
        _replace_durably(tmp, html_path)
        tmp = pdf_path.with_name(f".tmp-{os.getpid()}-{pdf_path.name}")
        render_pdf(d, pages, meta, tmp)
        _replace_durably(tmp, pdf_path)
    finally:
        for blocks in pages.values():
            for b in blocks:
                if b[0] == "figure":
                    plt.close(b[2])
    return {"html": html_path, "pdf": pdf_path}
