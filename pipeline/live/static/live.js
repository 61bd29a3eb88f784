// StrideLab live: WebSocket client shared by the therapist and patient pages. No external libraries.
"use strict";
const JOINTS = ["hip_left", "hip_right", "knee_left", "knee_right", "ankle_left", "ankle_right"];
const COLORS = {left: "#1f6fd1", right: "#d1401f"};
const L = {
  config: {}, frames: [], events: [], seen: new Set(), pendingIC: [], speed: null, speedOverride: 0, bandInfo: null, metrics: {}, summary: {},
  strideCurves: {left: [], right: []}, current: {left: null, right: null},
  stats: {frames: 0, events: 0, drawn: 0, fps: 0, cueOn: false, cueCount: 0, connected: false},
};
window.liveStats = L.stats;

const MEASURES = {
  stance_asymmetry_pct: {label: "Stance asymmetry", unit: "%", get: m => m.stance_asymmetry_pct},
  step_time_asymmetry_pct: {label: "Step-time asymmetry", unit: "%", get: m => m.step_time_asymmetry_pct},
  knee_peak_left: {label: "Peak knee flexion, left", unit: "°", get: () => peakOfLast("left", 2)},
  knee_peak_right: {label: "Peak knee flexion, right", unit: "°", get: () => peakOfLast("right", 2)},
};

function peakOfLast(side, col) {
  const c = L.strideCurves[side];
  if (!c.length) return null;
  return Math.max(...c[c.length - 1].knee.filter(v => v !== null));
}

function connect(onUpdate) {
  const ws = new WebSocket(`ws://${location.host}/ws`);
  ws.onopen = () => { L.stats.connected = true; };
  ws.onclose = () => { L.stats.connected = false; setTimeout(() => connect(onUpdate), 1000); };
  ws.onmessage = (msg) => {
    const m = JSON.parse(msg.data);
    if (m.type === "config") { L.config = m; if (window.onLiveConfig) window.onLiveConfig(m); return; }
    // events come on their own as soon as they are detected, usually before the frames that hold them
    for (const e of m.events) {
      const key = `${e.side}${e.type}${e.k}`;
      if (L.seen.has(key)) continue;
      L.seen.add(key); L.events.push(e); L.stats.events += 1;
      if (e.type === "IC") L.pendingIC.push(e);
    }
    if (L.events.length > 400) L.events.splice(0, L.events.length - 400);
    if (m.type === "frames") {
      for (const f of m.frames) ingestFrame(f);
      L.metrics = m.metrics || {}; L.summary = m.summary || {};
      if (m.speed) L.speed = m.speed;
    }
    closePending();
    evaluateCue();
    if (onUpdate) onUpdate();
  };
}

function closePending() {          // an IC closes its stride once the frames up to it are in
  const last = L.frames.length ? L.frames[L.frames.length - 1][0] : -1;
  L.pendingIC = L.pendingIC.filter((e) => { if (e.k > last) return true; closeStride(e.side, e.k); return false; });
}

function ingestFrame(f) {           // f = [k, t_ms, [6 sagittal angles], offset_ready]
  L.frames.push(f); L.stats.frames += 1;
  if (L.frames.length > 3000) L.frames.splice(0, L.frames.length - 3000);
  for (const side of ["left", "right"]) {
    const cur = L.current[side];
    if (cur) { cur.hip.push(f[2][JOINTS.indexOf("hip_" + side)]); cur.knee.push(f[2][JOINTS.indexOf("knee_" + side)]); }
  }
}

function closeStride(side, k) {     // an IC closes the stride that began at the previous IC of this foot
  const cur = L.current[side];
  if (cur && cur.knee.length > 20 && cur.knee.length < 400) {
    L.strideCurves[side].push({hip: resample(cur.hip), knee: resample(cur.knee)});
    if (L.strideCurves[side].length > 5) L.strideCurves[side].shift();
  }
  L.current[side] = {k0: k, hip: [], knee: []};
}

function resample(v) {              // to 0..100 % of the cycle
  const out = [];
  for (let i = 0; i <= 100; i++) {
    const x = i / 100 * (v.length - 1), a = Math.floor(x), b = Math.min(a + 1, v.length - 1);
    const va = v[a], vb = v[b];
    out.push(va === null || vb === null ? null : va + (vb - va) * (x - a));
  }
  return out;
}

function cueSettings() {
  const c = L.config.cue || {};
  const g = id => document.getElementById(id);
  return {
    measure: g("cue-measure") ? g("cue-measure").value : (c.measure || "stance_asymmetry_pct"),
    lo: g("cue-lo") ? parseFloat(g("cue-lo").value) : (c.low ?? -Infinity),
    hi: g("cue-hi") ? parseFloat(g("cue-hi").value) : (c.high ?? Infinity),
    audio: g("cue-audio") ? g("cue-audio").checked : !!c.audio,
  };
}

let audioCtx = null;
function beep(freq) {
  try {
    audioCtx = audioCtx || new (window.AudioContext || window.webkitAudioContext)();
    const o = audioCtx.createOscillator(), g = audioCtx.createGain();
    o.frequency.value = freq; g.gain.value = 0.15; o.connect(g); g.connect(audioCtx.destination);
    o.start(); o.stop(audioCtx.currentTime + 0.12);
  } catch (e) { /* no audio device */ }
}

