"""The README and docs/ say what the program does: every page path they name is a route of the app,
every ``commission ...`` command line they show parses with the CLI's own parser, every link
between them resolves (files, images and #anchors), and every docs page is linked from the README.
"""

from __future__ import annotations

import ast
import contextlib
import io
import itertools
import re
import shlex
from pathlib import Path

import pytest

from app.cli import build_parser

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
DOCS = ROOT / "docs"
PAGES = [README, *sorted(DOCS.glob("*.md"))]
ROUTE_SOURCES = (ROOT / "server" / "__init__.py", ROOT / "app" / "web.py")
DEMO_PLANT = ROOT / "plants" / "demo.toml"

#: paths in backticks that are not pages of this app, and why
NOT_ROUTES = {
    "/can/<bus>": "an MCAP channel name",
    "/points/<device>": "an MCAP channel name",
    "/_nicegui/client/ID/upload/N": "NiceGUI's own upload route",
}
#: first words of file-system paths (/dev/ttyUSB0, /proc/net/udp, /usr/bin/chromium): never pages
FILE_SYSTEM = {"dev", "proc", "sys", "usr", "etc", "tmp", "home", "var", "opt", "bin", "lib", "run", "mnt", "Library", "Users"}
#: words in a path that stand for any name (NAME, BUS, <device>, {name}, ID, N)
PLACEHOLDER = re.compile(r"^(?:[A-Z][A-Z0-9_]*|<[^>]+>|\{[^}]+\})$")


def rel(path: Path) -> str:
    return str(path.relative_to(ROOT))


def texts() -> dict[Path, str]:
    return {page: page.read_text(encoding="utf-8") for page in PAGES}


def strip_code_blocks(text: str) -> str:
    return re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)


# -- pages ------------------------------------------------------------------------------------------


def app_routes() -> list[str]:
    """Every path the app serves: the pages' ``@ui.page(...)``, the API's ``@app.get(...)`` and the
    ``*_url`` paths FastAPI serves its own description on, read from the source without starting it."""
    routes: set[str] = set()
    for source in ROUTE_SOURCES:
        tree = ast.parse(source.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in {"page", "get"}
                    and node.args and isinstance(node.args[0], ast.Constant) and str(node.args[0].value).startswith("/")):
                routes.add(node.args[0].value)
            if isinstance(node, ast.Assign) and isinstance(node.value, ast.Tuple):
                for target in node.targets:
                    if isinstance(target, ast.Tuple):
                        for name, value in zip(target.elts, node.value.elts, strict=False):
                            if isinstance(name, ast.Attribute) and name.attr.endswith("_url") and isinstance(value, ast.Constant):
                                routes.add(value.value)
    return sorted(routes)


def bus_tools() -> tuple[str, ...]:
    tree = ast.parse((ROOT / "server" / "__init__.py").read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "BUS_TOOLS" for t in node.targets):
            return tuple(ast.literal_eval(node.value))
    raise AssertionError("server/__init__.py declares no BUS_TOOLS")


def demo_names() -> set[str]:
    return set(re.findall(r'^name = "([^"]+)"', DEMO_PLANT.read_text(encoding="utf-8"), flags=re.M))


def named_paths() -> list[tuple[str, str]]:
    """(page file, path) for every page path the README and docs name in backticks or in a local URL."""
    found = []
    for page, text in texts().items():
        for match in re.finditer(r"`(?:GET )?(/[^`\s]*)`", text):
            found.append((rel(page), match.group(1)))
        for match in re.finditer(r"https?://127\.0\.0\.1:\d+(/[^\s)`'\"]*)", text):
            found.append((rel(page), match.group(1).rstrip(".,:;")))
    return found


def route_matches(path: str, route: str, names: set[str], tools: tuple[str, ...]) -> bool:
    want = [s for s in path.split("?")[0].split("/") if s]
    have = [s for s in route.split("/") if s]
    if len(want) != len(have):
        return False
    for word, part in zip(want, have, strict=True):
        if part.startswith("{"):
            if PLACEHOLDER.match(word):
                continue
            if part == "{tool}" and word not in tools:
                return False
            if part in {"{name}", "{bus}"} and word not in names:
                return False  # a concrete name in the guide is one of the demo plant's
        elif word != part:
            return False
    return True


