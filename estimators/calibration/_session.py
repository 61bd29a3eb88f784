"""Calibration of all IMUs of a session from one calibration trial, with quality control.

Every leg IMU is calibrated independently (thesis ch. 3: errors do not propagate between IMUs);
the pelvis uses the spec 7.A7 proposal. QC statuses: ``pass``; ``warn`` (usable, below a
recommendation: short standing, movement axis tilted, noisy standing); ``fail`` (no calibration or
not trustworthy: trial missing or too short, no standing, fewer repetitions / steps than needed,
planarity below the minimum, sensor on the wrong segment or side). Joint angles computed with a
failed calibration carry that status (``stridelab.estimators.joints``).
"""
from __future__ import annotations

from dataclasses import replace
from typing import Mapping

import numpy as np
from scipy.ndimage import uniform_filter1d

from stridelab.estimators.calibration._s2s import (CalibrationError, calibrate_imu, pelvis_from_sway, pelvis_from_thighs,
                                         vertical_calibration)
from stridelab.estimators.calibration._types import (LEG_PLACEMENTS, LEG_SEGMENTS, SIDES, STATUS_ORDER, CalibrationParams,
                                           CalibrationWindows, ImuCalibration, SessionCalibration)
from stridelab.estimators.calibration._windows import (count_cycles, count_repetitions, detect_calibration_windows,
                                             smoothed_norm)
from stridelab.estimators.quaternion import quat_to_matrix

DEFAULT_PLACEMENTS = ("pelvis",) + LEG_PLACEMENTS
_NAN33 = np.full((3, 3), np.nan)


def _worst(statuses) -> str:
    s = "pass"
    for x in statuses:
        if STATUS_ORDER[x] > STATUS_ORDER[s]:
            s = x
    return s


def missing_calibration(placements=DEFAULT_PLACEMENTS, reason: str = "calibration trial missing",
                        params: CalibrationParams = CalibrationParams()) -> SessionCalibration:
    """A failed :class:`SessionCalibration` (no rotation) for every placement, with ``reason``."""
    imus = {p: ImuCalibration(p, _NAN33.copy(), "none", "fail", (reason,)) for p in placements}
    return SessionCalibration(imus=imus, windows=CalibrationWindows(), status="fail", reasons=(reason,), params=params)


def _mean_rotation(quat: np.ndarray) -> np.ndarray:
    q = np.asarray(quat, float)
    q = q * np.where((q @ q[0]) < 0, -1.0, 1.0)[:, None]
    m = q.mean(axis=0)
    return quat_to_matrix(m / np.linalg.norm(m))


def _gravity_qc(a: np.ndarray) -> tuple[float, float]:
    n = np.linalg.norm(a, axis=1)
    d = a / n[:, None]
    m = d.mean(axis=0)
    m /= np.linalg.norm(m)
    ang = np.degrees(np.arccos(np.clip(d @ m, -1, 1)))
    return float(n.mean()), float(np.sqrt(np.mean(ang ** 2)))


def _sl(w):
    return slice(int(w[0]), int(w[1]))


