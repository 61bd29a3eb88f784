"""Per-participant report: a self-contained HTML file and an A4 PDF with the same content, from the newest
published snapshot.

The report is assembled in small steps, one module each: ``stridelab.reports.collect`` reads what the report shows,
``stridelab.reports.tables`` and ``stridelab.reports.figures`` shape it, ``stridelab.reports.document`` orders it into the report's pages
(the page list and their content are described there), and ``stridelab.reports.render_html`` / ``stridelab.reports.render_pdf``
write the two files (the PDF is laid out and paginated by ReportLab's Platypus: content that does not fit on a
sheet continues on the next, none is dropped). Only the pseudonym identifies the participant; file names
(which may carry site identifiers) are not printed.
"""
from __future__ import annotations

import os
import re
from datetime import datetime, timezone
from pathlib import Path

from stridelab.reports.collect import collect
from stridelab.reports.document import FIG_CAPTIONS, TITLES, blocks
from stridelab.reports.figures import pyplot
from stridelab.reports.render_html import render_html
from stridelab.reports.render_pdf import render_pdf

__all__ = ["FIG_CAPTIONS", "TITLES", "build_report", "collect", "render_html", "render_pdf"]

_SAFE = re.compile(r"[^A-Za-z0-9._-]")


def _replace_durably(tmp: Path, final: Path) -> None:
    with open(tmp, "rb") as f:
        os.fsync(f.fileno())
    os.replace(tmp, final)


def build_report(warehouse_root: Path, participant_id: str, out_dir: Path, *, study: str | None = None) -> dict:
    """Write ``<out_dir>/<study>_<participant>.html`` and ``.pdf`` from the newest snapshot.

    Raises LookupError (participant or snapshot not found) or ValueError (ambiguous participant).
    """
    from importlib.metadata import PackageNotFoundError, version
    from stridelab.warehouse.read import connect_snapshot, latest_snapshot
    root = Path(warehouse_root)
    snap = latest_snapshot(root)
    con = connect_snapshot(root)
    if con is None or snap is None:
        raise LookupError(f"the warehouse at {root} has no published snapshot yet; run `stridelab run` first")
    try:
        d = collect(con, root, participant_id, study)
    finally:
        con.close()
    try:
        ver = version("stridelab")
    except PackageNotFoundError:
        ver = "dev"
    meta = {"generated": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"), "snapshot": snap.name,
            "version": ver}
    plt = pyplot()
    pages = blocks(d)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = f"{_SAFE.sub('_', d['study'])}_{_SAFE.sub('_', participant_id)}"
    html_path, pdf_path = out_dir / f"{stem}.html", out_dir / f"{stem}.pdf"
    try:
        # each file appears whole or not at all: temporary name (.tmp-<pid>-, removed by the next run if
        # this process is killed), fsync, rename
        text = render_html(d, pages, meta)
        tmp = html_path.with_name(f".tmp-{os.getpid()}-{html_path.name}")
        tmp.write_text(text, encoding="utf-8")
        _replace_durably(tmp, html_path)
        tmp = pdf_path.with_name(f".tmp-{os.getpid()}-{pdf_path.name}")
        render_pdf(d, pages, meta, tmp)
        _replace_durably(tmp, pdf_path)
    finally:
        for page in pages.values():
            for b in page:
                if b[0] == "figure":
                    plt.close(b[2])
    return {"html": html_path, "pdf": pdf_path}
