"""The dashboard on a warehouse holding the simulated demo study and the public study (real recordings of the
public datasets, imported and run by the real pipeline): the study selector, accuracy rows that say which data
and reference they come from, pages that handle sessions as they come (one foot, feet only, hand-held, chest
accelerometer only). AppTest for the selector, then every page in Chromium with screenshots."""
from __future__ import annotations

from pathlib import Path

import pytest

from tests.browser import chromium, new_page, open_streamlit_page
from tests.dashboard.conftest import serve_dashboard
from tests.dashboard.test_pages import open_page

pytestmark = [pytest.mark.realdata, pytest.mark.slow]


def _frames(at):
    return [d.value for d in at.dataframe]


def test_study_selector_limits_the_accuracy_page_to_one_study(app_env, public_wh):
    app_env(public_wh)
    at = open_page("accuracy")
    assert at.sidebar.selectbox(key="study").options == ["All studies", "demo", "public"]
    both = {s for df in _frames(at) if "dataset" in df for s in df["dataset"]}
    assert any(s.startswith("demo") for s in both) and any(s.startswith("public") for s in both)
    at = open_page("accuracy", {"study": "public"})
    assert at.sidebar.selectbox(key="study").value == "public"
    frames = [df for df in _frames(at) if "reference" in df and "dataset" in df]
    rows = {(d, r) for df in frames for d, r in zip(df["dataset"], df["reference"])}
    assert rows and all(d.startswith("public") for d, _ in rows)
    refs = " ".join(r for _, r in rows)
    for ref in ("OptiTrack", "Voisard", "Qualisys", "Vicon", "UCI chest label"):
        assert ref in refs, (ref, refs)
    assert not any("simulated" in r for _, r in rows)


def test_participant_pages_of_sessions_as_they_come(app_env, public_wh):
    app_env(public_wh)
    for pid in ("pyshoe01", "broad01", "gaitmap01", "voisard01", "uci01"):
        at = open_page("participant", {"study": "public", "participant": pid})
        assert pid in " ".join(h.value for h in at.header)


EXPECT_PUBLIC = {
    "?study=public": ["StrideLab overview", "Participants of public", "broad01"],
    "accuracy?study=public": ["Accuracy against references", "every row with its recording and reference",
                              "total_rmse_deg"],
    "participant?study=public&participant=pyshoe01": ["Participant", "pyshoe01", "Sessions"],
    "participant?study=public&participant=broad01": ["Participant", "broad01", "Sessions"],
    "activity?study=public": ["Daily activity"],
    "runs": ["Pipeline runs", "Stage runs"],
    "accuracy": ["Accuracy against references", "every row with its recording and reference"],
}


@pytest.mark.browser
def test_every_page_on_the_public_study_in_chromium(public_wh, tmp_path_factory):
    shots = Path(tmp_path_factory.mktemp("screenshots_public"))
    errors: list[str] = []
    with serve_dashboard(public_wh) as url, chromium() as browser:
        page = new_page(browser, errors)
        for path, texts in EXPECT_PUBLIC.items():
            name = (path.split("?")[0] or "overview") + ("_" + path.split("=")[-1] if "participant=" in path
                                                           else "_public" if "study=" in path else "_all")
            open_streamlit_page(page, f"{url}/{path}", timeout_ms=60_000)
            for t in texts:
                page.get_by_text(t, exact=False).first.wait_for(state="attached", timeout=60_000)
            assert page.locator('[data-testid="stException"]').count() == 0, f"exception shown on {path}"
            page.screenshot(path=str(shots / f"{name}.png"), full_page=True)
    assert not errors, errors
    print(f"screenshots in {shots}")
