"""Plotly figures of the dashboard (pure functions: DataFrame in, figure out)."""
from __future__ import annotations

import numpy as np
import pandas as pd
import plotly.express as px
import plotly.graph_objects as go

from stridelab.reports.normative import is_sagittal, normative_band
from stridelab.warehouse.queries import ACTIVITY_CLASSES, ACTIVITY_COLORS, GAIT_PARAMS

KIND_COLORS = {"lab": "#4c78a8", "free_living": "#f58518", "calibration": "#54a24b"}


def _layout(fig: go.Figure, height: int = 320, **kw) -> go.Figure:
    fig.update_layout(height=height, margin=dict(l=10, r=10, t=40, b=10), **kw)
    return fig


def sessions_timeline(sessions: pd.DataFrame) -> go.Figure:
    df = sessions.copy()
    df["label"] = df["session_id"] + " · " + df["kind"]
    fig = px.timeline(df, x_start="start", x_end="end", y="kind", color="kind", hover_name="session_id",
                      hover_data={"protocol": True, "recordings": True, "trials": True, "kind": False},
                      color_discrete_map=KIND_COLORS, title="Sessions")
    # sessions of minutes are invisible on a scale of weeks: mark each start as well
    fig.add_trace(go.Scatter(x=df["start"], y=df["kind"], mode="markers", marker=dict(symbol="line-ns-open", size=14,
                             color="#333"), hovertext=df["label"], hoverinfo="text", showlegend=False))
    return _layout(fig, 240)


def gait_trend(summary: pd.DataFrame, params: list[str]) -> go.Figure:
    from plotly.subplots import make_subplots
    params = [p for p in params if p in summary]
    fig = make_subplots(rows=1, cols=max(1, len(params)), subplot_titles=[GAIT_PARAMS.get(p, p) for p in params])
    for i, p in enumerate(params, start=1):
        fig.add_trace(go.Scatter(x=summary["date"], y=summary[p], mode="lines+markers", name=GAIT_PARAMS.get(p, p),
                                 hovertext=summary["session_id"], showlegend=False), row=1, col=i)
    return _layout(fig, 300, title="Gait parameters across sessions (the gait stage's summary, both feet)")


def joint_cycles(df: pd.DataFrame, joint: str, plane: str | None) -> go.Figure:
    fig = go.Figure()
    band = normative_band(joint) if is_sagittal(plane) else None
    if band is not None:
        pct, m, sd = band
        fig.add_trace(go.Scatter(x=np.concatenate([pct, pct[::-1]]), y=np.concatenate([m + sd, (m - sd)[::-1]]),
                                 fill="toself", fillcolor="rgba(150,150,150,0.25)", line=dict(width=0),
                                 name="normative ± SD (approx.)", hoverinfo="skip"))
    palette = px.colors.qualitative.D3
    for i, ((sid, side), g) in enumerate(df.groupby(["session_id", "side"] if "side" in df else ["session_id",
                                                     df["joint"]], sort=False)):
        g = g.sort_values("pct")
        c = palette[i % len(palette)]
        if "sd_deg" in g and g["sd_deg"].notna().any():
            fig.add_trace(go.Scatter(x=np.concatenate([g["pct"], g["pct"][::-1]]),
                                     y=np.concatenate([g["mean_deg"] + g["sd_deg"], (g["mean_deg"] - g["sd_deg"])[::-1]]),
                                     fill="toself", opacity=0.2, line=dict(width=0), fillcolor=c, showlegend=False,
                                     hoverinfo="skip"))
        fig.add_trace(go.Scatter(x=g["pct"], y=g["mean_deg"], mode="lines", line=dict(color=c),
                                 name=f"{sid} {side}"))
    return _layout(fig, 300, title=f"{joint} {plane or ''} (deg) over the gait cycle",
                   xaxis_title="gait cycle (%)", yaxis_title="angle (deg)")


def foot_trajectory(df: pd.DataFrame) -> go.Figure:
    fig = px.line(df, x="x", y="y", color="placement", title="Foot trajectory (top view, m)")
    fig.update_yaxes(scaleanchor="x", scaleratio=1)
    return _layout(fig, 320)


