"""Shared fixtures: plants on free localhost ports, twins and a running worker."""

from __future__ import annotations

import asyncio
import contextlib
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from app.plant import Plant, parse_plant


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def modbus_plant(port: int | None = None, locks: tuple[tuple[str, int], ...] = (("door-1", 1),), **bus) -> Plant:
    """A plant with one simulated RTU line on a free port and the given (name, address) locks."""
    port = port or free_port()
    options = {"timeout": 0.2, "retries": 0, "poll_period": 0.1, **bus}
    lines = [
        "[[bus]]",
        'name = "line1"',
        'type = "modbus-rtu"',
        f'port = "socket://127.0.0.1:{port}"',
        "simulate = true",
        *[f"{k} = {str(v).lower() if isinstance(v, bool) else v!r}" for k, v in options.items()],
    ]
    for name, address in locks:
        lines += ["[[device]]", f'name = "{name}"', 'type = "hdlock"', 'bus = "line1"', f"address = {address}"]
    return parse_plant("\n".join(lines).replace("'", '"'))


async def wait_for(predicate, timeout: float = 5.0, interval: float = 0.05) -> bool:
    """Poll ``predicate`` until it is true or ``timeout`` seconds passed."""
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while loop.time() < end:
        if predicate():
            return True
        await asyncio.sleep(interval)
    return bool(predicate())


@pytest.fixture
def plant() -> Plant:
    return modbus_plant(locks=(("door-1", 1), ("door-2", 2)))


@contextlib.contextmanager
def sim_process(plant_file: Path) -> Iterator[tuple[subprocess.Popen, str]]:
    """`commission sim --plant FILE` in its own process; yields it and its first line of output.

    On leaving, it is stopped with SIGTERM and must exit cleanly (0) within 10 s.
    """
    proc = subprocess.Popen([sys.executable, "-m", "app.cli", "sim", "--plant", str(plant_file)], stdout=subprocess.PIPE, text=True)
    try:
        yield proc, proc.stdout.readline()
    finally:
        proc.terminate()
        try:
            assert proc.wait(timeout=10) == 0
        finally:
            if proc.poll() is None:
                proc.kill()
