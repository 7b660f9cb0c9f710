"""Shared fixtures: plants on free localhost ports, twins and a running worker."""

from __future__ import annotations

import asyncio
import contextlib
import json
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterable, Iterator
from pathlib import Path

import pytest

from app.plant import Plant, parse_plant


def pytest_configure(config: pytest.Config) -> None:
    """Every runtime the tests start (in this process and in app subprocesses, which inherit the
    environment) keeps its audit log, backups and sessions in a data folder of this test run,
    never in the user's own folder and never shared with a run beside it. Tests that need a
    folder of their own still set ``COMMISSION_DATA_DIR`` themselves."""
    import os
    import tempfile

    global _RUN_DATA_DIR
    if "COMMISSION_DATA_DIR" not in os.environ:
        _RUN_DATA_DIR = os.environ["COMMISSION_DATA_DIR"] = tempfile.mkdtemp(prefix="commission-tests-")


_RUN_DATA_DIR: str | None = None


@pytest.fixture(autouse=True)
def _own_data_dir(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each test its own data folder (its own audit log: no test waits on another's database lock),
    unless a module fixture already chose one for the app it runs."""
    import os

    if _RUN_DATA_DIR is not None and os.environ.get("COMMISSION_DATA_DIR") == _RUN_DATA_DIR:
        monkeypatch.setenv("COMMISSION_DATA_DIR", str(request.getfixturevalue("tmp_path") / "data"))


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def free_udp_port() -> int:
    """A UDP port nobody on this machine uses now (for a udp_multicast bus of one test)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("", 0))
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


# -- browser tests ----------------------------------------------------------------------------

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking"]


@pytest.fixture(scope="module")
def chromium():
    """Debian's chromium through playwright, launched once per test module.

    Not per session: playwright's sync API holds its event loop as the running one for as long as
    it is open, and the asyncio tests of the other modules could not run meanwhile.
    """
    if not CHROMIUM.exists():
        pytest.skip(f"{CHROMIUM} is not installed")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            yield browser
        finally:
            browser.close()


def wait_devices_online(url: str, names: Iterable[str] | None = None, proc: subprocess.Popen | None = None,
                        timeout: float = 20.0) -> dict[str, str]:
    """Wait until ``/api/devices`` of the app at ``url`` lists ``names`` (every device when None) online.

    Returns the status of every device; raises TimeoutError naming the devices that are not online,
    or RuntimeError when ``proc`` (the app) exits meanwhile.
    """
    wanted = None if names is None else set(names)
    end = time.monotonic() + timeout
    status: dict[str, str] = {}
    while True:
        if proc is not None and proc.poll() is not None:
            raise RuntimeError(f"the app exited with {proc.returncode} while waiting for its devices")
        try:
            with urllib.request.urlopen(url + "/api/devices", timeout=2) as response:
                status = {d["name"]: d["status"] for d in json.load(response)}
        except OSError as exc:
            status = {"(no answer)": str(exc)}
        names_now = set(status) if wanted is None else wanted
        if names_now and all(status.get(n) == "online" for n in names_now):
            return status
        if time.monotonic() >= end:
            raise TimeoutError(f"devices not online within {timeout} s: {status}")
        time.sleep(0.1)  # polling an HTTP endpoint from a synchronous test: the condition is checked each round


def inside_viewport(page, locator) -> None:
    """Assert that the element of ``locator`` is visible and lies wholly inside the page's viewport."""
    box = locator.bounding_box()
    assert box is not None, f"{locator} is not rendered"
    size = page.viewport_size or page.evaluate("({width: window.innerWidth, height: window.innerHeight})")
    assert box["x"] >= 0 and box["y"] >= 0, f"{locator} starts outside the viewport: {box}"
    assert box["x"] + box["width"] <= size["width"] + 0.5, f"{locator} sticks out right of {size['width']} px: {box}"
    assert box["y"] + box["height"] <= size["height"] + 0.5, f"{locator} sticks out below {size['height']} px: {box}"
