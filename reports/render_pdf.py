"""The report as an A4 PDF laid out by ReportLab's Platypus (a layout engine that flows and paginates).

Each report page (``stridelab.reports.document.TITLES``) starts on a new sheet; whatever does not fit goes on over
continuation sheets marked "(continued)" in the running header, so no row, note or figure is ever dropped.
Tables are split between rows with their header row repeated; a table title stays with its first rows and a
figure with its caption. Cells and headers wrap inside their column rather than being cut. Figures are the
matplotlib figures of the HTML report, placed as 160 dpi PNG images at their drawn size (scaled down to the
text width when wider). Text is set in DejaVu Sans, the font matplotlib ships (so "≤", "±", "—" print, and no
system font is needed). ``invariant`` output: the same report gives the same bytes.

ReportLab user guide, chapter 5 "PLATYPUS - Page Layout and Typography Using Scripts" (doc templates, frames,
flowables) and chapter 7 "Tables and TableStyles" (``repeatRows``, splitting by rows).
"""
from __future__ import annotations

import io
import os
from pathlib import Path
from xml.sax.saxutils import escape

import pandas as pd

from stridelab.reports.document import TITLES
from stridelab.reports.figures import png
from stridelab.reports.tables import fmt

FONT, BOLD, ITALIC = "DejaVuSans", "DejaVuSans-Bold", "DejaVuSans-Oblique"
#: table text size (pt), and the smallest it goes to before columns are narrowed and their cells wrap
TABLE_PT, TABLE_MIN_PT = 6.5, 5.0
MARGIN_PT = 36.0                           # left, right and bottom margin
CONTENT_TOP = 0.885                        # top of the text frame, fraction of the page height from the bottom
FIGURE_DPI = 160


def _fonts() -> None:
    from reportlab.lib.fonts import addMapping
    from reportlab.pdfbase import pdfmetrics
    from reportlab.pdfbase.ttfonts import TTFont
    if FONT in pdfmetrics.getRegisteredFontNames():
        return
    import matplotlib
    ttf = Path(matplotlib.get_data_path()) / "fonts" / "ttf"
    for name, file in ((FONT, "DejaVuSans.ttf"), (BOLD, "DejaVuSans-Bold.ttf"), (ITALIC, "DejaVuSans-Oblique.ttf"),
                       ("DejaVuSans-BoldOblique", "DejaVuSans-BoldOblique.ttf")):
        pdfmetrics.registerFont(TTFont(name, str(ttf / file)))
    addMapping(FONT, 0, 0, FONT)
    addMapping(FONT, 1, 0, BOLD)
    addMapping(FONT, 0, 1, ITALIC)
    addMapping(FONT, 1, 1, "DejaVuSans-BoldOblique")


def _styles() -> dict:
    from reportlab.lib.styles import ParagraphStyle
    base = ParagraphStyle("text", fontName=FONT, fontSize=8, leading=10.5, spaceAfter=3)
    return {"text": base,
            "note": ParagraphStyle("note", parent=base, fontName=ITALIC, textColor="#4d4d4d", spaceAfter=5),
            "heading": ParagraphStyle("heading", parent=base, fontName=BOLD, fontSize=9, leading=12, spaceBefore=4,
                                      keepWithNext=1),
            "table_title": ParagraphStyle("table_title", parent=base, fontName=BOLD, fontSize=9, leading=12,
                                          spaceBefore=4, spaceAfter=2),
            "caption": ParagraphStyle("caption", parent=base, fontName=BOLD, spaceBefore=2, spaceAfter=8)}


def _cell_style(size: float, bold: bool = False):
    from reportlab.lib.styles import ParagraphStyle
    return ParagraphStyle(f"cell{size}{bold}", fontName=BOLD if bold else FONT, fontSize=size, leading=size * 1.2)


def _header_width(label: str, font: str, size: float) -> float:
    """Width a column header needs when it may take two lines (split at a space)."""
    from reportlab.pdfbase.pdfmetrics import stringWidth
    words = label.split()
    best = stringWidth(label, font, size)
    for i in range(1, len(words)):
        best = min(best, max(stringWidth(" ".join(words[:i]), font, size),
                             stringWidth(" ".join(words[i:]), font, size)))
    return best


PAD = 3.0                                   # left + right cell padding (pt)


