"""Shared fixtures: plants on free localhost ports, twins and a running worker."""

from __future__ import annotations

import asyncio
import contextlib
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

# the source folder's build tools (tools/) and the app in a process of its own as the benchmarks start it
# (standard library only: bench/liveapp.py)
sys.path.append(str(Path(__file__).resolve().parent.parent))
sys.path.append(str(Path(__file__).resolve().parent.parent / "bench"))

from liveapp import CHROMIUM_ARGS, free_port, free_udp_port, wait_devices_online  # noqa: E402
from plants import heater_and_lock, modbus_plant  # noqa: E402

from app.plant import Plant, parse_plant  # noqa: E402


def pytest_configure(config: pytest.Config) -> None:
    """Every runtime the tests start (in this process and in app subprocesses, which inherit the
    environment) keeps its audit log, backups and sessions in a data folder of this test run,
    never in the user's own folder and never shared with a run beside it. Tests that need a
    folder of their own still set ``COMMISSION_DATA_DIR`` themselves."""
    import os
    import tempfile

    global _RUN_DATA_DIR
    # a test that holds a motion would run its process's threads real-time (app/realtime.py): two test
    # processes beside chromium and mosquitto on two cores would starve those; tests of it turn it on themselves
    os.environ.setdefault("COMMISSION_RT_HOLDERS", "0")
    from app import realtime

    realtime.HOLDERS_REAL_TIME = os.environ["COMMISSION_RT_HOLDERS"] != "0"
    if "COMMISSION_DATA_DIR" not in os.environ:
        _RUN_DATA_DIR = os.environ["COMMISSION_DATA_DIR"] = tempfile.mkdtemp(prefix="commission-tests-")


_RUN_DATA_DIR: str | None = None


# -- markers: the fast loop is ``pytest -m "not browser and not slow"`` ------------------------

#: test files that drive a real browser but are not named test_browser_*.py
BROWSER_FILES = {
    "test_backup_page_browser.py",
    "test_deadman_browser.py",
    "test_mqtt_browser.py",
    "test_stylesheet_browser.py",
}

#: tests that take more than about 5 s on two shared cores: a file name (every test in it) or a node id
SLOW_TESTS: set[str] = set()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark every real-browser test ``browser`` (a test_browser_*.py file, one of BROWSER_FILES, or a test
    that uses the ``chromium`` fixture) and every test of SLOW_TESTS ``slow``."""
    for item in items:
        name = item.path.name
        if name.startswith("test_browser_") or name in BROWSER_FILES or "chromium" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.browser)
        node = item.nodeid.split("/")[-1]
        if name in SLOW_TESTS or node in SLOW_TESTS or node.split("[")[0] in SLOW_TESTS:
            item.add_marker(pytest.mark.slow)


@pytest.fixture(autouse=True)
def _own_data_dir(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each test its own data folder (its own audit log: no test waits on another's database lock),
    unless a module fixture already chose one for the app it runs."""
    import os

    if _RUN_DATA_DIR is not None and os.environ.get("COMMISSION_DATA_DIR") == _RUN_DATA_DIR:
        monkeypatch.setenv("COMMISSION_DATA_DIR", str(request.getfixturevalue("tmp_path") / "data"))


async def wait_for(predicate, timeout: float = 5.0, interval: float = 0.05) -> bool:
    """Poll ``predicate`` until it is true or ``timeout`` seconds passed."""
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while loop.time() < end:
        if predicate():
            return True
        await asyncio.sleep(interval)
    return bool(predicate())


@contextlib.asynccontextmanager
async def running_plant(plant: Plant):
    """The app's runtime on ``plant`` with its twins, started; stopped (bounded) on leaving."""
    from app.runtime import Runtime

    runtime = Runtime(plant, simulate=True)
    await runtime.start()
    try:
        yield runtime
    finally:
        await asyncio.wait_for(runtime.stop(), 5)


@pytest.fixture
def plant() -> Plant:
    return modbus_plant(locks=(("door-1", 1), ("door-2", 2)))


@pytest.fixture
async def can_rig(tmp_path: Path):
    """The app without twins on :func:`plants.heater_and_lock`'s bus, and a python-can listener on that bus."""
    import can

    from app.runtime import Runtime

    channel = f"rig-{free_port()}-{time.monotonic_ns()}"
    runtime = Runtime(parse_plant(heater_and_lock(channel)), simulate=False, data_dir=tmp_path)
    await runtime.start()
    listener = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
    try:
        yield runtime, listener
    finally:
        listener.shutdown()
        await asyncio.wait_for(runtime.stop(), 5)


def spy_writes(twin) -> list[tuple[int, int]]:
    """Record every register write that reaches ``twin`` (over the wire, via FC 0x06) in the list returned."""
    writes: list[tuple[int, int]] = []
    original = twin.write

    def recording(address: int, value: int):
        writes.append((address, value))
        return original(address, value)

    twin.write = recording
    return writes


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


def inside_viewport(page, locator) -> None:
    """Assert that the element of ``locator`` is visible and lies wholly inside the page's viewport."""
    box = locator.bounding_box()
    assert box is not None, f"{locator} is not rendered"
    size = page.viewport_size or page.evaluate("({width: window.innerWidth, height: window.innerHeight})")
    assert box["x"] >= 0 and box["y"] >= 0, f"{locator} starts outside the viewport: {box}"
    assert box["x"] + box["width"] <= size["width"] + 0.5, f"{locator} sticks out right of {size['width']} px: {box}"
    assert box["y"] + box["height"] <= size["height"] + 0.5, f"{locator} sticks out below {size['height']} px: {box}"


__all__ = ["CHROMIUM", "CHROMIUM_ARGS", "free_port", "free_udp_port", "inside_viewport", "modbus_plant", "running_plant", "sim_process", "spy_writes",
           "wait_devices_online", "wait_for"]
