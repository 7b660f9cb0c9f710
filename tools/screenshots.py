"""The screenshots of the README and the guide, taken from the running demo plant.

Starts ``commission`` on the built-in demo plant (its simulated TCP endpoints on free ports, its
data in a temporary folder), waits until every device is online, and photographs pages in
Debian's chromium through playwright (no browser download)::

    python -m tools.screenshots            # writes docs/img/*.png
    python -m tools.screenshots --out DIR

Run it again after a page changed, so the pictures never show an older program.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
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
                # the page is drawn: its fonts are in, nothing is waiting for the server
                page.evaluate("document.fonts.ready")
                page.wait_for_load_state("networkidle", timeout=timeout_ms)
                target = out / name
                page.screenshot(path=str(target))
                written.append(target)
                print(f"{target.relative_to(ROOT) if target.is_relative_to(ROOT) else target}: {url}{path}")
        finally:
            browser.close()
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.screenshots", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=OUT, help=f"folder for the PNG files (default {OUT.relative_to(ROOT)})")
    args = parser.parse_args(argv)
    if not Path(CHROMIUM).exists():
        print(f"{CHROMIUM} is not installed: apt-get install chromium (or run bash .ci/run once)", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="commission-screenshots-") as folder:
        with running_app(demo_plant_text(), Path(folder)) as url:
            wait_devices_online(url, timeout=60)
            take(url, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
