"""The report pages in headless Chromium: they load offline, render, and log no errors.

Needs the Debian ``chromium`` package and the ``playwright`` Python package (its own
browser download is not used). Set ``BRAKETHERMO_SCREENSHOTS=DIR`` to keep the
screenshots for a look.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from _synth_race import estimate_frame, make_session, race_frame

from brakethermo.report.lap_report import write_session_report

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
pytestmark = pytest.mark.skipif(
    CHROMIUM is None, reason="chromium is not installed (apt-get install -y chromium)"
)
ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


def render_offline(pages: list[tuple[str, Path]], shots: Path,
                   then=None) -> list[str]:
    """Open each page in headless Chromium with the network refused; screenshot it.

    Returns every console error or warning, page error, failed or network request; each
    page's images must decode. ``then(page)`` runs on the last page (e.g. a click).
    """
    sync_api = pytest.importorskip("playwright.sync_api", reason="pip install playwright")
    shots.mkdir(parents=True, exist_ok=True)
    problems: list[str] = []
    with sync_api.sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": 1280, "height": 900})
        page.on(
            "console",
            lambda m: (
                problems.append(f"console {m.type}: {m.text}")
                if m.type in ("error", "warning")
                else None
            ),
        )
        page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
        page.on("requestfailed", lambda r: problems.append(f"request failed: {r.url}"))
        # Everything must come from the page itself: refuse any network request.
        page.route(
            "http*://**",
            lambda route: (problems.append(f"network: {route.request.url}"), route.abort()),
        )
        for name, page_path in pages:
            page.goto(page_path.as_uri())
            page.wait_for_load_state("load")
            widths = page.eval_on_selector_all("img", "els => els.map(e => e.naturalWidth)")
            assert widths and all(w > 0 for w in widths), f"{name}: an image did not decode"
            page.screenshot(path=str(shots / f"{name}.png"), full_page=True)
        if then is not None:
            then(page)
        browser.close()
    return problems


def screenshots(tmp_path: Path) -> Path:
    return Path(os.environ.get("BRAKETHERMO_SCREENSHOTS", tmp_path / "shots"))


def test_pages_render_without_console_errors(tmp_path: Path) -> None:
    frame = race_frame(2, seed=3)
    est, radii = estimate_frame(frame)
    out = tmp_path / "race"
    session = make_session(frame, tmp_path / "race.mcap")
    write_session_report(est, session, out, node_radii=radii)
    shots = screenshots(tmp_path)

    def back_to_index(page) -> None:
        page.click("text=all laps")
        assert page.url.endswith("/race/index.html")

    problems = render_offline([("index", out / "index.html"),
                               ("lap_01", out / "lap_01" / "index.html")], shots,
                              then=back_to_index)
    assert problems == []
    assert (shots / "lap_01.png").stat().st_size > 50_000