def column_widths(df: pd.DataFrame, cells: list[list[str]], room: float) -> tuple[list[float], float]:
    """Column widths (pt) from the content, headers on one line or else in two, and the font size: 6.5 pt, smaller
    down to 5 pt when the columns need more than ``room``; then the widest columns are narrowed (their cells
    wrap) until the table fits."""
    from reportlab.pdfbase.pdfmetrics import stringWidth

    def natural(size, two_lines=True):
        heads = [_header_width(str(c), BOLD, size) if two_lines else stringWidth(str(c), BOLD, size)
                 for c in df.columns]
        body = [max((stringWidth(r[k], FONT, size) for r in cells), default=0.0) for k in range(len(heads))]
        return [min(max(h, b) + PAD + 1, room * 0.6) for h, b in zip(heads, body)]

    size = TABLE_PT
    # headers on one line where the page is wide enough, the cells of the widest columns wrapping if need be
    w = natural(size, two_lines=False)
    heads = [stringWidth(str(c), BOLD, size) + PAD + 1 for c in df.columns]
    if sum(w) > room and sum(heads) <= room:
        c = _cap(w, room, heads)
        return [min(x, max(c, h)) for x, h in zip(w, heads)], size
    if sum(w) <= room:
        return w, size
    w = natural(size)
    if sum(w) > room:
        size = max(TABLE_MIN_PT, TABLE_PT * room / sum(w))
        w = natural(size)
    if sum(w) > room:                            # narrow the widest columns to one cap, so that all fit,
        # words whole where the page allows it (a column keeps its longest word's width)
        words = [max([stringWidth(x, BOLD, size) for x in str(c).split()] +
                     [stringWidth(x, FONT, size) for r in cells for x in r[k].split()] + [0.0]) + PAD + 1
                 for k, c in enumerate(df.columns)]
        floor = [min(f, x) for f, x in zip(words, w)] if sum(min(f, x) for f, x in zip(words, w)) <= room else None
        c = _cap(w, room, floor)
        w = [min(x, max(c, f)) for x, f in zip(w, floor or [12.0] * len(w))]
    return w, size


def _cap(w: list[float], room: float, floor: list[float] | None = None) -> float:
    """The largest cap c with sum(min(x, max(c, f))) <= room over the columns' widths x and floors f (12 pt by
    default): water filling, found by bisection."""
    floor = floor or [12.0] * len(w)
    lo, hi = 0.0, max(w)
    for _ in range(50):
        c = (lo + hi) / 2
        if sum(min(x, max(c, f)) for x, f in zip(w, floor)) <= room:
            lo = c
        else:
            hi = c
    return max(lo, 12.0)


def _table(title: str, df: pd.DataFrame, room: float, styles: dict) -> list:
    from reportlab.lib import colors
    from reportlab.pdfbase.pdfmetrics import stringWidth
    from reportlab.platypus import CondPageBreak, Paragraph, Table, TableStyle
    cells = [[fmt(v) for v in row] for row in df.itertuples(index=False)] or [["—"] * max(1, len(df.columns))]
    columns = [str(c) for c in df.columns] or [""]
    widths, size = column_widths(pd.DataFrame(columns=columns), cells, room)
    head_style, cell_style = _cell_style(size, bold=True), _cell_style(size)
    data = [[Paragraph(escape(c), head_style) for c in columns]]
    for r in cells:                              # a cell wider than its column wraps (a Paragraph); others stay text
        data.append([Paragraph(escape(v), cell_style) if stringWidth(v, FONT, size) + PAD > w else v
                     for v, w in zip(r, widths)])
    t = Table(data, colWidths=widths, repeatRows=1, hAlign="LEFT")
    t.setStyle(TableStyle([("FONT", (0, 0), (-1, -1), FONT, size, size * 1.2),
                           ("GRID", (0, 0), (-1, -1), 0.3, colors.HexColor("#999999")),
                           ("BACKGROUND", (0, 0), (-1, 0), colors.HexColor("#eeeeee")),
                           ("VALIGN", (0, 0), (-1, -1), "TOP"),
                           ("LEFTPADDING", (0, 0), (-1, -1), PAD / 2), ("RIGHTPADDING", (0, 0), (-1, -1), PAD / 2),
                           ("TOPPADDING", (0, 0), (-1, -1), 1), ("BOTTOMPADDING", (0, 0), (-1, -1), 1.5)]))
    # the title stays with the header and first rows (a new sheet if fewer fit); a long table then runs on
    # from there (KeepTogether / keepWithNext would move all of it to the next sheet first)
    first = 6 * (size * 1.2 + 2.5)               # a two-line header and three rows, about
    return [CondPageBreak(first + 20), Paragraph(escape(title), styles["table_title"]), t]


