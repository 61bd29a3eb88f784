"""Screenshots for the README and the docs, in Debian's headless Chromium (playwright-core drives it).

    python tools/screenshots.py dashboard PAGE OUT.png [--warehouse DIR]   # a page of the dashboard ('' = Overview)
    python tools/screenshots.py site URL OUT.png                           # any page, e.g. of the built docs site

Maintainers' tool (not run by the tests): the README's picture is ``docs/img/dashboard.png`` from
``make demo ARGS=--no-serve`` then ``python tools/screenshots.py dashboard programme docs/img/dashboard.png``.
"""
from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM = os.environ.get("STRIDELAB_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking", "--no-first-run"]


def shoot(url: str, out: Path, *, width=1280, height=800, streamlit=False, full_page=False) -> None:
    from playwright.sync_api import sync_playwright
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS, headless=True)
        page = browser.new_page(viewport={"width": width, "height": height})
        page.goto(url, wait_until="networkidle" if not streamlit else "domcontentloaded")
        if streamlit:
            page.wait_for_selector("h1", timeout=60_000)
            page.wait_for_function("() => !document.querySelector('[data-testid=\"stStatusWidget\"]')",
                                   timeout=60_000)
            try:
                page.locator(".js-plotly-plot").first.wait_for(timeout=20_000)
            except Exception:  # noqa: BLE001 - a page without a figure
                pass
            time.sleep(2)
        page.screenshot(path=str(out), full_page=full_page)
        browser.close()


def dashboard(page_path: str, out: Path, warehouse: Path) -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    proc = subprocess.Popen([sys.executable, "-m", "streamlit", "run", str(ROOT / "dashboard" / "app.py"),
                             "--server.port", str(port), "--server.address", "localhost", "--server.headless", "true",
                             "--browser.gatherUsageStats", "false", "--server.fileWatcherType", "none",
                             "--", "--warehouse", str(warehouse)],
                            env={**os.environ, "STRIDELAB_WAREHOUSE": str(warehouse)},
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        url = f"http://localhost:{port}"
        for _ in range(240):
            try:
                if urllib.request.urlopen(f"{url}/_stcore/health", timeout=1).status == 200:
                    break
            except OSError:
                time.sleep(0.25)
        shoot(f"{url}/{page_path}", out, width=1280, height=860, streamlit=True)
    finally:
        proc.terminate()
        proc.wait(10)


if __name__ == "__main__":
    kind, target, out = sys.argv[1:4]
    wh = Path(sys.argv[sys.argv.index("--warehouse") + 1]) if "--warehouse" in sys.argv else ROOT / "stridelab-home" / "warehouse"
    if kind == "dashboard":
        dashboard(target, Path(out), wh)
    else:
        shoot(target, Path(out), full_page=False)
    print(f"saved {out}")
