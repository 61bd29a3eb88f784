"""``stridelab report PID``: per-participant report (self-contained HTML + PDF) from the newest snapshot.

The report is a view of the warehouse and lives with the dashboard (``dashboard/report.py``: same
queries, same layout rules); this module is the pipeline's entry point to it (CLI, nightly run).
"""
from __future__ import annotations

from pathlib import Path


def build_report(warehouse_root: Path, participant_id: str, out_dir: Path, *, study: str | None = None) -> dict:
    """Write ``<out_dir>/<study>_<participant>.html`` and ``.pdf``; returns {"html": path, "pdf": path}.

    Raises LookupError when the warehouse has no snapshot or the participant is unknown, ValueError
    when the pseudonym exists in several studies and ``study`` is not given.
    """
    from dashboard.report import build_report as _build
    return _build(Path(warehouse_root), participant_id, Path(out_dir), study=study)
