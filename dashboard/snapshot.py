"""The pages' cached, read-only access to the newest snapshot (Streamlit), over the queries of
``stridelab.warehouse.queries``: one cached read-only connection per published snapshot (``st.cache_resource``; a newer
snapshot gives a new connection, the old one is closed when it leaves the cache) and ``st.cache_data`` on every
query, keyed by the snapshot name, so a nightly run that publishes a snapshot invalidates the cache without ever
being blocked by a reader."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import duckdb

from stridelab.warehouse.queries import QUERIES
from stridelab.warehouse.read import latest_snapshot



class Snapshot:
    """The pages' handle on the newest snapshot: ``snap.q(queries.sessions, pid)`` runs a cached query.

    ``None`` from :func:`open_snapshot` means the warehouse has published nothing yet.
    """

    def __init__(self, root: Path, name: str):
        self.root = root
        self.name = name

    def q(self, fn: Callable, *args, **kwargs):
        if fn.__name__ not in QUERIES:
            raise ValueError(f"{fn.__name__} is not a query of stridelab.warehouse.queries")
        return _cache()[1](str(self.root), self.name, fn.__name__, args, tuple(sorted(kwargs.items())))


def open_snapshot(root: str | Path) -> Snapshot | None:
    snap = latest_snapshot(root)
    if snap is None:
        return None
    return Snapshot(Path(root), snap.name)


def _close(con) -> None:
    try:
        con.close()
    except Exception:  # noqa: BLE001 - already closed
        pass


def _st():
    import streamlit as st
    return st


def _make_cached():
    st = _st()

    @st.cache_resource(max_entries=2, show_spinner=False, on_release=_close)
    def connection(root: str, snapshot: str):
        return duckdb.connect(str(Path(root) / "snapshots" / snapshot), read_only=True)

    @st.cache_data(max_entries=512, show_spinner=False, ttl=3600)
    def cached(root: str, snapshot: str, fn_name: str, args: tuple, kwargs: tuple):
        fn = QUERIES[fn_name]
        cur = connection(root, snapshot).cursor()     # a cursor per query: safe across script threads
        try:
            return fn(cur, *args, **dict(kwargs))
        finally:
            cur.close()

    return connection, cached


_CACHE: list = []


def _cache():
    """(connection, cached query) functions, created on first use (the reports never need Streamlit)."""
    if not _CACHE:
        _CACHE.extend(_make_cached())
    return _CACHE

