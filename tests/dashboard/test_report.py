"""Per-participant report: HTML self-contained, PDF rendered and checked (pages, pseudonym, a known figure)."""
from __future__ import annotations

import re
import shutil
import subprocess

import pytest

from stridelab.reports.participant import TITLES, build_report

pytestmark = pytest.mark.slow

pypdf = pytest.importorskip("pypdf", reason="pypdf is needed to read the report PDF (pip install pypdf)")


@pytest.fixture(scope="module")
def report(full_wh, tmp_path_factory):
    out = tmp_path_factory.mktemp("reports")
    return build_report(full_wh, "P001", out), None


def test_pdf_pages_pseudonym_and_known_figure(report):
    paths, _ = report
    reader = pypdf.PdfReader(paths["pdf"])
    assert len(reader.pages) >= len(TITLES)                      # one A4 page per report page, + continuations
    w, h = (float(x) for x in reader.pages[0].mediabox.upper_right)
    assert abs(w - 595) < 2 and abs(h - 842) < 2
    texts = [p.extract_text() for p in reader.pages]
    assert all("P001" in t for t in texts)                       # the pseudonym on every page
    page_of = {n: next(i for i, t in enumerate(texts) if f"{n}. {title}" in t) for n, title in TITLES.items()}
    assert list(page_of.values()) == sorted(page_of.values())   # in order; a continued page follows its page
    assert "Figure 1: Gait parameters across sessions" in texts[page_of[2]]
    assert "Figure 4: Time per activity class and day" in texts[page_of[4]]
    assert "Bland-Altman" in "".join(texts[page_of[5]:page_of[6]])
    assert not any(".mcap" in t for t in texts)                  # file names (possible site identifiers) never printed
    assert reader.metadata.title == "StrideLab report P001"


def test_pdf_figure_is_drawn(report, tmp_path):
    """Render page 2 with poppler and check that Figure 1's area holds a plot, not a blank box."""
    if shutil.which("pdftoppm") is None:
        pytest.skip("pdftoppm (poppler-utils) not installed: apt-get install poppler-utils")
    from PIL import Image
    import numpy as np
    paths, _ = report
    subprocess.run(["pdftoppm", "-f", "2", "-l", "2", "-r", "60", "-png", str(paths["pdf"]), str(tmp_path / "p")],
                   check=True)
    img = np.asarray(Image.open(next(tmp_path.glob("p*.png"))).convert("RGB")).astype(int)
    h = img.shape[0]
    band = img[int(0.12 * h):int(0.33 * h)]                      # where Figure 1 sits on page 2
    blue = (band[..., 2] > 150) & (band[..., 0] < 120)           # the series colour #4c78a8
    assert blue.sum() > 50
    assert (band.sum(axis=2) < 600).mean() > 0.01                # axes, ticks and labels


def test_html_is_self_contained(report):
    paths, _ = report
    html = paths["html"].read_text()
    # Figures 1 and 3-6; the synthetic warehouse has no clinical measures (Figure 2)
    assert "<svg" in html and html.count("<figure>") == 5 and "Figure 5: Free-living walking bouts" in html
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:|//)""", html)     # nothing fetched from elsewhere
    assert "<script" not in html
    assert "P001" in html and ".mcap" not in html


def test_report_without_stage_results_explains(ingested_wh, tmp_path):
    paths = build_report(ingested_wh, "P002", tmp_path)
    reader = pypdf.PdfReader(paths["pdf"])
    assert len(reader.pages) == len(TITLES)
    text = "\n".join(p.extract_text() for p in reader.pages)
    assert ("stridelab run" in text or "No " in text) and "P002" in text   # missing results are explained


def test_unknown_participant_and_empty_warehouse(ingested_wh, missing_wh, tmp_path):
    with pytest.raises(LookupError, match="not in the warehouse"):
        build_report(ingested_wh, "P999' OR '1'='1", tmp_path)
    with pytest.raises(LookupError, match="no published snapshot"):
        build_report(missing_wh, "P001", tmp_path)
    with pytest.raises(LookupError, match="not in study"):
        build_report(ingested_wh, "P001", tmp_path, study="other")


def test_summary_page_of_a_two_visit_participant(demo_wh, tmp_path):
    """The demo pipeline's warehouse (two lab visits, a chest day after each): page 1 is the clinician's summary
    with speed, the asymmetry ratios, steps/day and upright time, the change since the previous visit with its
    MDC95, bands with their source and the data-quality flags; page 2 holds the per-visit and per-side tables."""
    paths = build_report(demo_wh, "P001", tmp_path)
    reader = pypdf.PdfReader(paths["pdf"])
    assert len(reader.pages) >= len(TITLES)
    texts = [p.extract_text() for p in reader.pages]
    start3 = next(i for i, t in enumerate(texts) if f"3. {TITLES[3]}" in t)
    # a table cell wider than its column wraps: compare with the line breaks as spaces
    p1, p2 = " ".join(texts[0].split()), " ".join("\n".join(texts[1:start3]).split())   # page 2 and continuations
    for t in ("Summary", "Gait speed (m/s)", "Swing time symmetry ratio", "Stance time symmetry ratio",
              "Steps per day", "Upright time", "Previous visit", "MDC95", "Perry et al. 1995",
              "Patterson et al. 2010", "Where data quality limits a number", "Paretic side unknown"):
        assert t in p1, t
    assert "SI stride" not in p1 + p2 and "symmetry index" not in (p1 + p2).lower()
    assert "Clinical measures per lab visit" in p2 and "Latest visit per side" in p2 and "Figure 2" in p2