def test_the_docs_name_pages():
    assert len(named_paths()) >= 15, "the guide names the app's pages in backticks, e.g. `/device/door-1`"


def test_a_page_the_app_does_not_serve_is_caught():
    routes, names, tools = app_routes(), demo_names(), bus_tools()

    def served(path: str) -> bool:
        return any(route_matches(path, r, names, tools) for r in routes)

    assert served("/device/door-1") and served("/monitor/BUS/poll") and served("/replace/<device>") and served("/fleet")
    assert not served("/devices/door-1")  # no such route
    assert not served("/device/door-9")  # no such device in the demo plant
    assert not served("/monitor/can1/sniff")  # no such bus tool


def test_every_page_the_docs_name_is_a_route_of_the_app():
    routes, names, tools = app_routes(), demo_names(), bus_tools()
    assert "/device/{name}" in routes and "/api/devices" in routes
    unknown = [f"{page}: {path}" for page, path in named_paths()
               if path not in NOT_ROUTES and path.split("/")[1] not in FILE_SYSTEM and not any(route_matches(path, r, names, tools) for r in routes)]
    assert not unknown, "pages named in the docs that the app does not serve (routes: " + ", ".join(routes) + "):\n" + "\n".join(unknown)


# -- command lines ----------------------------------------------------------------------------------


def command_lines() -> list[tuple[str, str, bool]]:
    """(page file, command line, whole) for every ``commission ...`` the README and docs show: the lines
    of code blocks (whole: it must parse as written) and inline code (a mention such as
    ``commission user add`` or ``commission export --format mcap`` must name a command and its options)."""
    found = []
    for page, text in texts().items():
        for block in re.findall(r"^```[a-z]*\n(.*?)^```", text, flags=re.S | re.M):
            for line in block.splitlines():
                line = line.split(" # ")[0].split("  #")[0].strip()
                for part in re.split(r"\s*(?:&&|;)\s*", line):
                    if part.startswith("commission") and (part == "commission" or part.startswith("commission ")):
                        found.append((rel(page), part, True))
        for span in re.findall(r"`(commission(?: [^`]*)?)`", strip_code_blocks(text)):
            found.append((rel(page), " ".join(span.split()), False))
    return found


def parse(line: str) -> tuple[int, str]:
    """Exit status and error text of the CLI's parser on ``line`` (0: it parses)."""
    words = shlex.split(re.sub(r"\s\[[^\]]*\]", "", line))[1:]  # [--yes]: an optional part, shown in brackets
    stderr = io.StringIO()
    try:
        with contextlib.redirect_stderr(stderr), contextlib.redirect_stdout(io.StringIO()):
            build_parser().parse_args(words)
    except SystemExit as exc:
        return int(exc.code or 0), stderr.getvalue().strip().splitlines()[-1] if stderr.getvalue().strip() else ""
    return 0, ""


def mention_problem(line: str) -> str:
    """What is wrong with a mention of a command in running text (its command words and options), or ''.

    The command words are checked by asking the CLI's parser for their help (an unknown one is refused
    as on the command line), the options against the options that help names."""
    words = [w for w in shlex.split(line)[1:] if w != "..."]
    command = list(itertools.takewhile(lambda w: not w.startswith("-"), words))[:2]
    help_text, stderr = io.StringIO(), io.StringIO()
    try:
        with contextlib.redirect_stdout(help_text), contextlib.redirect_stderr(stderr):
            build_parser().parse_args([*command, "--help"])
    except SystemExit as exc:
        if exc.code:
            return stderr.getvalue().strip().splitlines()[-1]
    known = set(re.findall(r"(?<![\w-])(--?[A-Za-z][\w-]*)", help_text.getvalue()))
    unknown = [w.split("=")[0] for w in words if w.startswith("-") and w.split("=")[0] not in known]
    return f"commission {' '.join(command)} has no option {', '.join(unknown)}" if unknown else ""


