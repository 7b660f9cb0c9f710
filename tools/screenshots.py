"""The screenshots of the README and the guide, taken from the running demo plant.

Starts ``commission`` on the built-in demo plant (its simulated TCP endpoints on free ports, its
data in a temporary folder), waits until every device is online, and photographs pages in
Debian's chromium through playwright (no browser download)::

    python -m tools.screenshots            # writes docs/img/*.png
    python -m tools.screenshots --out DIR
    python -m tools.screenshots --every-page --out DIR   # every page, in German and English, at two sizes

``--every-page`` follows every link of the app from the overview (each path once, its query left out) and writes
``DIR/<lang>/<width>x<height>/<page>.png`` for German and English at 1440x900 (a laptop) and 768x1024 (a tablet),
for a person to look at after a change of pages or of the catalogs.

Run it again after a page changed, so the pictures never show an older program.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.append(str(ROOT / "bench"))

from liveapp import CHROMIUM, CHROMIUM_ARGS, demo_plant_text, need_playwright, running_app, wait_devices_online  # noqa: E402

OUT = ROOT / "docs" / "img"
VIEWPORT = {"width": 1440, "height": 900}

#: file name, page path, a text the page shows once its values are in, whether to wait for a chart
SHOTS = (
    ("overview.png", "/", "door-1", False),
    ("device-hdlock.png", "/device/door-1", "LockStatus", True),
    ("device-electrak.png", "/device/lift", "Take control", True),
    ("plant-view.png", "/plant", "door-1", False),
)


def take(url: str, out: Path, timeout_ms: int = 30_000) -> list[Path]:
    """Photograph every page of SHOTS from the app at ``url`` into ``out``; returns the files written."""
    sync_playwright = need_playwright()
    out.mkdir(parents=True, exist_ok=True)
    written = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            context = browser.new_context(viewport=VIEWPORT)
            page = context.new_page()
            for name, path, text, chart in SHOTS:
                page.goto(url + path, wait_until="networkidle", timeout=timeout_ms)
                page.get_by_text(text).first.wait_for(state="visible", timeout=timeout_ms)
                if chart:
                    page.locator(".js-plotly-plot .main-svg").first.wait_for(state="visible", timeout=timeout_ms)
                settle(page, timeout_ms)
                target = out / name
                page.screenshot(path=str(target))
                written.append(target)
                print(f"{target.relative_to(ROOT) if target.is_relative_to(ROOT) else target}: {url}{path}")
        finally:
            browser.close()
    return written


#: the sizes of --every-page: an engineer's laptop and an operator's tablet
SIZES = (VIEWPORT, {"width": 768, "height": 1024})
#: paths --every-page does not photograph: downloads, the API and its documentation, logging out
NOT_PAGES = ("/api/", "/docs", "/redoc", "/openapi.json", "/logout", "/_nicegui")


def slug(path: str) -> str:
    """A file name for a page's path: ``/device/door-1`` -> ``device_door-1``, ``/`` -> ``overview``."""
    return path.strip("/").replace("/", "_") or "overview"


def settle(page, timeout_ms: int) -> None:
    """Wait until ``page`` is drawn: its fonts in, nothing waiting for the server."""
    page.evaluate("document.fonts.ready")
    page.wait_for_load_state("networkidle", timeout=timeout_ms)


def crawl(page, url: str, timeout_ms: int, limit: int | None = None) -> Iterator[str]:
    """Every page linked from the overview, followed breadth first (``limit`` at most): ``page`` is taken to each in
    turn and settled, and its path yielded; a bus monitor's tools (buttons) count as links."""
    todo, seen = ["/", "/login"], {"/", "/login"}
    while todo and (limit is None or len(seen) <= limit):
        path = todo.pop(0)
        page.goto(url + path, wait_until="networkidle", timeout=timeout_ms)
        settle(page, timeout_ms)
        links = page.eval_on_selector_all("a[href^='/']", "links => links.map(a => a.getAttribute('href'))")
        tools = page.eval_on_selector_all("[data-monitor^='tool-']", "bs => bs.map(b => b.dataset.monitor.slice(5))")
        for href in links + [f"{path}/{tool}" for tool in tools]:
            link = href.split("?")[0].split("#")[0]
            if link not in seen and not link.startswith(NOT_PAGES) and "." not in link.rsplit("/", 1)[-1]:
                seen.add(link)
                todo.append(link)
        yield path


@contextlib.contextmanager
def demo_plant(prefix: str) -> Iterator[str]:
    """``commission`` on the built-in demo plant (its data in a temporary folder) with every device online: its URL."""
    with tempfile.TemporaryDirectory(prefix=prefix) as folder, running_app(demo_plant_text(), Path(folder)) as url:
        wait_devices_online(url, timeout=60)
        yield url


def no_chromium() -> bool:
    """Whether Debian's chromium is missing (said on stderr, with what to do)."""
    if Path(CHROMIUM).exists():
        return False
    print(f"{CHROMIUM} is not installed: apt-get install chromium (or run bash .ci/run once)", file=sys.stderr)
    return True


def every_page(url: str, out: Path, langs=("de", "en"), limit: int = 80, timeout_ms: int = 30_000) -> list[Path]:
    """Every page linked from the overview (followed breadth first, ``limit`` at most), photographed in each of
    ``langs`` at each of SIZES into ``out/<lang>/<w>x<h>/``; returns the files written."""
    sync_playwright = need_playwright()
    written: list[Path] = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            for lang in langs:
                context = browser.new_context(viewport=SIZES[0])
                page = context.new_page()
                page.goto(f"{url}/?lang={lang}", wait_until="networkidle", timeout=timeout_ms)  # kept for this browser
                for path in crawl(page, url, timeout_ms, limit):  # each page loaded at the laptop's size
                    for size in SIZES:
                        width, height = size["width"], size["height"]
                        page.set_viewport_size(size)
                        page.wait_for_function("([w, h]) => innerWidth === w && innerHeight === h", arg=[width, height])
                        settle(page, timeout_ms)
                        target = out / lang / f"{width}x{height}" / f"{slug(path)}.png"
                        target.parent.mkdir(parents=True, exist_ok=True)
                        page.screenshot(path=str(target), full_page=True)
                        written.append(target)
                    page.set_viewport_size(SIZES[0])
                    print(f"{lang} {path}: {len(SIZES)} sizes", flush=True)
                context.close()
        finally:
            browser.close()
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.screenshots", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=OUT, help=f"folder for the PNG files (default {OUT.relative_to(ROOT)})")
    parser.add_argument("--every-page", action="store_true",
                        help="every page linked from the overview, in German and English, at 1440x900 and 768x1024")
    args = parser.parse_args(argv)
    if no_chromium():
        return 2
    with demo_plant("commission-screenshots-") as url:
        if args.every_page:
            written = every_page(url, args.out)
            print(f"{len(written)} screenshots in {args.out}")
        else:
            take(url, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
