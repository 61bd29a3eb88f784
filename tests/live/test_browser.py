"""``stridelab live --replay`` of the hemiparetic walk with the pages open in Debian's Chromium (Playwright):
the stick figure moves, gait events appear, the stance-asymmetry cue triggers; screenshots saved."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.browser import chromium, free_port, require_chromium, stop, wait_until_serving

pytestmark = [pytest.mark.browser, pytest.mark.slow]


def test_live_replay_in_chromium(lab_files, tmp_path_factory):
    require_chromium()
    cal, walk = lab_files
    shots = Path(os.environ.get("STRIDELAB_LIVE_SHOTS") or tmp_path_factory.mktemp("live_screenshots"))
    shots.mkdir(parents=True, exist_ok=True)
    port = free_port()
    proc = subprocess.Popen([sys.executable, "-m", "stridelab", "live", "--replay", str(walk),
                             "--calibration", str(cal),
                             "--speed", "1", "--minutes", "3", "--port", str(port), "--no-record", "--audio",
                             "--cue", "stance_asymmetry_pct:0:10"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    url = f"http://127.0.0.1:{port}"
    try:
        wait_until_serving(proc, f"{url}/api/state", "stridelab live")
        errors: list[str] = []
        with chromium("--autoplay-policy=no-user-gesture-required") as browser:
            page = browser.new_page(viewport={"width": 1500, "height": 900})
            page.on("pageerror", lambda e: errors.append(str(e)))
            patient = browser.new_page(viewport={"width": 900, "height": 600})
            patient.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(f"{url}/", wait_until="domcontentloaded")
            patient.goto(f"{url}/patient", wait_until="domcontentloaded")
            page.wait_for_function("() => window.liveStats && window.liveStats.events >= 6", timeout=90_000)
            a = page.evaluate("document.getElementById('stick').toDataURL()")
            page.wait_for_timeout(300)
            b = page.evaluate("document.getElementById('stick').toDataURL()")
            assert a != b, "the stick figure did not move"
            page.wait_for_function("() => document.body.dataset.cue === 'on'", timeout=90_000)
            stats = page.evaluate("({...window.liveStats})")
            assert stats["cueCount"] >= 1 and stats["frames"] > 200
            assert "IC" in page.evaluate("JSON.stringify(L.events.map(e => e.type))")
            assert page.locator("#cue-banner").is_visible()
            # the normative band follows the walking speed: first the live estimate, then one typed in
            page.wait_for_function("() => L.speed && L.speed.speed_m_s > 0", timeout=90_000)
            note = page.locator("#bandnote").inner_text()
            assert "m/s (live estimate" in note and "Schwartz" in note, note
            live_v = page.evaluate("L.speed.speed_m_s")
            page.fill("#walk-speed", "0.4")
            page.wait_for_timeout(600)
            note = page.locator("#bandnote").inner_text()
            assert "0.40 m/s (entered on this page" in note, note
            from stridelab.reports.normative import speed_matched_band
            for v in (0.4, live_v, 1.3):
                page.fill("#walk-speed", str(v))
                js = page.evaluate("speedBand('knee')")
                _pct, mean, sd, _info = speed_matched_band("knee", v, 0.90, n=51)
                assert max(abs(a - b) for a, b in zip(js["mean"], mean)) < 1e-9
                assert max(abs(a - b) for a, b in zip(js["sd"], sd)) < 1e-9
            page.fill("#walk-speed", "")
            page.wait_for_timeout(1500)         # a few more strides drawn on the curves
            page.screenshot(path=str(shots / "therapist.png"))
            patient.wait_for_function("() => document.body.dataset.cue === 'on'", timeout=30_000)
            patient.screenshot(path=str(shots / "patient.png"))
            print(f"\nscreenshots in {shots}; page stats {stats}")
        assert not errors, errors
        assert (shots / "therapist.png").stat().st_size > 10_000
    finally:
        stop(proc, 15)
