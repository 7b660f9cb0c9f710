"""The pages' Tailwind rules are compiled beforehand (tools/stylesheet.py), not in every browser."""

from __future__ import annotations

from pathlib import Path

import pytest
from webutil import demo_plant_text, free_port, running_app, settled

from tools.stylesheet import STYLESHEET, build, class_tokens, compile_css, utility_classes

pytestmark = pytest.mark.timeout(180)

PAGES = ("/", "/plant", "/device/door-1", "/device/lift-1", "/device/heater-hm", "/backup")


def test_the_stylesheet_is_compiled_from_the_source_as_it_is(chromium):
    assert STYLESHEET.read_text(encoding="utf-8") == build(chromium), (
        "classes changed since static/tailwind.css was made: run `python -m tools.stylesheet`")
    assert {"w-full", "gap-2", "items-center"} <= utility_classes(STYLESHEET.read_text(encoding="utf-8"))


def test_every_tailwind_class_on_the_pages_has_its_rule_and_no_compiler_runs(chromium, tmp_path: Path):
    ours = utility_classes(STYLESHEET.read_text(encoding="utf-8"))
    seen: set[str] = set()
    with running_app(demo_plant_text(free_port()), tmp_path) as url:
        page = chromium.new_page(viewport={"width": 1440, "height": 900})
        for path in PAGES:
            page.goto(url + path)
            settled(page)  # live values, charts and their classes in
            seen |= set(page.evaluate("() => [...document.querySelectorAll('[class]')].flatMap(e => [...e.classList])"))
            scripts = page.evaluate("() => [...document.scripts].map(s => s.src)")
            assert not any("tailwindcss" in src for src in scripts), path
        full = page.locator(".w-full").first  # a rule from the stylesheet is applied
        assert full.evaluate("e => getComputedStyle(e).width === getComputedStyle(e.parentElement).width "
                             "|| getComputedStyle(e).width === (e.parentElement.clientWidth "
                             "- parseFloat(getComputedStyle(e.parentElement).paddingLeft) "
                             "- parseFloat(getComputedStyle(e.parentElement).paddingRight)) + 'px'")
        page.close()
    needed = utility_classes(compile_css(sorted(seen), chromium))
    missing = needed - ours
    assert not missing, (f"classes on the pages with no rule in static/tailwind.css: {sorted(missing)}; add them to "
                         "RENDERED_CLASSES in tools/stylesheet.py if Quasar or plotly put them there, then regenerate")
    assert len(class_tokens()) > 1000