def test_the_docs_show_commands():
    whole = [line for _, line, is_whole in command_lines() if is_whole]
    assert len(whole) >= 20, whole


def test_every_command_line_the_docs_show_parses():
    failures = []
    for page, line, whole in command_lines():
        if whole:
            status, error = parse(line)
            if status != 0:
                failures.append(f"{page}: {line}\n    {error}")
        else:
            problem = mention_problem(line)
            if problem:
                failures.append(f"{page}: {line}\n    {problem}")
    assert not failures, "command lines in the docs that commission refuses:\n" + "\n".join(failures)


def test_a_wrong_command_line_is_caught():
    assert parse("commission backup --plant site.toml --out backups/")[0] == 0
    assert parse("commission backup --plant site.toml --outt backups/")[0] == 2
    assert parse("commission restore --plant P --device door-1 f.json [--yes]")[0] == 0
    assert mention_problem("commission user add") == ""
    assert mention_problem("commission export --format mcap") == ""
    assert "invalid choice: 'users'" in mention_problem("commission users add")
    assert mention_problem("commission --host 0.0.0.0") == ""
    assert "no option --formt" in mention_problem("commission export --formt mcap")


# -- links ------------------------------------------------------------------------------------------


def slug(heading: str) -> str:
    """GitHub's anchor of a heading."""
    text = re.sub(r"[`*_]", "", heading.strip().lower())
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    text = strip_code_blocks(page.read_text(encoding="utf-8"))
    return {slug(h) for h in re.findall(r"^#{1,6} (.+)$", text, flags=re.M)}


def links(page: Path) -> list[str]:
    return re.findall(r"\]\(([^)\s]+)\)", strip_code_blocks(page.read_text(encoding="utf-8")))


def test_every_link_in_the_readme_and_docs_resolves():
    broken = []
    for page in PAGES:
        for target in links(page):
            if re.match(r"^[a-z]+:", target):
                continue  # http(s), mailto: outside this checkout
            file_part, _, anchor = target.partition("#")
            resolved = (page.parent / file_part).resolve() if file_part else page
            if not resolved.exists():
                broken.append(f"{rel(page)}: {target} (no file {resolved})")
            elif anchor and resolved.suffix == ".md" and anchor not in anchors(resolved):
                broken.append(f"{rel(page)}: {target} (no heading #{anchor} in {rel(resolved)})")
    assert not broken, "links that lead nowhere:\n" + "\n".join(broken)


def test_every_docs_page_is_linked_from_the_readme():
    linked = {(README.parent / t.partition("#")[0]).resolve() for t in links(README) if not re.match(r"^[a-z]+:", t)}
    missing = [rel(p) for p in sorted(DOCS.glob("*.md")) if p.resolve() not in linked]
    assert not missing, f"docs pages the README does not link: {missing}"


def test_the_readme_fits_on_a_few_screens():
    lines = README.read_text(encoding="utf-8").count("\n")
    assert lines <= 250, f"README.md has {lines} lines; move detail into docs/"


def test_the_readme_shows_the_command_ci_runs_and_the_fast_loop_first():
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    ci_command = [line for line in ci.splitlines() if "python3 -m tools.suite" in line and not line.startswith("#")]
    assert len(ci_command) == 1, ci_command
    test_section = README.read_text(encoding="utf-8").split("\n## Test", 1)[1].split("\n## ", 1)[0]
    commands = [line.split("#")[0].strip() for line in test_section.splitlines()
                if line.startswith("python3 -m ") and not line.startswith(("`", " "))]
    assert commands and commands[0] == 'python3 -m pytest -q -m "not browser and not slow"', commands
    assert ci_command[0] in commands, f"the README's Test section does not show {ci_command[0]!r}, which .ci/run runs"


@pytest.mark.parametrize("image", sorted((DOCS / "img").glob("*.png")), ids=lambda p: p.name)
def test_every_screenshot_is_shown(image: Path):
    shown = {(page.parent / t).resolve() for page in PAGES for t in links(page)}
    assert image.resolve() in shown, f"{rel(image)} is shown on no page (python -m tools.screenshots makes it)"
