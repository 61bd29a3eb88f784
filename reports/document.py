"""The report's content as a document model: page number -> blocks, the same for the HTML and the PDF.

Layout (always the same six pages in this order, so a study coordinator can file them; a section without data
says why and what to run; a page whose content does not fit on one A4 sheet continues on the next):

1. summary for the clinician: speed, asymmetry ratios, steps/day, upright time at the latest visit, the change
   since the previous visit against its minimal detectable change, normative bands with their source, and the
   flags where data quality limits a number
2. gait: parameters across sessions (Figure 1), clinical measures per visit and per side (paretic /
   non-paretic ratio, symmetry ratio, variability) and their trend with uncertainty (Figure 2)
3. joint-angle cycles of the newest lab session against a normative band (Figure 3)
4. daily activity: time per class per day (Figure 4), a daily table, and free-living walking bouts
   (durations, time of day: Figure 5; steps, cadence within bouts, longest bout)
5. sessions, data quality, and accuracy against the reference where one was recorded (Figure 6)
6. walking at home (trunk sensor): lab capacity beside home performance (Figure 7)

A block is ``("text", str)`` | ``("note", str)`` | ``("heading", str)`` | ``("table", title, DataFrame)`` |
``("figure", caption, matplotlib Figure)``. Tables carry every row: the renderers paginate.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from stridelab.reports import figures as F
from stridelab.reports.tables import (accuracy_table, activity_table, clinical_side_table, clinical_visit_table,
                            gait_table, home_days_table, quality_table, sessions_table, summary_table,
                            walking_table)
from stridelab.warehouse import queries as Q

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

def home_blocks(d: dict) -> list[tuple]:
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
        out.append(("figure", FIG_CAPTIONS["home"], F.fig_home(cap, days)))
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


def blocks(d: dict) -> dict[int, list[tuple]]:
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
        pages[2].append(("figure", FIG_CAPTIONS["gait"], F.fig_gait(g)))
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
                                                     "Patterson et al. 2010)", F.fig_clinical(cv)))
        pages[2].append(("note", "Step time: contralateral contact to this foot's contact; single support: the "
                                 "other foot's swing. * Step length: ±0.1 on its ratio from the method. Definitions "
                                 "and references: docs/clinical_measures.md."))

    j = d["joints"]
    if j is None:
        pages[3].append(("note", Q.missing_hint("joint_cycles")))
    elif j.empty:
        pages[3].append(("note", "No joint-angle cycles for this participant."))
    else:
        fig, sid = F.fig_joints(j)
        pages[3].append(("figure", FIG_CAPTIONS["joints"] + f" ({sid})", fig))
        pages[3].append(("note", "Grey: approximate adult normative mean ± SD, sagittal plane (reports/normative.py); "
                                 "coloured bands: ± SD over the session's cycles."))
        rom = j.groupby([c for c in ("session_id", "joint", "side", "plane") if c in j])["mean_deg"].agg(np.ptp)
        rom = rom.rename("range of motion deg").round(1).reset_index()
        if "plane" in rom:
            rom = rom[rom["plane"].astype(str).str.lower().str.contains("sag|flex")] if \
                rom["plane"].astype(str).str.lower().str.contains("sag|flex").any() else rom
        pages[3].append(("table", "Range of motion of the mean cycle", rom))
    cal = d["calibration"]
    if cal is not None and not cal.empty:
        cols = [c for c in cal.columns if c in ("session_id", "placement", "status", "reasons", "qc_status", "reason")]
        pages[3].append(("table", "Calibration QC", cal[cols or list(cal.columns[:4])]))

    daily = d["daily"]
    if daily is None:
        pages[4].append(("note", Q.missing_hint("activity_bouts")))
    elif daily.empty:
        pages[4].append(("note", "No free-living chest recording classified for this participant."))
    else:
        pages[4].append(("figure", FIG_CAPTIONS["activity"], F.fig_activity(daily)))
        pages[4].append(("table", "Per day (hours per class, steps, posture transitions)",
                         activity_table(daily)))
    walk = d["walking"]
    if walk is not None and not walk.empty:
        pages[4].append(("figure", FIG_CAPTIONS["walking"], F.fig_walking(walk)))
        pages[4].append(("table", "Walking bouts per day (chest sensor; consecutive walking and stairs joined)",
                         walking_table(walk)))

    pages[6] += home_blocks(d)

    pages[5] += [("table", "Sessions", sessions_table(d)), ("table", "Data quality", quality_table(d))]
    if not d["issues"].empty:
        pages[5].append(("table", "Quality flags", d["issues"][["source", "session_id", "what", "message"]]
                         .rename(columns={"source": "Source", "session_id": "Session", "what": "What",
                                          "message": "Message"})))
    acc, pairs = d["accuracy"], d["stride_pairs"]
    if acc is None and pairs is None:
        pages[5].append(("note", Q.missing_hint("accuracy")))
    else:
        if acc is not None and not acc.empty:
            pages[5].append(("table", "Accuracy metrics of this participant's sessions", accuracy_table(acc)))
        elif pairs is None or pairs.empty:
            pages[5].append(("note", "No reference was recorded in this participant's sessions."))
        if pairs is not None and not pairs.empty:
            fig, bias, sd = F.fig_bland_altman(pairs)
            pages[5].append(("figure", FIG_CAPTIONS["bland_altman"] + f": bias {bias * 100:+.1f} cm, limits of agreement "
                                                         f"± {1.96 * sd * 100:.1f} cm, n = {len(pairs)}", fig))
    return pages
