"""Every sleep in the test suite, and why it is there.

A test waits on a condition (``eventually()`` in tests/webutil.py), never on a constant sleep. What
remains are real delays: a time the device document or the design names (a watchdog, a lease, a
status period) that has to pass so that the test can show that something did *not* happen, a pause a
script plays as a person or a bus would, or the poll interval of a loop that waits on a condition with
a bound. A browser test waits for what it asserts (playwright's ``wait_for``, ``expect``, ``wait_for_function``,
``settled()`` in tests/webutil.py). This script lists every ``asyncio.sleep``/``time.sleep`` call and every
playwright ``wait_for_timeout`` under tests/ with its kind:

- ``poll``: inside a loop (a bounded wait on a condition, or a sender's period);
- ``yield``: ``sleep(0)``, handing the event loop over once;
- ``delay``: a constant delay with its reason, the comment on its line or the line above;
- ``UNEXPLAINED``: a constant delay without a reason (``tests/app/test_sleeps.py`` fails on any).

Run: ``python -m tools.sleeps`` (``--all`` lists every sleep, not only the delays).
"""

from __future__ import annotations

import argparse
import ast
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SLEEPS = {("asyncio", "sleep"), ("time", "sleep")}


@dataclass(frozen=True)
class Sleep:
    path: str
    line: int
    kind: str  # poll | yield | delay | UNEXPLAINED
    call: str
    reason: str


def _is_sleep(node: ast.Call) -> bool:
    """``asyncio.sleep``, ``time.sleep``, or a playwright page's ``wait_for_timeout`` (whatever holds the page)."""
    func = node.func
    if not isinstance(func, ast.Attribute):
        return False
    return func.attr == "wait_for_timeout" or (isinstance(func.value, ast.Name) and (func.value.id, func.attr) in SLEEPS)


def _reason(lines: list[str], lineno: int) -> str:
    """The comment on the call's line, else a comment line right above it."""
    line = lines[lineno - 1]
    if "#" in line:
        return line.split("#", 1)[1].strip()
    above = lines[lineno - 2].strip() if lineno >= 2 else ""
    return above[1:].strip() if above.startswith("#") else ""


def _zero(node: ast.Call) -> bool:
    return bool(node.args) and isinstance(node.args[0], ast.Constant) and node.args[0].value == 0


def scan(path: Path) -> list[Sleep]:
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines()
    tree = ast.parse(text)
    found: list[Sleep] = []

    def visit(node: ast.AST, in_loop: bool) -> None:
        for child in ast.iter_child_nodes(node):
            loop = in_loop or isinstance(child, ast.While | ast.For | ast.AsyncFor)
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
                loop = False  # a function defined in a loop is judged by its own body
            if isinstance(child, ast.Call) and _is_sleep(child):
                reason = _reason(lines, child.lineno)
                if _zero(child):
                    kind = "yield"
                elif in_loop:
                    kind = "poll"
                else:
                    kind = "delay" if reason else "UNEXPLAINED"
                found.append(Sleep(str(path.relative_to(ROOT)), child.lineno, kind, ast.unparse(child), reason))
            visit(child, loop)

    visit(tree, False)
    return found


def all_sleeps(folder: Path = ROOT / "tests") -> list[Sleep]:
    return [s for path in sorted(folder.rglob("*.py")) for s in scan(path)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--all", action="store_true", help="list polls and yields too")
    args = parser.parse_args(argv)
    sleeps = all_sleeps()
    counts: dict[str, int] = {}
    for s in sleeps:
        counts[s.kind] = counts.get(s.kind, 0) + 1
        if args.all or s.kind in {"delay", "UNEXPLAINED"}:
            print(f"{s.path}:{s.line}: {s.kind}: {s.call}  # {s.reason}")
    print(", ".join(f"{kind}: {n}" for kind, n in sorted(counts.items())))
    return 1 if counts.get("UNEXPLAINED") else 0


if __name__ == "__main__":
    sys.exit(main())
