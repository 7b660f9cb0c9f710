"""Every page of the running demo plant in one language, and the lines on it that read as the other one.

Starts ``commission`` on the built-in demo plant (as ``tools.screenshots`` does), follows every link of the app
from the overview in Debian's chromium, and reads each page's visible text and tooltips once its values are in::

    python -m tools.language_walk              # German pages: lines that read as English
    python -m tools.language_walk --lang en    # English pages: lines that read as German
    python -m tools.language_walk --json FILE  # the lines found, by page

A German line reads as English when it is a text of the English catalog whose German differs, or has English
function words ("the", "not", "after" ...); an English line reads as German when it has German function words or
umlauts. Both are heuristics for a person to read through: the documents' own names (``GnApl bei Vorwarnung vor
dem Öffnen blinken``, ``LockRequestDelay``), the bytes a line carried and Material icons' ligatures (``warning``)
are listed too. The tests (tests/pages/test_i18n_pages.py, tests/browser/test_i18n_browser.py) check the catalog's
texts exactly; this walk looks at every page at once.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.append(str(ROOT / "bench"))

from liveapp import CHROMIUM, CHROMIUM_ARGS, need_playwright  # noqa: E402
from tools.screenshots import VIEWPORT, crawl, demo_plant, no_chromium  # noqa: E402

ENGLISH = set("the of and to is are not from with after before when which this that be by or it its on for no any has "
              "have only until then than must may".split())
GERMAN = set("der die das und nicht ist mit von für auf bei ein eine einer wird werden oder den dem des sich nach zu im "
             "am vom zum zur".split())
TRAFFIC = re.compile(r"^\d\d:\d\d:\d\d\S*\t")  # a row of a bus monitor: its time first


def english_catalog() -> set[str]:
    """The English texts of the catalog whose German differs (with a letter in them)."""
    from babel.messages.pofile import read_po

    with open(ROOT / "locale" / "de" / "LC_MESSAGES" / "messages.po", "rb") as f:
        return {m.id for m in read_po(f) if isinstance(m.id, str) and m.id and m.string != m.id
                and any(c.isalpha() for c in m.id)}


def reads_as(lang: str, catalog: set[str]):
    """Whether a line of a ``lang`` page reads as the other language."""
    if lang == "de":
        def other(line: str) -> bool:
            words = [w.lower() for w in re.findall(r"[A-Za-z]+", line)]
            return line in catalog or sum(w in ENGLISH for w in words) >= 2 or (len(words) <= 4 and any(w in ENGLISH for w in words))
    else:
        def other(line: str) -> bool:
            return any(c in line for c in "äöüÄÖÜß") or any(w in GERMAN for w in re.findall(r"[A-Za-zÄÖÜäöüß]+", line))
    return other


def walk(url: str, lang: str, timeout_ms: int = 30_000) -> dict[str, list[str]]:
    other = reads_as(lang, english_catalog() if lang == "de" else set())
    found: dict[str, list[str]] = {}
    with need_playwright()() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_context(viewport=VIEWPORT).new_page()
            page.goto(f"{url}/?lang={lang}", wait_until="networkidle", timeout=timeout_ms)  # kept for this browser
            for path in crawl(page, url, timeout_ms):
                lines = page.evaluate("document.body.innerText").split("\n")
                lines += page.eval_on_selector_all("[title]", "es => es.map(e => e.title)")
                found[path] = sorted({line.strip() for line in lines if line.strip() and other(line.strip())})
                print(f"{path}: {len(found[path])}", file=sys.stderr, flush=True)
        finally:
            browser.close()
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.language_walk", description=__doc__.split("\n\n")[0])
    parser.add_argument("--lang", choices=("de", "en"), default="de", help="the pages' language (default de)")
    parser.add_argument("--json", type=Path, help="write the lines found, by page, into this file")
    parser.add_argument("--traffic", action="store_true", help="list the bus monitors' rows of traffic too")
    args = parser.parse_args(argv)
    if no_chromium():
        return 2
    with demo_plant("commission-walk-") as url:
        found = walk(url, args.lang)
    if not args.traffic:
        found = {path: [line for line in lines if not TRAFFIC.match(line)] for path, lines in found.items()}
    if args.json:
        args.json.write_text(json.dumps(found, indent=1, ensure_ascii=False), encoding="utf-8")
    counts = Counter(line for lines in found.values() for line in lines)
    first = {line: path for path, lines in reversed(found.items()) for line in lines}
    for line, n in counts.most_common():
        print(f"{n:3d}  {first[line]:28s}  {line[:160]}")
    print(f"{len(found)} pages, {len(counts)} distinct lines that read as {'English' if args.lang == 'de' else 'German'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
