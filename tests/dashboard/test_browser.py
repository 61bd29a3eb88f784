"""End to end in a real headless browser (Debian's Chromium driven by Playwright): start the app on a
free localhost port, open every page, assert the key elements and that no exception is shown, save
screenshots."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from stridelab.pipeline.privacy import stored_name
from tests.browser import chromium, new_page, open_streamlit_page
from tests.dashboard.conftest import serve_dashboard

pytestmark = [pytest.mark.browser, pytest.mark.slow]

# page url path -> texts that must be visible
EXPECT = {      # the default page (Overview) lives at the root URL
    # the quarantined file (conftest's broken.mcap) appears under its stored name with its reason (the name: in the test)
    "": ["StrideLab overview", "Participants", "Quarantined files", "truncated MCAP", "Quality flags"],
    "accuracy": ["Accuracy against references", "orientation", "rmse_deg"],
    "participant": ["Participant", "P001", "Sessions", "Gait parameters"],
    "activity": ["Daily activity", "Posture transitions", "Daily totals"],
    "runs": ["Pipeline runs", "Stage runs", "no stance phase detected"],
}
# the real pipeline's output on the (small) demo study: every stage's results, including accuracy
EXPECT_DEMO = {
    "": ["StrideLab overview", "Participants", "P001", "P002"],
    "accuracy": ["Accuracy against references", "orientation", "inclination_rmse_deg", "gait"],
    "participant": ["Participant", "P001", "Sessions", "Gait parameters"],
    "programme": ["Programme: change between visits", "Cohort: first", "MDC95", "Participant trend"],
    "activity": ["Daily activity", "Daily totals"],
    "runs": ["Pipeline runs", "Stage runs", "joint_angles"],
}


@pytest.fixture(scope="module")
def server(full_wh):
    with serve_dashboard(full_wh) as url:
        yield url


def _open_every_page(browser, server: str, expect: dict, shots: Path, errors: list) -> None:
    page = new_page(browser, errors)
    for path, texts in expect.items():
        name = path or "overview"
        open_streamlit_page(page, f"{server}/{path}")
        for t in texts:      # table cells live in a canvas grid: present in the DOM, not "visible"
            page.get_by_text(t, exact=False).first.wait_for(state="attached", timeout=30_000)
        assert page.locator('[data-testid="stException"]').count() == 0, f"exception shown on {name}"
        assert page.get_by_text("Page not found").count() == 0, f"{name}: page not found"
        if path in ("participant", "accuracy", "activity", "runs", "programme"):
            page.locator(".js-plotly-plot").first.wait_for(timeout=30_000)
        page.screenshot(path=str(shots / f"{name}.png"), full_page=True)
        assert (shots / f"{name}.png").stat().st_size > 10_000


def test_every_page_of_the_demo_pipeline_warehouse_in_chromium(demo_server, tmp_path_factory):
    shots = tmp_path_factory.mktemp("screenshots_demo")
    errors: list[str] = []
    with chromium() as browser:
        _open_every_page(browser, demo_server, EXPECT_DEMO, shots, errors)
    assert not errors, errors
    print(f"screenshots in {shots}")


def test_every_page_in_chromium(server, tmp_path_factory):
    shots = tmp_path_factory.mktemp("screenshots")
    with chromium() as browser:
        errors: list[str] = []
        # the quarantined file is listed under its stored name (a keyed hash), never under the name it had
        expect = dict(EXPECT, **{"": EXPECT[""] + [stored_name("broken.mcap")]})
        _open_every_page(browser, server, expect, shots, errors)
        # navigation through the sidebar works too (a fresh tab: full-page screenshots resize the viewport)
        page = new_page(browser, errors)
        page.goto(server, wait_until="domcontentloaded")
        page.get_by_text("Quality flags").first.wait_for(state="attached", timeout=30_000)
        page.get_by_text(stored_name("broken.mcap")).first.wait_for(state="attached", timeout=30_000)
        assert page.get_by_text("broken", exact=False).count() == 0
        link = page.locator('[data-testid="stSidebarNavLink"]', has_text="Runs").first
        link.wait_for(state="visible", timeout=30_000)
        link.click()
        page.get_by_role("heading", name="Pipeline runs").wait_for(timeout=30_000)
        page.wait_for_url("**/runs", timeout=30_000)
        assert not errors, errors
    print(f"screenshots in {shots}")


def test_cohort_change_page_in_chromium(demo_server, tmp_path_factory):
    """The Programme page on the demo pipeline's two-visit warehouse: the cohort-change figure (one marker per
    participant with its MDC95 bar) and the participant trends are drawn; screenshot kept (path printed, or in
    $STRIDELAB_SCREENSHOTS)."""
    shots = Path(os.environ.get("STRIDELAB_SCREENSHOTS") or tmp_path_factory.mktemp("screenshots_programme"))
    shots.mkdir(parents=True, exist_ok=True)
    errors: list[str] = []
    url = demo_server
    with chromium() as browser:
        page = new_page(browser, errors)
        open_streamlit_page(page, f"{url}/programme", heading="Programme: change between visits", timeout_ms=60_000)
        page.get_by_text("Cohort: first", exact=False).first.wait_for(state="attached", timeout=30_000)
        plots = page.locator(".js-plotly-plot")
        plots.first.wait_for(timeout=30_000)
        assert plots.count() >= 5                     # the cohort change + four participant trends
        # the cohort figure has one marker per participant of the demo warehouse (P001, P002)
        assert page.locator(".js-plotly-plot").first.locator("g.points path.point").count() == 2
        assert page.locator('[data-testid="stException"]').count() == 0
        page.screenshot(path=str(shots / "programme.png"), full_page=True)
    assert not errors, errors
    assert (shots / "programme.png").stat().st_size > 20_000
    print(f"screenshot: {shots / 'programme.png'}")