def error_distribution(metrics: pd.DataFrame, metric: str) -> go.Figure:
    d = metrics[metrics["metric"] == metric]
    x = "estimator" if "estimator" in d and d["estimator"].notna().any() else "stage"
    color = "placement" if "placement" in d and d["placement"].nunique() > 1 else None
    unit = d["unit"].dropna().iloc[0] if "unit" in d and d["unit"].notna().any() else ""
    fig = px.box(d, x=x, y="value", color=color, points="all", title=f"{metric} {f'({unit})' if unit else ''}")
    return _layout(fig, 320)


def bland_altman(pairs: pd.DataFrame, title: str, unit: str = "") -> go.Figure:
    est, ref = pairs["estimate"].to_numpy(float), pairs["reference"].to_numpy(float)
    mean, diff = (est + ref) / 2, est - ref
    bias, sd = float(np.nanmean(diff)), float(np.nanstd(diff, ddof=1)) if len(diff) > 1 else 0.0
    fig = go.Figure(go.Scatter(x=mean, y=diff, mode="markers", marker=dict(size=6, opacity=0.6), name="strides"))
    for y, name, dash in ((bias, f"bias {bias:+.3g}", "solid"), (bias + 1.96 * sd, f"+1.96 SD {bias + 1.96 * sd:+.3g}", "dash"),
                          (bias - 1.96 * sd, f"−1.96 SD {bias - 1.96 * sd:+.3g}", "dash")):
        fig.add_hline(y=y, line_dash=dash, annotation_text=name, annotation_position="top right")
    return _layout(fig, 320, title=f"Bland–Altman: {title}", xaxis_title=f"mean of IMU and reference {unit}",
                   yaxis_title=f"IMU − reference {unit}")


def timing_histogram(errors_ms: pd.DataFrame) -> go.Figure:
    fig = px.histogram(errors_ms, x="error_ms", color="quantity", barmode="overlay", nbins=40, opacity=0.7,
                       title="Event timing error (detected − reference, ms)")
    return _layout(fig, 300)


def confusion(conf: pd.DataFrame) -> go.Figure:
    labels = [c for c in ACTIVITY_CLASSES if c in set(conf["reference"]) | set(conf["predicted"])]
    labels += sorted((set(conf["reference"]) | set(conf["predicted"])) - set(labels))
    m = conf.pivot_table(index="reference", columns="predicted", values="seconds", aggfunc="sum", fill_value=0.0)
    m = m.reindex(index=labels, columns=labels, fill_value=0.0)
    pct = 100 * m.div(m.sum(axis=1).replace(0, np.nan), axis=0)
    fig = px.imshow(pct.round(1), text_auto=True, color_continuous_scale="Blues", zmin=0, zmax=100,
                    labels=dict(x="classified", y="reference", color="% of reference time"),
                    title="Posture / activity confusion (% of reference time per row)")
    return _layout(fig, 380)


def activity_timeline(bouts: pd.DataFrame) -> go.Figure:
    fig = px.timeline(bouts, x_start="start_local", x_end="end_local", y="class", color="class",
                      category_orders={"class": list(ACTIVITY_CLASSES)}, color_discrete_map=ACTIVITY_COLORS,
                      title="Posture and activity timeline (local time)")
    fig.update_yaxes(autorange="reversed")
    return _layout(fig, 300, showlegend=False)


def daily_totals(daily: pd.DataFrame) -> go.Figure:
    d = daily[daily["class"] != "_transitions"]
    fig = px.bar(d, x="day", y="hours", color="class", category_orders={"class": list(ACTIVITY_CLASSES)},
                 color_discrete_map=ACTIVITY_COLORS, title="Time per class and day (h)")
    return _layout(fig, 320)


def daily_steps(daily: pd.DataFrame) -> go.Figure:
    d = daily[(daily["class"] != "_transitions") & daily["steps"].notna() & (daily["steps"] > 0)]
    fig = px.bar(d, x="day", y="steps", color="class", color_discrete_map=ACTIVITY_COLORS,
                 title="Steps per walking modality and day")
    return _layout(fig, 300)


def weekly_trend(daily: pd.DataFrame) -> go.Figure:
    d = daily[daily["class"] != "_transitions"].copy()
    d["week"] = pd.to_datetime(d["day"]).dt.to_period("W").dt.start_time
    w = d.groupby(["week", "class"], as_index=False)["hours"].sum()
    days = d.groupby("week")["day"].nunique()
    w["hours_per_day"] = w["hours"] / w["week"].map(days)
    fig = px.line(w, x="week", y="hours_per_day", color="class", markers=True, color_discrete_map=ACTIVITY_COLORS,
                  title="Weekly trend (mean hours per day)")
    return _layout(fig, 300)