def calibrate_session(acc: Mapping[str, np.ndarray] | None, gyr: Mapping[str, np.ndarray] | None, *,
                      sampling_rate_hz: float, windows: CalibrationWindows | None = None,
                      params: CalibrationParams = CalibrationParams(),
                      mounts: Mapping[str, np.ndarray] | None = None,
                      quats: Mapping[str, np.ndarray] | None = None,
                      placements=DEFAULT_PLACEMENTS) -> SessionCalibration:
    """Calibrate the pelvis and leg IMUs of a session from its calibration trial.

    acc, gyr: placement -> (N, 3) native-sensor arrays (m/s², rad/s) on one time grid, or ``None``
        when the session has no calibration trial (→ a failed calibration, never an exception).
    windows: manual windows (study manifest); ``None`` → :func:`detect_calibration_windows`.
    mounts: placement -> ``P_mount`` (3×3 signed permutation, det +1) taking native axes to
        (x anterior, y up, z right); identity when absent (spec §0.2).
    quats: placement -> (N, 4) sensor → ENU orientation over the trial; enables the thigh-based
        pelvis heading (spec 7.A7), otherwise the pelvis heading comes from walking sway.
    placements: which placements are expected; missing ones are reported as failed.
    """
    if sampling_rate_hz <= 0:
        raise ValueError(f"sampling_rate_hz must be > 0, got {sampling_rate_hz}")
    if not acc or not gyr:
        return missing_calibration(placements, params=params)
    fs = float(sampling_rate_hz)
    mounts = mounts or {}
    P = {p: np.asarray(mounts.get(p, np.eye(3)), float) for p in gyr}
    for p, m in P.items():
        if m.shape != (3, 3) or abs(np.linalg.det(m) - 1.0) > 1e-6:
            raise ValueError(f"mounts[{p!r}] must be a 3×3 rotation (signed permutation, det +1), got {m.tolist()}")
    acc_S = {p: np.asarray(acc[p], float) @ P[p].T for p in gyr if p in acc}
    gyr_S = {p: np.asarray(gyr[p], float) @ P[p].T for p in gyr if p in acc}
    n = min(len(v) for v in gyr_S.values())
    session_reasons: list[str] = []
    if n < params.min_standing_s * fs + 2 * fs:
        return missing_calibration(placements, reason=f"calibration trial too short ({n / fs:.1f} s)", params=params)
    win = windows if windows is not None else detect_calibration_windows(acc_S, gyr_S, sampling_rate_hz=fs,
                                                                         params=params)
    if win.standing is None or (win.standing[1] - win.standing[0]) < params.min_standing_s * fs:
        r = f"no quiet standing of ≥ {params.min_standing_s:g} s in the calibration trial"
        out = missing_calibration(placements, reason=r, params=params)
        return SessionCalibration(out.imus, win, "fail", (r,), params=params)
    if not win.hip_fe and win.walking is None:
        session_reasons.append("no hip flexion/extension or straight walking found in the calibration trial")
    stand = _sl(win.standing)
    imus: dict[str, ImuCalibration] = {}

    # ---- steps: swings of the shanks (or thighs) in the walking window -------------------------
    walk_cycles: dict[str, int] = {}

    for p in placements:
        if p == "pelvis":
            continue
        seg, _, side = p.partition("_")
        if p not in gyr_S:
            imus[p] = ImuCalibration(p, _NAN33.copy(), "none", "fail", (f"no {p} sensor in the calibration trial",))
            continue
        if seg not in LEG_SEGMENTS:
            continue
        method = params.method
        if method == "auto":
            method = "hip_fe" if side in win.hip_fe else "walking"
            if method == "hip_fe" and win.walking is not None and float(np.mean(smoothed_norm(
                    gyr_S[p][_sl(win.hip_fe[side])], int(round(fs))))) < params.active_gyr_rad_s:
                method = "walking"          # the segment does not rotate in the hip FE (e.g. a foot kept level)
        mw = win.hip_fe.get(side) if method == "hip_fe" else win.walking
        a_st = acc_S[p][stand]
        g_norm, g_spread = _gravity_qc(a_st)
        y = a_st.mean(axis=0) / np.linalg.norm(a_st.mean(axis=0))
        xv = float(np.degrees(np.arccos(np.clip(abs(y[0]), 0, 1))))
        base = dict(placement=p, method=method, standing_s=(stand.stop - stand.start) / fs, gravity_m_s2=g_norm,
                    gravity_spread_deg=g_spread, x_vertical_deg=xv)
        if mw is None:
            what = f"hip flexion/extension of the {side} leg" if method == "hip_fe" else "straight walking"
            imus[p] = ImuCalibration(R_sensor_af=_NAN33.copy(), status="fail", reasons=(f"no {what} window",), **base)
            continue
        g_move = gyr_S[p][_sl(mw)]
        try:
            R_S_AF, R_S_VF, planarity, gamma = calibrate_imu(a_st, g_move)
        except CalibrationError as e:
            imus[p] = ImuCalibration(R_sensor_af=_NAN33.copy(), status="fail", reasons=(str(e),), **base)
            continue
        # agreement standing vs movement: tilt of the 3D principal rotation axis out of the horizontal plane
        gc = g_move - g_move.mean(axis=0)
        ev, evec = np.linalg.eigh(gc.T @ gc)
        axis_tilt = float(np.degrees(np.arcsin(np.clip(abs(evec[:, -1] @ R_S_VF[:, 1]), 0, 1))))
        z_S = R_S_AF[:, 2]
        # the detected window starts and ends where the smoothed angular rate crosses its threshold: the
        # gait initiation / termination steps (one leg moving) and a slow lift into the first hip FE
        # repetition fall partly outside it; count up to 1 s beyond it, never into another movement window
        others = [w for s_, w in win.hip_fe.items() if not (method == "hip_fe" and s_ == side)]
        if method == "hip_fe" and win.walking is not None:
            others.append(win.walking)
        lo = max([int(mw[0] - fs), 0] + [int(b) for a, b in others if b <= mw[0]])
        hi = min([int(mw[1] + fs), len(gyr_S[p])] + [int(a) for a, b in others if a >= mw[1]])
        g_count = gyr_S[p][lo:hi]
        if method == "hip_fe":
            cycles = count_repetitions(g_count, z_S, sampling_rate_hz=fs)
        else:
            cycles = count_cycles(g_count, z_S, sampling_rate_hz=fs, prominence_rad_s=params.peak_prominence_rad_s,
                                  min_peak_fraction=params.min_peak_fraction)
        if method == "walking":
            walk_cycles[p] = cycles
        cal = ImuCalibration(R_sensor_af=P[p].T @ R_S_AF, status="pass", planarity=planarity, gamma_deg=gamma,
                             n_cycles=cycles, axis_tilt_deg=axis_tilt, **base)
        if base["standing_s"] < params.target_standing_s:
            cal = cal.with_status("warn", f"standing {base['standing_s']:.1f} s < recommended "
                                          f"{params.target_standing_s:g} s")
        if abs(g_norm - params.gravity_m_s2) > params.stand_acc_m_s2:
            cal = cal.with_status("warn", f"standing |a| = {g_norm:.2f} m/s² differs from g")
        if g_spread > params.max_gravity_spread_deg:
            cal = cal.with_status("warn", f"gravity direction spread {g_spread:.1f}° during standing (not still)")
        if planarity < params.min_planarity:
            cal = cal.with_status("fail", f"explained variance of the principal axis {planarity:.2f} < "
                                          f"{params.min_planarity:g} (movement not single-axis)")
        if axis_tilt > params.max_axis_tilt_deg:
            cal = cal.with_status("warn", f"movement axis {axis_tilt:.0f}° out of the standing horizontal plane")
        if method == "hip_fe" and seg == "thigh":
            ax = float(np.mean(acc_S[p][_sl(mw)] @ R_S_AF[:, 0]))
            if ax < 0:
                cal = cal.with_status("fail", "thigh tilts backward during hip flexion: sensor x points posterior "
                                              "(wrong mounting permutation or left/right swapped)")
        imus[p] = cal

    # repetitions are a property of the hip movement: counted on the thigh, applied to its leg
    for side in SIDES:
        t = imus.get(f"thigh_{side}")
        reps = t.n_cycles if (t is not None and t.method == "hip_fe" and t.valid) else None
        for seg in LEG_SEGMENTS:
            p = f"{seg}_{side}"
            c = imus.get(p)
            if c is None or c.method != "hip_fe" or not c.valid:
                continue
            if reps is None:
                reps = c.n_cycles
            c = replace(c, n_cycles=reps)
            if reps < params.min_fe_repetitions:
                c = c.with_status("fail", f"{reps} hip flexion/extension repetitions < "
                                          f"{params.min_fe_repetitions} required")
            imus[p] = c
    n_steps = 0
    if win.walking is not None:
        for seg in ("shank", "thigh", "foot"):
            if all(f"{seg}_{s}" in walk_cycles for s in SIDES):
                n_steps = sum(walk_cycles[f"{seg}_{s}"] for s in SIDES)
                break
        for p, c in imus.items():
            if c.method == "walking" and c.valid and n_steps < params.min_walking_steps:
                imus[p] = c.with_status("fail", f"{n_steps} straight-walking steps < {params.min_walking_steps} required")

    # ---- pelvis -------------------------------------------------------------------------------------
    if "pelvis" in placements:
        imus["pelvis"] = _calibrate_pelvis(acc_S, gyr_S, P, win, imus, quats, fs, params)

    # ---- wrong segment / side from motion ---------------------------------------------------------
    for p, reason in motion_plausibility(gyr_S, win, sampling_rate_hz=fs, params=params, acc_S=acc_S).items():
        if p in imus:
            imus[p] = imus[p].with_status("fail", reason)
        session_reasons.append(f"{p}: {reason}")

    status = _worst([c.status for c in imus.values()] + (["fail"] if session_reasons and any(
        "no hip" in r for r in session_reasons) else []))
    return SessionCalibration(imus=imus, windows=win, status=status, reasons=tuple(session_reasons),
                              n_steps=n_steps, params=params)


