"""Open a report in headless Chromium (the distribution's package, driven by Playwright) and
measure what a reader would see: console errors, images, sections, horizontal overflow.

Playwright must not download browsers: the system Chromium is used through ``executable_path``
(``scripts/bootstrap.sh`` installs it with ``apt-get install chromium`` when missing).
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["find_chromium", "PageCheck", "inspect_page", "WIDTH", "PHONE"]

#: Viewport width of the overflow check (a laptop screen).
WIDTH = 1280
#: Viewport width of a phone (the ranking figure must read there too).
PHONE = 390


#: Text of every text node whose element starts within the first 900 px (the first screen).
_FIRST_SCREEN = """() => {
  const walk = document.createTreeWalker(document.body, NodeFilter.SHOW_TEXT);
  const out = [];
  while (walk.nextNode()) {
    const el = walk.currentNode.parentElement;
    if (el && el.getBoundingClientRect().top < 900) out.push(walk.currentNode.textContent);
  }
  return out.join('');
}"""


def find_chromium() -> str | None:
    """Path of the system Chromium (or Chrome), or None."""
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        if path := shutil.which(name):
            return path
    return None


@dataclass
class PageCheck:
    """What the page showed."""

    console_errors: list[str] = field(default_factory=list)
    broken_images: list[str] = field(default_factory=list)
    n_images: int = 0
    section_ids: list[str] = field(default_factory=list)
    scroll_width: int = 0
    first_screen_text: str = ""
    ranking_figure_top: float = float("inf")  # px from the top of the page to the ranking plot
    ranking_figure_width: tuple[float, float] = (0.0, 0.0)  # (shown, natural) px width of the ranking plot


def inspect_page(html: Path, screenshot: Path, chromium: str, width: int = WIDTH) -> PageCheck:
    """Load ``html`` at ``width`` px, wait for it, take a full-page ``screenshot``."""
    from playwright.sync_api import sync_playwright

    check = PageCheck()
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, headless=True, args=["--no-sandbox"])
        try:
            page = browser.new_page(viewport={"width": width, "height": 900})
            page.on("console", lambda m: check.console_errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: check.console_errors.append(str(e)))
            page.goto(html.resolve().as_uri(), wait_until="load")
            images = page.evaluate("Array.from(document.images).map(i => [i.alt, i.complete && i.naturalWidth > 0])")
            check.n_images = len(images)
            check.broken_images = [alt for alt, ok in images if not ok]
            check.section_ids = page.evaluate("Array.from(document.querySelectorAll('section')).map(s => s.id)")
            check.scroll_width = int(page.evaluate("document.documentElement.scrollWidth"))
            check.first_screen_text = page.evaluate(_FIRST_SCREEN)
            check.ranking_figure_top = float(page.evaluate(
                "(() => { const i = document.querySelector('#ranking img');"
                " return i ? i.getBoundingClientRect().top : Infinity; })()"))
            check.ranking_figure_width = tuple(page.evaluate(
                "(() => { const i = document.querySelector('#ranking img');"
                " return i ? [i.getBoundingClientRect().width, i.naturalWidth] : [0, 0]; })()"))
            page.screenshot(path=str(screenshot), full_page=True)
        finally:
            browser.close()
    return check