let lastBeep = 0;
function evaluateCue() {
  const s = cueSettings(), m = MEASURES[s.measure];
  const v = m ? m.get(L.metrics) : null;
  L.cueValue = v;
  const on = v !== null && v !== undefined && isFinite(v) && (v < s.lo || v > s.hi);
  if (on && !L.stats.cueOn) L.stats.cueCount += 1;
  L.stats.cueOn = on;
  document.body.dataset.cue = on ? "on" : "off";
  if (on && s.audio && performance.now() - lastBeep > 600) {
    lastBeep = performance.now();
    const err = v > s.hi ? v - s.hi : s.lo - v;            // pitch grows with the error (thesis ch. 8)
    beep(440 + Math.min(err, 50) * 12);
  }
}

function fmt(v, d = 1) { return v === null || v === undefined || !isFinite(v) ? "–" : v.toFixed(d); }

function drawLoop(draw) {
  let n = 0, t0 = performance.now();
  function tick() {
    draw(); L.stats.drawn += 1; n += 1;
    const t = performance.now();
    if (t - t0 > 1000) { L.stats.fps = n * 1000 / (t - t0); n = 0; t0 = t; }
    requestAnimationFrame(tick);
  }
  requestAnimationFrame(tick);
}

// ---- therapist drawings ------------------------------------------------------------------------------
function drawStick(cv) {
  const ctx = cv.getContext("2d"), W = cv.width, H = cv.height;
  ctx.clearRect(0, 0, W, H);
  const f = L.frames[L.frames.length - 1];
  ctx.fillStyle = "#555"; ctx.font = "14px sans-serif";
  if (!f) { ctx.fillText("waiting for data…", 10, 20); return; }
  const hip = [W / 2, H * 0.18], seg = H * 0.33, foot = H * 0.12;
  ctx.strokeStyle = "#888"; ctx.lineWidth = 2; ctx.beginPath(); ctx.moveTo(0, H - 8); ctx.lineTo(W, H - 8); ctx.stroke();
  for (const side of ["left", "right"]) {
    const a = f[2];
    const hf = a[JOINTS.indexOf("hip_" + side)], kf = a[JOINTS.indexOf("knee_" + side)], af = a[JOINTS.indexOf("ankle_" + side)];
    if (hf === null || kf === null) continue;
    const th = hf * Math.PI / 180, sh = (hf - kf) * Math.PI / 180, ft = sh + Math.PI / 2 - (af || 0) * Math.PI / 180;
    // sagittal view, walking to the right: flexion swings the thigh forward (+x)
    const knee = [hip[0] + seg * Math.sin(th), hip[1] + seg * Math.cos(th)];
    const ank = [knee[0] + seg * Math.sin(sh), knee[1] + seg * Math.cos(sh)];
    const toe = [ank[0] + foot * Math.sin(ft), ank[1] + foot * Math.cos(ft)];
    ctx.strokeStyle = COLORS[side]; ctx.lineWidth = 7; ctx.lineCap = "round";
    ctx.beginPath(); ctx.moveTo(...hip); ctx.lineTo(...knee); ctx.lineTo(...ank); ctx.lineTo(...toe); ctx.stroke();
    ctx.fillStyle = COLORS[side]; for (const p of [knee, ank]) { ctx.beginPath(); ctx.arc(p[0], p[1], 6, 0, 7); ctx.fill(); }
  }
  ctx.fillStyle = "#222"; ctx.beginPath(); ctx.arc(hip[0], hip[1], 9, 0, 7); ctx.fill();
  ctx.fillStyle = "#555"; ctx.fillText(`frame ${f[0]}` + (f[3] ? "" : " (standing offset pending)"), 10, 20);
}

// The normative band at the participant's walking speed (Schwartz et al. 2008: five speeds; linear in
// dimensionless speed v/sqrt(g L) between the two categories around it, the nearest beyond the outer ones:
// reports/normative.py speed_matched_band). Speed: the page's field, else --walking-speed, else the live estimate.
function currentSpeed() {
  const b = L.config.bands || {};
  if (L.speedOverride > 0) return {v: L.speedOverride, src: "entered on this page"};
  if (b.walking_speed_m_s > 0) return {v: b.walking_speed_m_s, src: "given (--walking-speed)"};
  if (L.speed && L.speed.speed_m_s > 0) return {v: L.speed.speed_m_s, src: `live estimate, ${L.speed.n_strides} strides`};
  return null;
}