def _calibrate_pelvis(acc_S, gyr_S, P, win, imus, quats, fs, params) -> ImuCalibration:
    p = "pelvis"
    if p not in gyr_S:
        return ImuCalibration(p, _NAN33.copy(), "none", "fail", ("no pelvis sensor in the calibration trial",))
    stand = _sl(win.standing)
    a_st = acc_S[p][stand]
    g_norm, g_spread = _gravity_qc(a_st)
    base = dict(placement=p, standing_s=(stand.stop - stand.start) / fs, gravity_m_s2=g_norm,
                gravity_spread_deg=g_spread)
    thighs = [f"thigh_{s}" for s in SIDES]
    use_thighs = (params.pelvis_method in ("auto", "thighs") and quats is not None and p in quats
                  and all(t in quats and t in imus and imus[t].valid for t in thighs))
    try:
        if use_thighs:
            R_G_S = _mean_rotation(np.asarray(quats[p])[stand]) @ P[p].T          # G <- S (after mount)
            R_G_AF = [_mean_rotation(np.asarray(quats[t])[stand]) @ imus[t].R_sensor_af for t in thighs]
            R_S_AF, method = pelvis_from_thighs(a_st, R_G_S, R_G_AF), "pelvis_thighs"
        elif params.pelvis_method in ("auto", "sway") and win.walking is not None:
            R_S_AF = pelvis_from_sway(a_st, acc_S[p][_sl(win.walking)], sampling_rate_hz=fs)
            method = "pelvis_sway"
        else:
            return ImuCalibration(R_sensor_af=_NAN33.copy(), method="none", status="fail",
                                  reasons=("pelvis heading needs thigh orientations or a walking window",), **base)
    except CalibrationError as e:
        return ImuCalibration(R_sensor_af=_NAN33.copy(), method="none", status="fail", reasons=(str(e),), **base)
    R_S_VF = vertical_calibration(a_st)
    cal = ImuCalibration(R_sensor_af=P[p].T @ R_S_AF, method=method, status="pass",
                         x_vertical_deg=float(np.degrees(np.arccos(np.clip(abs(R_S_VF[0, 1]), 0, 1)))), **base)
    if base["standing_s"] < params.target_standing_s:
        cal = cal.with_status("warn", f"standing {base['standing_s']:.1f} s < recommended {params.target_standing_s:g} s")
    if g_spread > params.max_gravity_spread_deg:
        cal = cal.with_status("warn", f"gravity direction spread {g_spread:.1f}° during standing (not still)")
    return cal