def run_durations(runs: pd.DataFrame) -> go.Figure:
    runs = runs.sort_values("started_at").assign(started=lambda d: d["started_at"].dt.strftime("%Y-%m-%d %H:%M:%S"))
    fig = px.bar(runs, x="started", y="duration_s", color="status",
                 color_discrete_map={"ok": "#54a24b", "failed": "#e45756", "interrupted": "#bab0ac",
                                     "running": "#4c78a8"}, hover_name="run_id", title="Run durations (s)")
    fig.update_xaxes(type="category", title="started (UTC)")
    return _layout(fig, 260)


def programme_change(change: pd.DataFrame, name: str) -> go.Figure:
    """Change from the first to the latest visit per participant, with ± its MDC95 (between-session error; no bar
    where none is known)."""
    c = change.dropna(subset=["change"]).sort_values("participant_id")
    colors = np.where(c["beyond_mdc"], "#e45756", "#4c78a8")
    fig = go.Figure(go.Scatter(
        x=c["change"], y=c["participant_id"], mode="markers", marker=dict(size=11, color=colors),
        error_x=dict(type="data", array=c["mdc95"].fillna(0.0), visible=True, color="#888"),
        hovertext=[f"{p}: {a:.3g} → {b:.3g} (change {d:+.3g}, MDC95 {m:.3g})" for p, a, b, d, m in
                   zip(c["participant_id"], c["baseline"], c["latest"], c["change"], c["mdc95"])],
        hoverinfo="text", showlegend=False))
    fig.add_vline(x=0, line=dict(color="#333", width=1))
    fig.update_xaxes(title=f"change in {name} (latest − first visit)")
    return _layout(fig, max(220, 60 + 40 * len(c)),
                   title=f"{name}: change between visits (red: beyond the between-session MDC95; bars: ± MDC95)")


def clinical_trend(series: pd.DataFrame, name: str, band: tuple | None = None) -> go.Figure:
    """One measure across a participant's visits, ± 1.96 SEM (within-session uncertainty); optional normative band
    ``(low, high, label)``."""
    s = series.sort_values("visit")
    fig = go.Figure(go.Scatter(x=s["date"], y=s["value"], mode="lines+markers",
                               error_y=dict(type="data", array=1.96 * s["sem"], visible=True),
                               hovertext=s["session_id"] + " · visit " + s["visit"].astype(str), showlegend=False))
    if band is not None:
        lo, hi, label = band
        fig.add_hrect(y0=lo if lo is not None else s["value"].min(), y1=hi if hi is not None else s["value"].max(),
                      fillcolor="#54a24b", opacity=0.12, line_width=0, annotation_text=label,
                      annotation_position="top left")
    return _layout(fig, 260, title=name)


def walking_bout_durations(bouts: pd.DataFrame) -> go.Figure:
    """Histogram of free-living walking-bout durations (log-spaced bins), per chest day."""
    b = bouts[bouts["seconds"] > 0]
    edges = np.geomspace(max(1.0, float(b["seconds"].min())), float(b["seconds"].max()) * 1.01, 16) if len(b) else [1, 2]
    fig = go.Figure()
    for day, g in b.groupby("day"):
        h, _ = np.histogram(g["seconds"], bins=edges)
        fig.add_trace(go.Bar(x=[f"{a:.0f}-{c:.0f}" for a, c in zip(edges[:-1], edges[1:])], y=h, name=str(day)))
    fig.update_xaxes(title="bout duration (s)")
    fig.update_yaxes(title="bouts")
    return _layout(fig, 300, title="Walking bouts: duration distribution", barmode="group")


def walking_by_hour(bouts: pd.DataFrame) -> go.Figure:
    """Walking minutes per local hour of the day, per chest day."""
    fig = go.Figure()
    for day, g in bouts.groupby("day"):
        m = g.groupby("hour")["seconds"].sum().reindex(range(24), fill_value=0) / 60
        fig.add_trace(go.Bar(x=list(range(24)), y=m.to_numpy(), name=str(day)))
    fig.update_xaxes(title="hour of the day (local)", dtick=2)
    fig.update_yaxes(title="walking minutes")
    return _layout(fig, 280, title="Walking by time of day", barmode="group")
