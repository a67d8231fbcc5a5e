"""Open the smoke leaderboard in headless Chromium: tables sort, figures render."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from .conftest import SuiteRun

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"


def test_leaderboard_in_headless_chromium(smoke_run: SuiteRun) -> None:
    sync_api = pytest.importorskip("playwright.sync_api")
    if not Path(CHROMIUM).exists():
        pytest.skip("Debian chromium is not installed (apt-get install chromium)")
    page_path = smoke_run.out / "index.html"
    assert page_path.is_file(), smoke_run.stdout[-2000:]
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=[
            "--no-sandbox", "--disable-gpu", "--disable-background-networking",
            "--disable-component-update", "--disable-sync", "--no-first-run"])
        page = browser.new_page(viewport={"width": 1280, "height": 900})
        requests: list[str] = []
        page.on("request", lambda r: requests.append(r.url))
        page.goto(page_path.as_uri())
        assert all(u.startswith(("file:", "data:")) for u in requests), requests
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
