"""``--replace``: a corrected export supersedes the recording it corrects, and what depended on it.

The recordings a file supersedes are the ingested ones with the same samples (a re-export with
corrected metadata) or the same file name (a corrected export of the same trial). They stay in the
catalog with status ``superseded`` and a reason naming their successor; their sensors, issues and
reference events go (their series files are garbage-collected once no snapshot refers to them). A
session left without recordings is removed with every stage output of it; a session that keeps
recordings has a new stage input hash, so the run recomputes its stages.
"""
from __future__ import annotations

#: tables with a session_id that are not stage outputs (kept, or handled on their own)
_NOT_OUTPUTS = {"recordings", "stage_runs", "sessions", "reference_events"}


def previous_versions(con, p) -> list[tuple[str, str, str]]:
    """(content_hash, file_name, session_id) of the ingested recordings ``p`` supersedes."""
    return con.execute("SELECT content_hash, file_name, session_id FROM recordings WHERE status = 'ingested' "
                       "AND content_hash <> ? AND ((? <> '' AND sample_hash IN (?, ?)) OR file_name = ?) ORDER BY 1",
                       [p.content_hash, p.sample_hash, p.sample_hash, p.legacy_sample_hash or p.sample_hash,
                        p.file_name]).fetchall()


def sessions_emptied(con, old: list[tuple[str, str, str]]) -> set[str]:
    """Sessions whose every ingested recording is among ``old``."""
    gone = {h for h, _, _ in old}
    out = set()
    for sid in {s for _, _, s in old}:
        left = {h for (h,) in con.execute("SELECT content_hash FROM recordings WHERE session_id = ? "
                                          "AND status = 'ingested'", [sid]).fetchall()}
        if left <= gone:
            out.add(sid)
    return out


def _output_tables(con) -> list[str]:
    return [t for (t,) in con.execute("SELECT DISTINCT table_name FROM information_schema.columns "
                                      "WHERE column_name = 'session_id' AND table_schema = 'main'").fetchall()
            if t not in _NOT_OUTPUTS]


def supersede(con, old: list[tuple[str, str, str]], p, emptied: set[str]) -> list[str]:
    """Mark ``old`` superseded by ``p`` and remove what only they fed; returns their file names."""
    for h, name, sid in old:
        con.execute("UPDATE recordings SET status = 'superseded', reason = ? WHERE content_hash = ?",
                    [f"superseded by {p.file_name} (sha256 {p.content_hash[:12]}…) with --replace", h])
        for t in ("sensors", "recording_issues", "reference_events", "live_outputs"):
            con.execute(f'DELETE FROM "{t}" WHERE content_hash = ?', [h])
    for sid in emptied:
        for t in _output_tables(con):         # stage outputs and stage_state of the emptied session
            con.execute(f'DELETE FROM "{t}" WHERE session_id = ?', [sid])
        con.execute("DELETE FROM sessions WHERE session_id = ?", [sid])
    con.execute("DELETE FROM participants WHERE (study, participant_id) NOT IN "
                "(SELECT study, participant_id FROM sessions)")
    for sid in {s for _, _, s in old} - emptied:
        refresh_session_span(con, sid)
    return [name for _, name, _ in old]


def refresh_session_span(con, session_id: str) -> None:
    """Session start/end from its ingested recordings (after some were superseded)."""
    con.execute("UPDATE sessions SET start_ns = (SELECT min(start_ns) FROM recordings r WHERE r.session_id = ? "
                "AND r.status = 'ingested'), end_ns = (SELECT max(end_ns) FROM recordings r WHERE r.session_id = ? "
                "AND r.status = 'ingested') WHERE session_id = ?", [session_id, session_id, session_id])