def _figure(caption: str, fig, room: float, max_h: float, styles: dict) -> list:
    from reportlab.platypus import Image, KeepTogether, Paragraph
    from PIL import Image as PILImage
    data = png(fig, FIGURE_DPI)
    with PILImage.open(io.BytesIO(data)) as im:
        px_w, px_h = im.size
    w, h = px_w / FIGURE_DPI * 72, px_h / FIGURE_DPI * 72
    scale = min(1.0, room / w, max_h / h)
    img = Image(io.BytesIO(data), width=w * scale, height=h * scale, hAlign="LEFT")
    return [KeepTogether([img, Paragraph(escape(caption), styles["caption"])])]


def _section_mark(doc, n: int):
    """A zero-size flowable at the start of report page ``n``: the running header knows which page it is on and
    whether this sheet continues it."""
    from reportlab.platypus import Flowable

    class SectionMark(Flowable):
        def wrap(self, *_):
            return 0, 0

        def draw(self):
            doc.section, doc.section_sheet = n, self.canv.getPageNumber()
    return SectionMark()


def render_pdf(d: dict, pages: dict, meta: dict, path: Path) -> None:
    """Write the report to ``path``: report page n starts a new A4 sheet, continuation sheets follow it."""
    from reportlab.lib.pagesizes import A4
    from reportlab.platypus import BaseDocTemplate, Frame, PageBreak, PageTemplate, Paragraph

    _fonts()
    styles = _styles()
    width, height = A4
    room = width - 2 * MARGIN_PT
    frame_h = height * CONTENT_TOP - MARGIN_PT
    frame = Frame(MARGIN_PT, MARGIN_PT, room, frame_h, id="content",
                  leftPadding=0, rightPadding=0, topPadding=0, bottomPadding=0)
    pid = d["participant_id"]

    def header_footer(canv, doc):
        n = getattr(doc, "section", 1)
        cont = canv.getPageNumber() != getattr(doc, "section_sheet", canv.getPageNumber())
        more = " (continued)" if cont else ""
        canv.saveState()
        canv.setFont(BOLD, 12)
        canv.drawString(MARGIN_PT, height * 0.965, f"StrideLab participant report: {pid}")
        canv.setFont(FONT, 8)
        canv.drawRightString(width - MARGIN_PT, height * 0.965, f"page {n} / {len(TITLES)}{more}")
        canv.setFont(FONT, 7)
        canv.setFillGray(0.35)
        canv.drawString(MARGIN_PT, height * 0.947,
                        f"Study {d['study']} · generated {meta['generated']} · snapshot {meta['snapshot']}")
        canv.setStrokeGray(0.2)
        canv.setLineWidth(0.8)
        canv.line(MARGIN_PT, height * 0.939, width - MARGIN_PT, height * 0.939)
        canv.setFillGray(0.0)
        canv.setFont(BOLD, 11)
        canv.drawString(MARGIN_PT, height * 0.902, f"{n}. {TITLES[n]}{more}")
        canv.setFont(FONT, 6.5)
        canv.setFillGray(0.4)
        canv.drawCentredString(width / 2, height * 0.025, f"{pid} · pseudonymised data · StrideLab {meta['version']}")
        canv.restoreState()

    doc = BaseDocTemplate(os.fspath(path), pagesize=A4, title=f"StrideLab report {pid}", author="StrideLab",
                          subject=f"study {d['study']}", creator="StrideLab", invariant=1,
                          leftMargin=MARGIN_PT, rightMargin=MARGIN_PT, topMargin=height * (1 - CONTENT_TOP),
                          bottomMargin=MARGIN_PT)
    doc.addPageTemplates([PageTemplate(id="report", frames=[frame], onPageEnd=header_footer)])
    story: list = []
    for k, n in enumerate(TITLES):
        if k:
            story.append(PageBreak())
        story.append(_section_mark(doc, n))
        for b in pages[n]:
            if b[0] in ("text", "note", "heading"):
                story.append(Paragraph(escape(b[1]), styles[b[0]]))
            elif b[0] == "table":
                story += _table(b[1], b[2], room, styles)
            elif b[0] == "figure":
                story += _figure(b[1], b[2], room, 0.8 * frame_h, styles)
            else:
                raise ValueError(f"unknown report block {b[0]!r}")
    doc.build(story)
