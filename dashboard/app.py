"""StrideLab dashboard: ``stridelab dashboard`` (or ``streamlit run dashboard/app.py -- --warehouse PATH`` in a
checkout with StrideLab installed: the app imports ``stridelab.dashboard``, never its folder by name).

Reads only the newest published snapshot of the warehouse (read-only); never blocks a nightly run.
The warehouse comes from ``--warehouse`` after ``--``, else ``$STRIDELAB_WAREHOUSE``, else
``$STRIDELAB_HOME/warehouse``.
"""
from __future__ import annotations

from pathlib import Path

import streamlit as st

_PAGES = Path(__file__).resolve().parent / "views"   # not "pages/": that name turns on the legacy auto-navigation

st.set_page_config(page_title="StrideLab", page_icon=":material/directions_walk:", layout="wide")

pages = [
    st.Page(_PAGES / "overview.py", title="Overview", icon=":material/dashboard:", url_path="overview", default=True),
    st.Page(_PAGES / "accuracy.py", title="Accuracy", icon=":material/target:", url_path="accuracy"),
    st.Page(_PAGES / "participant.py", title="Participant", icon=":material/person:", url_path="participant"),
    st.Page(_PAGES / "programme.py", title="Programme", icon=":material/trending_up:", url_path="programme"),
    st.Page(_PAGES / "activity.py", title="Activity", icon=":material/directions_run:", url_path="activity"),
    st.Page(_PAGES / "walking_home.py", title="Walking at home", icon=":material/home:", url_path="walking-home"),
    st.Page(_PAGES / "runs.py", title="Runs", icon=":material/history:", url_path="runs"),
]
nav = st.navigation(pages)
from stridelab.dashboard.common import study_selector  # noqa: E402  (after set_page_config)
study_selector()
nav.run()
