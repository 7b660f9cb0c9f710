"""The Tailwind rules the pages use, compiled once and kept in ``static/tailwind.css``.

NiceGUI normally compiles Tailwind in every browser: its script (260 kB) watches the page and
builds the rules for the classes it finds, some 60-90 ms of the page's main thread before a
new page shows its first values. The classes a page can carry are the ones written in this
program's source, so they are compiled here once instead, with the same compiler (NiceGUI's
``tailwindcss.min.js``, run in chromium) and the app runs with ``tailwind=False``.

Regenerate after changing classes (``tests/browser/test_stylesheet_browser.py`` fails until then)::

    python -m tools.stylesheet

Every word of every string in ``pages/``, ``app/`` and ``devices/`` is offered to the compiler:
it makes rules only for the words that are Tailwind classes, so a class written anywhere (in a
``.classes()`` call, a slot template or a table's row class) is covered; a few plain words that
happen to be class names ("hidden", "table") give rules nothing on the page uses. The classes
Quasar and plotly add themselves are listed in ``RENDERED_CLASSES``.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SOURCES = ("pages", "app", "devices")
STYLESHEET = ROOT / "static" / "tailwind.css"
# as NiceGUI's page template gives it to the compiler
PRELUDE = "@custom-variant dark (&:where(body.body--dark, body.body--dark *));"
TOKEN = re.compile(r"[a-z!-][a-z0-9:\-\[\]/.%_#()!,]*")
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking"]
# classes Quasar and plotly put on the pages themselves (found on the demo plant's pages by
# tests/browser/test_stylesheet_browser.py): the compiler in the browser made rules for them too,
# the same as Quasar's and plotly's own
RENDERED_CLASSES = (
    "absolute", "flex", "inline", "justify-center", "overflow-hidden", "self-stretch",
    "text-center", "text-left", "text-right", "cursor-pointer", "cursor-crosshair",
    "cursor-e-resize", "cursor-ew-resize", "cursor-n-resize", "cursor-ne-resize", "cursor-ns-resize",
    "cursor-nw-resize", "cursor-s-resize", "cursor-se-resize", "cursor-sw-resize", "cursor-w-resize",
)


def class_tokens(root: Path = ROOT) -> list[str]:
    """Every word in a string literal of the program's source that could be a class name, and
    the classes Quasar and plotly add, sorted."""
    tokens: set[str] = set(RENDERED_CLASSES)
    for folder in SOURCES:
        for path in sorted((root / folder).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.Constant) and isinstance(node.value, str):
                    tokens.update(t for t in re.split(r"[\s'\"`{}]+", node.value)
                                  if len(t) < 60 and TOKEN.fullmatch(t))
    return sorted(tokens)


def compile_css(tokens: list[str], browser=None, chromium: str = "/usr/bin/chromium") -> str:
    """Tailwind's rules for ``tokens``, from NiceGUI's own compiler in a chromium page (in
    ``browser``, a playwright browser, or in one started for it)."""
    if browser is None:
        from playwright.sync_api import sync_playwright

        with sync_playwright() as p:
            started = p.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)
            try:
                return compile_css(tokens, started)
            finally:
                started.close()
    import html

    import nicegui

    compiler = (Path(nicegui.__file__).parent / "static" / "tailwindcss.min.js").read_text(encoding="utf-8")
    page_html = (f'<!doctype html><html><head><style type="text/tailwindcss">{PRELUDE}</style></head><body>'
                 f'<div class="{html.escape(" ".join(tokens))}"></div></body></html>')
    page = browser.new_page()
    try:
        page.set_content(page_html)
        page.add_script_tag(content=compiler)
        found = "() => [...document.querySelectorAll('style')].map(s => s.textContent).find(t => t.includes('tailwindcss v'))"
        page.wait_for_function(found, timeout=20_000)
        page.wait_for_timeout(300)  # the compiler writes once more after its first pass if classes were late
        css = page.evaluate(found)
    finally:
        page.close()
    return css.strip() + "\n"


def utility_classes(css: str) -> set[str]:
    """The class names the ``utilities`` layer of ``css`` has rules for (as written, escaped)."""
    if "@layer utilities {" not in css:
        return set()
    return set(re.findall(r"^  \.((?:\\.|[^\s{,:])+)", css.split("@layer utilities {", 1)[1], re.M))


def build(browser=None) -> str:
    """The stylesheet for the source as it is now."""
    return compile_css(class_tokens(), browser)


def main() -> int:
    tokens = class_tokens()
    css = compile_css(tokens)
    STYLESHEET.write_text(css, encoding="utf-8")
    print(f"{STYLESHEET.relative_to(ROOT)}: {len(css):,} bytes for {len(tokens):,} words of the source")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