function speedBand(joint) {
  const b = L.config.bands || {};
  if (!b.curves || !b.curves[joint]) return null;
  const cats = b.categories, c = cats.map(k => b.centres[k]);
  const sp = currentSpeed();
  let vh = sp ? sp.v / Math.sqrt(9.80665 * b.leg_length_m) : b.centres.free, clamped = false;
  if (vh < c[0] || vh > c[c.length - 1]) clamped = true;
  const v = Math.min(Math.max(vh, c[0]), c[c.length - 1]);
  let i = 0; while (i < c.length - 2 && v >= c[i + 1]) i++;
  const w = (v - c[i]) / (c[i + 1] - c[i]), A = b.curves[joint][cats[i]], B = b.curves[joint][cats[i + 1]];
  const mix = (a, bb) => a.map((x, k) => (1 - w) * x + w * bb[k]);
  L.bandInfo = {vh, lower: cats[i], upper: cats[i + 1], w, clamped, speed: sp};
  return {pct: b.pct, mean: mix(A.mean, B.mean), sd: mix(A.sd, B.sd)};
}

function bandNote() {
  const i = L.bandInfo, b = L.config.bands || {};
  if (!i) return "";
  const leg = `leg ${b.leg_length_m} m${b.leg_length_assumed ? " assumed" : ""}`;
  const where = i.clamped ? `held at ${i.w < 0.5 ? i.lower : i.upper}` :
    `${Math.round(100 * (1 - i.w))} % ${i.lower} + ${Math.round(100 * i.w)} % ${i.upper}`;
  return i.speed ? `grey: normative band at ${i.speed.v.toFixed(2)} m/s (${i.speed.src}; ${leg}; v̂ ${i.vh.toFixed(3)}: ${where}; ` +
    `Schwartz et al. 2008, interpolated between its five speeds)` :
    "grey: normative band at free speed (walking speed not known yet; Schwartz et al. 2008)";
}

function drawCurves(cv, joint) {
  const ctx = cv.getContext("2d"), W = cv.width, H = cv.height, pad = 30;
  ctx.clearRect(0, 0, W, H);
  const band = speedBand(joint);
  const lo = joint === "knee" ? -10 : -25, hi = joint === "knee" ? 75 : 50;
  const X = p => pad + (W - pad - 5) * p / 100, Y = v => H - pad - (H - pad - 10) * (v - lo) / (hi - lo);
  ctx.strokeStyle = "#ddd"; ctx.lineWidth = 1; ctx.font = "11px sans-serif"; ctx.fillStyle = "#666";
  for (let v = Math.ceil(lo / 25) * 25; v <= hi; v += 25) { ctx.beginPath(); ctx.moveTo(pad, Y(v)); ctx.lineTo(W, Y(v)); ctx.stroke(); ctx.fillText(v + "°", 2, Y(v) + 4); }
  ctx.fillText("0 %", pad, H - 12); ctx.fillText("gait cycle (IC → IC)", W / 2 - 50, H - 12); ctx.fillText("100 %", W - 35, H - 12);
  if (band) {
    ctx.fillStyle = "rgba(120,120,120,0.25)"; ctx.beginPath();
    band.mean.forEach((m, i) => ctx.lineTo(X(band.pct[i]), Y(m + band.sd[i])));
    for (let i = band.mean.length - 1; i >= 0; i--) ctx.lineTo(X(band.pct[i]), Y(band.mean[i] - band.sd[i]));
    ctx.fill();
  }
  for (const side of ["left", "right"]) {
    L.strideCurves[side].forEach((c, j, arr) => {
      ctx.strokeStyle = COLORS[side]; ctx.globalAlpha = 0.25 + 0.75 * (j + 1) / arr.length; ctx.lineWidth = 2;
      ctx.beginPath(); let pen = false;
      c[joint].forEach((v, i) => { if (v === null) { pen = false; return; } if (pen) ctx.lineTo(X(i), Y(v)); else ctx.moveTo(X(i), Y(v)); pen = true; });
      ctx.stroke();
    });
  }
  ctx.globalAlpha = 1;
  ctx.fillStyle = "#222"; ctx.font = "13px sans-serif"; ctx.fillText(joint === "knee" ? "Knee flexion" : "Hip flexion", pad + 5, 14);
}

function drawEvents(cv) {
  const ctx = cv.getContext("2d"), W = cv.width, H = cv.height;
  ctx.clearRect(0, 0, W, H);
  const f = L.frames[L.frames.length - 1];
  if (!f) return;
  const fs = L.config.sampling_rate_hz || 100, span = 10 * fs, kNow = f[0];
  const X = k => 60 + (W - 70) * (1 - (kNow - k) / span);
  ctx.font = "12px sans-serif";
  [["left", 18], ["right", 48]].forEach(([side, y]) => {
    ctx.fillStyle = COLORS[side]; ctx.fillText(side, 5, y + 4);
    ctx.strokeStyle = "#ccc"; ctx.beginPath(); ctx.moveTo(60, y); ctx.lineTo(W, y); ctx.stroke();
    for (const e of L.events) {
      if (e.side !== side || kNow - e.k > span) continue;
      ctx.fillStyle = e.type === "IC" ? COLORS[side] : "#fff"; ctx.strokeStyle = COLORS[side];
      ctx.beginPath(); ctx.arc(X(e.k), y, 6, 0, 7); ctx.fill(); ctx.stroke();
    }
  });
  ctx.fillStyle = "#666"; ctx.fillText("● IC   ○ TC   (last 10 s)", W - 170, H - 4);
}