def motion_plausibility(gyr_S: Mapping[str, np.ndarray], win: CalibrationWindows, *, sampling_rate_hz: float,
                        params: CalibrationParams = CalibrationParams(),
                        acc_S: Mapping[str, np.ndarray] | None = None) -> dict[str, str]:
    """placement -> reason for leg / pelvis sensors whose motion does not fit their label.

    * hip FE of one leg: that leg's thigh, shank and foot move, the other leg stands still;
    * walking: a leg sensor moves in phase with the segments of its own leg (gyro-norm envelopes
      correlate more with the ipsilateral than with the contralateral segments), the pelvis rotates
      less than either thigh, and the thigh moves less than the shank: lower angular rate (95th
      percentile of |ω|) and, when ``acc_S`` is given, lower dynamic acceleration (95th percentile of
      |a − 1-s moving mean|; the shank sensor sits two to three times farther from the hip). Both
      must point the other way to flag a thigh/shank swap: in stiff-knee (e.g. hemiparetic) gait the
      paretic thigh may rotate faster than its shank, but its sensor still accelerates less.
    """
    fs = sampling_rate_hz
    bad: dict[str, str] = {}
    n1 = int(round(1.0 * fs))
    for side, w in win.hip_fe.items():
        other = "left" if side == "right" else "right"
        for s, expect in ((side, True), (other, False)):
            for seg in LEG_SEGMENTS:
                p = f"{seg}_{s}"
                if p not in gyr_S:
                    continue
                act = float(np.mean(smoothed_norm(gyr_S[p][_sl(w)], n1))) > params.active_gyr_rad_s
                if act and not expect:
                    bad[p] = f"moves during the {side} leg's hip flexion/extension: placed on the {side} leg?"
                elif expect and not act and seg == "thigh":
                    bad[p] = f"still during the {side} leg's hip flexion/extension: not on the {side} thigh?"
    if win.walking is not None:
        sl = _sl(win.walking)
        env = {p: smoothed_norm(gyr_S[p][sl], int(round(0.1 * fs))) for p in gyr_S}
        env = {p: v - v.mean() for p, v in env.items()}

        def corr(a, b):
            d = np.sqrt(np.sum(env[a] ** 2) * np.sum(env[b] ** 2))
            return float(np.sum(env[a] * env[b]) / d) if d > 0 else 0.0

        for side in SIDES:
            other = "left" if side == "right" else "right"
            for seg in LEG_SEGMENTS:
                p = f"{seg}_{side}"
                if p not in env or p in bad:
                    continue
                same = [corr(p, f"{s2}_{side}") for s2 in LEG_SEGMENTS if s2 != seg and f"{s2}_{side}" in env]
                opp = [corr(p, f"{s2}_{other}") for s2 in LEG_SEGMENTS if s2 != seg and f"{s2}_{other}" in env]
                if same and opp and np.mean(opp) > np.mean(same) + params.swap_margin:
                    bad[p] = f"moves in phase with the {other} leg while walking: left/right swapped?"
        amp = {p: float(np.percentile(np.linalg.norm(np.nan_to_num(gyr_S[p][sl]), axis=1), 95)) for p in gyr_S}
        dyn = {}
        if acc_S is not None:
            for p in acc_S:
                a = np.nan_to_num(np.asarray(acc_S[p], float)[sl])
                if a.shape[0]:
                    d = a - uniform_filter1d(a, size=max(int(round(fs)), 1), axis=0, mode="nearest")
                    dyn[p] = float(np.percentile(np.linalg.norm(d, axis=1), 95))
        for side in SIDES:
            t, s = f"thigh_{side}", f"shank_{side}"
            acc_says = t not in dyn or s not in dyn or dyn[t] > dyn[s]
            if t in amp and s in amp and amp[t] > amp[s] * 1.1 and acc_says and t not in bad and s not in bad:
                bad[t] = f"moves more than {s} while walking: thigh and shank sensors swapped?"
                bad[s] = f"moves less than {t} while walking: thigh and shank sensors swapped?"
        if "pelvis" in amp:
            th = [amp[f"thigh_{s}"] for s in SIDES if f"thigh_{s}" in amp]
            if th and amp["pelvis"] > min(th):
                bad["pelvis"] = "moves more than a thigh while walking: not on the pelvis?"
    return bad
