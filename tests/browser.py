"""The real browser of the page tests (Debian's Chromium driven by Playwright) and the local servers they open:
one helper for the dashboard's pages (tests/dashboard) and the live page (tests/live)."""
from __future__ import annotations

import os
import shutil
import socket
import subprocess
import time
import urllib.request
from contextlib import contextmanager
from pathlib import Path

import pytest

CHROMIUM = os.environ.get("STRIDELAB_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]


def require_chromium() -> None:
    """Skip the test (with what to install) where Chromium or Playwright is missing; fail a test that drives the
    browser without the ``browser`` marker (``make test-fast`` leaves those out)."""
    from tests.conftest import _RUNNING
    item = _RUNNING[-1] if _RUNNING else None
    if item is not None and item.get_closest_marker("browser") is None:
        pytest.fail(f"{item.nodeid} drives Chromium but is not marked browser: add @pytest.mark.browser",
                    pytrace=False)
    if not Path(CHROMIUM).exists():
        pytest.skip(f"Chromium not found at {CHROMIUM}: apt-get install chromium (or set STRIDELAB_CHROMIUM)")
    pytest.importorskip("playwright", reason="pip install playwright (its browser download is not needed)")


def free_port() -> int:
    """A localhost port nobody listens on now (the OS picks it: tests never bind fixed ports)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_until_serving(proc: subprocess.Popen, url: str, what: str, attempts: int = 240) -> None:
    """Poll ``url`` until it answers 200 (about 0.25 s apart); fail with the server's output if it exits."""
    for _ in range(attempts):
        if proc.poll() is not None:
            pytest.fail(f"{what} exited {proc.returncode}: {proc.stdout.read()[-2000:] if proc.stdout else ''}")
        try:
            with urllib.request.urlopen(url, timeout=1) as resp:
                if resp.status == 200:
                    return
        except OSError:
            time.sleep(0.25)
    pytest.fail(f"{what} did not answer {url} after {attempts} attempts")


def stop(proc: subprocess.Popen, timeout: float = 15) -> None:
    """Terminate a server this test started, kill it if it does not go."""
    proc.terminate()
    try:
        proc.wait(timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(5)


@contextmanager
def chromium(*extra_args: str):
    """A headless Chromium (Playwright's ``Browser``), closed afterwards; skips without Chromium/Playwright."""
    require_chromium()
    from playwright.sync_api import sync_playwright
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=[*CHROMIUM_ARGS, *extra_args], headless=True)
        try:
            yield browser
        finally:
            browser.close()


def new_page(browser, errors: list):
    """A 1400 x 1000 page whose uncaught JavaScript errors are appended to ``errors``."""
    page = browser.new_page(viewport={"width": 1400, "height": 1000})
    page.on("pageerror", lambda e: errors.append(str(e)))
    return page


def open_streamlit_page(page, url: str, *, heading: str | None = None, timeout_ms: int = 30_000) -> None:
    """Go to ``url`` and wait until the page's heading (``heading``'s role heading, else any ``h1``) is there and
    Streamlit's script run has finished (it renders in steps: no 'running' status widget left)."""
    page.goto(url, wait_until="domcontentloaded")
    if heading:
        page.get_by_role("heading", name=heading).wait_for(timeout=timeout_ms)
    else:
        page.wait_for_selector("h1", timeout=timeout_ms)
    page.wait_for_function("() => !document.querySelector('[data-testid=\"stStatusWidget\"]')",
                           timeout=timeout_ms)
