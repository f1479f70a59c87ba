"""Headless Debian chromium driven by playwright, shared by the monitor's browser tests.

Never downloads a browser: the tests are skipped where ``chromium`` is not installed (CI
installs it with apt-get). Waits are playwright's auto-waiting ``expect`` and
``wait_for_function``, each with a timeout — never sleeps.
"""

from __future__ import annotations

import contextlib
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from support import ROOT

CHROMIUM = shutil.which("chromium")
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None, reason="Debian's chromium is not installed (CI installs it: apt-get install chromium)"
)
ARTIFACTS = ROOT / "test-artifacts"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


class BrowserPage:
    """An open page, the JavaScript errors it logged, and the helpers the tests use."""

    prefix = "page"  # screenshot names: test-artifacts/PREFIX-NAME.png

    def __init__(self, page: Any, errors: list[str], timeout_ms: int) -> None:
        self.page, self.errors, self.timeout_ms = page, errors, timeout_ms

    def js(self, expression: str) -> Any:
        return self.page.evaluate(expression)

    def wait(self, expression: str, arg: Any = None) -> Any:
        return self.page.wait_for_function(expression, arg=arg, timeout=self.timeout_ms)

    def number(self, element_id: str) -> float:
        return float(self.js(f"Number(document.getElementById('{element_id}').dataset.value)"))

    def shot(self, name: str) -> Path:
        ARTIFACTS.mkdir(exist_ok=True)
        path = ARTIFACTS / f"{self.prefix}-{name}.png"
        # bytes, written here: screenshot(path=...) would leave an executor thread in playwright's loop
        path.write_bytes(self.page.screenshot())
        return path


@contextlib.contextmanager
def open_page(url: str, timeout_ms: int) -> Iterator[tuple[Any, list[str]]]:
    """Launch chromium, open ``url``; yields ``(page, errors)``; closes everything after."""
    from playwright.sync_api import sync_playwright

    pw = browser = None
    try:
        pw = sync_playwright().start()
        browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1400, "height": 860})
        page.set_default_timeout(timeout_ms)
        errors: list[str] = []
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.on("console", lambda msg: errors.append(msg.text) if msg.type == "error" else None)
        page.goto(url)
        yield page, errors
    finally:
        if browser is not None:
            browser.close()
        if pw is not None:
            pw.stop()


def expect(locator: Any) -> Any:
    """playwright's auto-waiting ``expect`` (imported lazily: playwright is a test extra)."""
    from playwright.sync_api import expect as pw_expect

    return pw_expect(locator)
