"""The safety cores are sans-I/O: no asyncio, threads, sockets, clocks or bus libraries (ARCHITECTURE.md rule 6)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FORBIDDEN = {"asyncio", "threading", "socket", "selectors", "time", "can", "serial", "pymodbus", "concurrent",
             "multiprocessing", "subprocess", "nicegui", "app", "pages", "devices.lease"}


def cores() -> list[Path]:
    return [ROOT / "devices" / "control.py", *sorted((ROOT / "devices").glob("*/control.py"))]


def imported(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(("." * node.level) + node.module)
    return names


def test_cores_exist_for_the_families_with_keepalives():
    found = {p.parent.name for p in cores()}
    assert {"devices", "scu", "electrak", "m3io", "mo64"} <= found  # the HD-Lock has no keep-alive: its rules are its policy


def test_cores_import_no_io():
    for path in cores():
        for name in imported(path):
            top = name.lstrip(".")
            assert not any(top == f or top.startswith(f + ".") for f in FORBIDDEN), f"{path.relative_to(ROOT)} imports {name}"
