"""Open the smoke leaderboard in headless Chromium: tables sort, figures render."""

from __future__ import annotations

import contextlib
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from .conftest import SuiteRun

# one xdist worker runs every test of the smoke_run fixture, so the smoke suite runs once
pytestmark = pytest.mark.xdist_group("smoke_run")

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
# The smoke page measured 10,981 px tall at 1400 px before the figures were reworked (one
# 3626-px strip of scatter panels, per-encoder figures and provenance open) and 7,389 px after.
MAX_HEIGHT_1400 = 9_000



@contextlib.contextmanager
def _page(sync_api: Any, path: Path, width: int) -> Iterator[tuple[Any, Any]]:
    """Debian's Chromium, headless, on ``path`` at ``width`` px; asserts that the page loads
    nothing from the network."""
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=[
            "--no-sandbox", "--disable-gpu", "--disable-background-networking",
            "--disable-component-update", "--disable-sync", "--no-first-run"])
        page = browser.new_page(viewport={"width": width, "height": 900})
        requests: list[str] = []
        page.on("request", lambda r: requests.append(r.url))
        page.goto(path.as_uri())
        assert all(u.startswith(("file:", "data:")) for u in requests), requests
        yield browser, page


def test_leaderboard_in_headless_chromium(smoke_run: SuiteRun) -> None:
    sync_api = pytest.importorskip("playwright.sync_api")
    if not Path(CHROMIUM).exists():
        pytest.skip("Debian chromium is not installed (apt-get install chromium)")
    page_path = smoke_run.out / "index.html"
    assert page_path.is_file(), smoke_run.stdout[-2000:]
    with _page(sync_api, page_path, width=1280) as (browser, page):
        images = page.eval_on_selector_all("img", "els => els.map(e => e.naturalWidth)")
        assert len(images) >= 4 and all(w > 100 for w in images)

        def column(table: str, header: str) -> list[str]:
            idx = page.eval_on_selector_all(
                f"#{table} th", f"ths => ths.findIndex(t => t.textContent.trim() === '{header}')")
            assert idx >= 0, f"{table} has no column {header}"
            return page.eval_on_selector_all(
                f"#{table} tbody tr", f"rows => rows.map(r => r.cells[{idx}].dataset.v)")

        page.click("#encoders th:has-text('encoder')")
        names = column("encoders", "encoder")
        assert names == sorted(names)
        page.click("#encoders th:has-text('encoder')")
        assert column("encoders", "encoder") == sorted(names, reverse=True)
        page.click("#metrics th:text-is('spearman')")
        rho = [float(v) for v in column("metrics", "spearman") if v != ""]
        assert rho == sorted(rho)
        shot = smoke_run.out / "screenshot.png"
        page.screenshot(path=str(shot), full_page=True)
        browser.close()
    assert shot.stat().st_size > 10_000


def test_leaderboard_reads_in_a_minute(smoke_run: SuiteRun) -> None:
    """At 1400 px the page is short by default (per-encoder figures and provenance closed),
    and the metric-vs-return figure names each point's encoder on hover."""
    sync_api = pytest.importorskip("playwright.sync_api")
    if not Path(CHROMIUM).exists():
        pytest.skip("Debian chromium is not installed (apt-get install chromium)")
    with _page(sync_api, smoke_run.out / "index.html", width=1400) as (browser, page):
        height = page.evaluate("document.documentElement.scrollHeight")
        assert height < MAX_HEIGHT_1400, height
        details = page.eval_on_selector_all("details", "els => els.map(e => e.open)")
        assert len(details) >= 3 and not any(details)  # per-encoder figures + provenance
        assert page.eval_on_selector_all(".per-encoder details img", "els => els.length") >= 2
        titles = page.eval_on_selector_all(
            "svg g[id^='mvr-'] > title", "els => els.map(e => e.textContent)")
        encoders = page.eval_on_selector_all(
            "#encoders tbody tr", "rows => rows.map(r => r.cells[1].dataset.v)")
        assert len(titles) >= len(encoders) > 0
        assert all(any(t.startswith(e + " (") for t in titles) for e in encoders)
        width = page.eval_on_selector(".svgfig svg", "e => e.getBoundingClientRect().width")
        assert width > 900  # the panels are large enough to read
        page.click(".per-encoder summary >> nth=0")
        assert page.eval_on_selector(".per-encoder details", "e => e.open")
        assert page.evaluate("document.documentElement.scrollHeight") > height
        browser.close()
