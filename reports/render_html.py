"""The report as one self-contained HTML file (inline CSS and SVG figures, nothing fetched from elsewhere)."""
from __future__ import annotations

import html

import pandas as pd

from stridelab.reports.document import TITLES
from stridelab.reports.figures import svg
from stridelab.reports.tables import fmt

_CSS = """body{font-family:DejaVu Sans,Helvetica,Arial,sans-serif;font-size:11px;color:#222;max-width:820px;margin:20px auto}
h1{font-size:18px;margin:0} h2{font-size:14px;border-bottom:1px solid #888;margin-top:28px}
h3{font-size:12px;margin:10px 0 4px} table{border-collapse:collapse;margin:4px 0 10px}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:left} th{background:#f0f0f0}
.note{color:#555;font-style:italic} figure{margin:6px 0} figcaption{font-weight:bold;margin-top:2px}
section{page-break-after:always} header{border-bottom:2px solid #333;padding-bottom:4px}
svg{max-width:100%;height:auto}"""


def _html_table(df: pd.DataFrame) -> str:
    head = "".join(f"<th>{html.escape(str(c))}</th>" for c in df.columns)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(fmt(v))}</td>" for v in row) + "</tr>"
                   for row in df.itertuples(index=False))
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def render_html(d: dict, pages: dict, meta: dict) -> str:
    e = html.escape
    out = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>StrideLab report {e(d['participant_id'])}"
           f"</title><style>{_CSS}</style></head><body>",
           f"<header><h1>StrideLab participant report: {e(d['participant_id'])}</h1>"
           f"<div>Study {e(d['study'])} · generated {e(meta['generated'])} · snapshot {e(meta['snapshot'])}</div></header>"]
    for n, title in TITLES.items():
        out.append(f"<section id='page-{n}'><h2>{n}. {e(title)}</h2>")
        for b in pages[n]:
            if b[0] == "heading":
                out.append(f"<h3>{e(b[1])}</h3>")
            elif b[0] == "text":
                out.append(f"<p>{e(b[1])}</p>")
            elif b[0] == "note":
                out.append(f"<p class='note'>{e(b[1])}</p>")
            elif b[0] == "table":
                out.append(f"<h3>{e(b[1])}</h3>{_html_table(b[2])}")
            elif b[0] == "figure":
                out.append(f"<figure>{svg(b[2])}<figcaption>{e(b[1])}</figcaption></figure>")
        out.append("</section>")
    out.append("</body></html>")
    return "\n".join(out)
