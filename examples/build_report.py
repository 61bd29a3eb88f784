"""Build a participant's report
===============================

``stridelab.reports.participant.build_report`` writes the per-participant report (self-contained HTML and a PDF) from the
newest snapshot, as ``stridelab report PID`` and the nightly run do: sessions, gait parameters with their
accuracy against the reference, the change between visits against its MDC95, daily activity. The figure is the
PDF's first page (rendered with ``pdftoppm`` from poppler-utils, when installed).
"""
import shutil
import subprocess
import tempfile
from pathlib import Path

import stridelab
from _common import home, out, saved
from stridelab.reports.participant import build_report

h = home()
with stridelab.open(h) as wh:
    pid = wh.participants()["participant_id"].iloc[-1]
with tempfile.TemporaryDirectory() as tmp:
    paths = build_report(h / "warehouse", pid, Path(tmp))
    for kind, p in paths.items():
        print(f"{kind}: {Path(p).name} ({Path(p).stat().st_size // 1024} KiB)")
    pdf = Path(paths["pdf"])
    shutil.copy(pdf, out(f"report_{pid}.pdf"))
    if shutil.which("pdftoppm"):
        subprocess.run(["pdftoppm", "-png", "-r", "50", "-f", "1", "-l", "1", "-singlefile", str(pdf),
                        str(out("build_report").with_suffix(""))], check=True)
        saved(out("build_report.png"))
    else:
        print("pdftoppm not found (apt-get install poppler-utils): the PDF is saved, no PNG of its first page")
saved(out(f"report_{pid}.pdf"))
