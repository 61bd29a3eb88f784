"""The report's figures, drawn once with matplotlib: inline SVG in the HTML, 160 dpi PNG images in the PDF."""
from __future__ import annotations

import io

import numpy as np
import pandas as pd

from stridelab.reports.normative import CLINICAL_BANDS, normative_band
from stridelab.warehouse import queries as Q

def pyplot():
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    plt.rcParams.update({"pdf.fonttype": 42, "svg.fonttype": "none", "font.size": 8, "axes.titlesize": 9,
                         "figure.dpi": 100, "svg.hashsalt": "stridelab", "axes.spines.top": False,
                         "axes.spines.right": False})
    return plt


def fig_gait(gait: pd.DataFrame):
    plt = pyplot()
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
    plt = pyplot()
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
            gs = gs.sort_values("pct")
            c = colors.get(str(side), "#333333")
            ax.plot(gs["pct"], gs["mean_deg"], color=c, lw=1.3, label=str(side) or "mean")
            if "sd_deg" in gs:
                ax.fill_between(gs["pct"], gs["mean_deg"] - gs["sd_deg"], gs["mean_deg"] + gs["sd_deg"],
                                color=c, alpha=0.15, lw=0)
        ax.set_title(f"{name} (deg)")
        ax.set_xlabel("gait cycle (%)")
    axes[0][0].legend(fontsize=6, frameon=False)
    fig.tight_layout()
    return fig, sid


def fig_activity(daily: pd.DataFrame):
    plt = pyplot()
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
    plt = pyplot()
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
    plt = pyplot()
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
    plt = pyplot()
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
    plt = pyplot()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(7.4, 2.4))
    x = np.arange(len(cap))
    for k, (col, lab) in enumerate((("lab_speed_m_s", "lab gait speed"), ("home_speed_median_m_s", "home median"),
                                    ("home_speed_p95_m_s", "home 95th centile"))):
        a1.bar(x + (k - 1) * 0.27, cap[col].astype(float).fillna(0).to_numpy(), width=0.27, label=lab)
    a1.set_xticks(x, [f"visit {v}" for v in cap["visit"]])
    a1.set_ylabel("m/s")
    top = np.nanmax(cap[["lab_speed_m_s", "home_speed_median_m_s", "home_speed_p95_m_s"]].astype(float).to_numpy(),
                    initial=0.0)
    a1.set_ylim(0, max(top, 0.1) * 1.3)                    # headroom: the legend sits above the bars, not on them
    a1.legend(fontsize=6, frameon=False, loc="upper center", ncol=3)
    if len(days):
        a2.plot(days["date"], days["speed_median_m_s"], "o-", label="median")
        a2.plot(days["date"], days["speed_p95_m_s"], "s--", label="95th centile")
        a2.tick_params(axis="x", labelrotation=30, labelsize=6)
        a2.legend(fontsize=6, frameon=False)
    a2.set_ylabel("walking speed (m/s)")
    fig.tight_layout()
    return fig


def svg(fig) -> str:
    buf = io.StringIO()
    fig.savefig(buf, format="svg", bbox_inches="tight", metadata={"Date": None})
    s = buf.getvalue()
    return s[s.index("<svg"):]


def png(fig, dpi: int = 160) -> bytes:
    """The figure as a PNG image (``dpi`` dots per inch of its size, cropped to its drawn area)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    return buf.getvalue()