def test_table_headers_wrap_instead_of_being_cut(tmp_path):
    """A table too wide for its headers on one line: headers take two lines, no header loses characters (the
    page-1 summary once cut "MDC95 of the change" to "MDC95 of the chang"), and every cell is printed whole."""
    import pandas as pd
    from reportlab.pdfbase.pdfmetrics import stringWidth

    from stridelab.reports.render_pdf import BOLD, column_widths, render_pdf
    cols = ["Measure", "Latest visit", "Previous visit", "Change", "MDC95 of the change", "Beyond noise?",
            "Reference band (source)"]
    cols = cols + [f"{c} at visit 2" for c in cols[1:4]]                           # 10 columns
    row = ["Single support symmetry ratio", "1.21", "1.30", "-0.09", "0.05", "yes", "healthy 1.00-1.05 (Patterson)"]
    df = pd.DataFrame([row + row[1:4]], columns=cols)
    pages = {n: [] for n in TITLES}
    pages[1] = [("table", "Summary table", df)]
    render_pdf({"participant_id": "P042", "study": "s"}, pages, {"generated": "now", "snapshot": "x", "version": "0"},
               tmp_path / "r.pdf")
    words = pypdf.PdfReader(tmp_path / "r.pdf").pages[0].extract_text().split()
    for c in cols + row:                                     # every header and cell word whole
        assert all(w in words for w in c.split()), c
    assert not any(w.startswith("chang") and w != "change" for w in words)
    widths, size = column_widths(df, [[str(v) for v in df.iloc[0]]], 523.0)
    assert sum(widths) <= 523.0 + 1e-6
    assert widths[4] < stringWidth(cols[4], BOLD, size)     # the header needs two lines in its column


def test_long_table_continues_on_new_pages_and_keeps_every_row(tmp_path):
    """A page whose content does not fit goes on over continuation sheets: every row of a 150-row table is in
    the PDF (the renderer used to stop drawing a page at its bottom and drop the rest)."""
    import pandas as pd
    from stridelab.reports.participant import render_pdf
    rows = pd.DataFrame({"Stride": [f"S{i:03d}" for i in range(150)], "Length m": [1.0 + i / 1000 for i in range(150)]})
    pages = {n: [] for n in TITLES}
    pages[2] = [("text", "before the table"), ("table", "Every stride", rows), ("note", "after the table")]
    d = {"participant_id": "P042", "study": "s"}
    render_pdf(d, pages, {"generated": "now", "snapshot": "x", "version": "0"}, tmp_path / "r.pdf")
    reader = pypdf.PdfReader(tmp_path / "r.pdf")
    text = "\n".join(p.extract_text() for p in reader.pages)
    assert all(f"S{i:03d}" in text for i in range(150))
    assert "after the table" in text and "(continued)" in text
    assert len(reader.pages) > len(TITLES)


def test_participant_with_a_long_stride_table_keeps_every_row(tmp_path):
    """A participant with 2400 strides listed one per row (eight columns, one of them wrapping): the PDF runs
    over many sheets, each report page still starts its own sheet in order, and every stride's row is in the
    extracted text with its values."""
    import numpy as np
    import pandas as pd

    from stridelab.reports.render_pdf import render_pdf
    rng = np.random.default_rng(7)
    n = 2400
    strides = pd.DataFrame({"Stride": [f"ST{i:05d}" for i in range(n)],
                            "Session": [f"P077-lab-{1 + i // 800}" for i in range(n)],
                            "Side": np.where(np.arange(n) % 2, "right", "left"),
                            "Length m": rng.uniform(0.4, 1.6, n).round(3),
                            "Time s": rng.uniform(0.8, 1.6, n).round(3),
                            "Speed m/s": rng.uniform(0.3, 1.5, n).round(3),
                            "Stance %": rng.uniform(55, 70, n).round(1),
                            "Flags": ["turn; near the walkway end; foot contact confirmed by the second sensor"
                                      if i % 97 == 0 else "" for i in range(n)]})
    pages = {k: [("text", f"content of page {k}")] for k in TITLES}
    pages[2] = [("text", "before the strides"), ("table", "Every stride", strides), ("note", "after the strides")]
    render_pdf({"participant_id": "P077", "study": "s"}, pages, {"generated": "now", "snapshot": "x", "version": "0"},
               tmp_path / "r.pdf")
    reader = pypdf.PdfReader(tmp_path / "r.pdf")
    texts = [p.extract_text() for p in reader.pages]
    print(f"{n} strides: {len(reader.pages)} pages")
    assert len(reader.pages) > len(TITLES) + 1
    firsts = [next(i for i, t in enumerate(texts) if f"content of page {k}" in t or
                   (k == 2 and "before the strides" in t)) for k in TITLES]
    assert firsts == sorted(firsts) and len(set(firsts)) == len(TITLES)   # each report page on its own sheet
    words = " ".join(texts[firsts[1]:firsts[2]]).split()
    at = {w: i for i, w in enumerate(words) if w.startswith("ST")}
    for r in strides.itertuples(index=False):              # the row, its values in order after its id
        i = at[r.Stride]
        assert words[i + 1:i + 7] == [r.Session, r.Side, f"{r._3:.3g}", f"{r._4:.3g}", f"{r._5:.3g}",
                                      f"{r._6:.3g}"], r.Stride
    assert sum("Every stride" in t for t in texts) == 1 and all("Length m" in t for t in texts[firsts[1]:firsts[2]])
    assert "after the strides" in texts[firsts[2] - 1]
    assert "(continued)" in texts[firsts[1] + 1]
    assert "ST00000" in texts[firsts[1]]                     # the table starts below the text, not on a new sheet
