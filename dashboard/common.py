"""What every page shares: the warehouse location, the snapshot handle, empty-state messages."""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import streamlit as st

from stridelab.dashboard.snapshot import Snapshot, open_snapshot
from stridelab.warehouse.read import snapshot_status
from stridelab.warehouse import queries as Q

ENV = "STRIDELAB_WAREHOUSE"
ALL_STUDIES = "All studies"


def warehouse_root() -> Path:
    """``--warehouse PATH`` after ``--`` on the streamlit command line, else $STRIDELAB_WAREHOUSE, else
    the default of the CLI ($STRIDELAB_HOME/warehouse)."""
    ap = argparse.ArgumentParser(add_help=False)
    ap.add_argument("--warehouse", default=None)
    args, _ = ap.parse_known_args(sys.argv[1:])
    if args.warehouse:
        return Path(args.warehouse).expanduser().resolve()
    if os.environ.get(ENV):
        return Path(os.environ[ENV]).expanduser().resolve()
    from stridelab.warehouse.location import default_warehouse
    return default_warehouse()


def snapshot() -> Snapshot | None:
    """The newest published snapshot, or None after telling the user what to run."""
    root = warehouse_root()
    snap = open_snapshot(root)
    _, damaged = snapshot_status(root)          # a damaged newest snapshot: the previous one, said here
    if damaged:
        st.warning(damaged, icon=":material/warning:")
    if snap is None and damaged:
        return None
    if snap is None:
        st.info(f"The warehouse at `{root}` has no published data yet. To fill it, "
                f"{Q.RUN_HINT.replace('WAREHOUSE', str(root))}.", icon=":material/info:")
    return snap


def empty_warehouse_note(snap: Snapshot) -> bool:
    """True (and a hint shown) when the snapshot holds no session at all."""
    if snap.q(Q.counts)["sessions"] == 0:
        st.info(f"No sessions in the warehouse yet: {Q.RUN_HINT}.", icon=":material/info:")
        return True
    return False


def hint(dataset: str) -> None:
    st.caption(":material/hourglass_empty: " + Q.missing_hint(dataset))


def footer(snap: Snapshot | None) -> None:
    if snap is not None:
        st.caption(f"Snapshot `{snap.name}` of `{snap.root}` (read-only).")


def study_selector() -> str | None:
    """The study selector every page shares (sidebar, above the page's own filters; ``?study=`` in the URL):
    the selected study id, or None for all studies side by side."""
    snap = open_snapshot(warehouse_root())
    if snap is None:
        return None
    studies = sorted(snap.q(Q.studies)["study"].dropna().astype(str).unique())
    if not studies:
        return None
    options = [ALL_STUDIES] + studies
    if "study" not in st.session_state:
        qp = st.query_params.get("study")
        st.session_state["study"] = qp if qp in studies else ALL_STUDIES
    if st.session_state["study"] not in options:
        st.session_state["study"] = ALL_STUDIES
    choice = st.sidebar.selectbox("Study", options, key="study",
                                  help="Simulated and real studies live side by side in one warehouse; "
                                       "every page shows the study chosen here.")
    if choice == ALL_STUDIES:
        st.query_params.pop("study", None)
        return None
    st.query_params["study"] = choice
    return choice


def current_study() -> str | None:
    """The study chosen in the shared selector (None = all studies)."""
    v = st.session_state.get("study")
    return None if v in (None, ALL_STUDIES) else v


def participant_picker(snap: Snapshot, key: str = "participant") -> tuple[str | None, str | None]:
    """Participant selector in the sidebar, within the study of the shared selector (or a per-page study
    selector when all studies are shown); returns (study, participant_id)."""
    parts = snap.q(Q.participants)
    if parts.empty:
        return None, None
    studies = sorted(parts["study"].unique())
    chosen = current_study()
    if chosen in studies:
        study = chosen
    else:
        study = st.sidebar.selectbox("Study of the participant", studies, key=f"{key}_study") \
            if len(studies) > 1 else studies[0]
    ids = parts.loc[parts["study"] == study, "participant_id"].tolist()
    qp = st.query_params.get("participant")
    idx = ids.index(qp) if qp in ids else 0
    pid = st.sidebar.selectbox("Participant (pseudonym)", ids, index=idx, key=f"{key}_pid")
    return study, pid
