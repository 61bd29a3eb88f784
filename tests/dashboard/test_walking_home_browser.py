"""The "Walking at home" page in a real headless Chromium on the demo pipeline's warehouse (simulated lower-back
sensor at the lab visits and on the home days, the real trunk-gait stage): the capacity-beside-performance figure,
the per-day figures and tables are drawn, no exception; screenshot kept ($STRIDELAB_SCREENSHOTS)."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from tests.browser import chromium, new_page, open_streamlit_page

pytestmark = [pytest.mark.browser, pytest.mark.slow]


def test_walking_at_home_page_in_chromium(demo_wh, demo_server, tmp_path_factory):
    from stridelab.warehouse.read import connect_snapshot
    con = connect_snapshot(demo_wh)
    try:
        n_days = con.execute("SELECT count(*) FROM daily_gait_outcomes d JOIN sessions s USING (session_id) "
                             "WHERE s.participant_id = 'P001'").fetchone()[0]
        n_bouts = con.execute("SELECT count(*) FROM walking_bouts").fetchone()[0]
    finally:
        con.close()
    assert n_days >= 1 and n_bouts >= 1            # the page is looked at with data
    shots = Path(os.environ.get("STRIDELAB_SCREENSHOTS") or tmp_path_factory.mktemp("screenshots_home"))
    shots.mkdir(parents=True, exist_ok=True)
    errors: list[str] = []
    with chromium() as browser:
        page = new_page(browser, errors)
        open_streamlit_page(page, f"{demo_server}/walking-home?participant=P001", heading="Walking at home",
                            timeout_ms=60_000)
        for text in ("Lab capacity beside home performance", "Per day", "Walking bouts", "Home days"):
            page.get_by_text(text, exact=False).first.wait_for(state="attached", timeout=30_000)
        plots = page.locator(".js-plotly-plot")
        plots.first.wait_for(timeout=30_000)
        assert plots.count() == 3          # capacity beside performance, speed per day, bouts per class
        # one capacity bar group per lab visit of P001 (two visits in the demo programme)
        assert page.get_by_text("visit 2", exact=False).count() >= 1
        assert page.locator('[data-testid="stException"]').count() == 0
        page.screenshot(path=str(shots / "walking_home.png"), full_page=True)
    assert not errors, errors
    print(f"screenshot: {shots / 'walking_home.png'}")
