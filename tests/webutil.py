"""Helpers shared by the page tests (simulated user) and the browser tests."""

from __future__ import annotations

import asyncio
import contextlib
import importlib
import logging
import os
import subprocess
import sys
import time
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass
from pathlib import Path

import liveapp
import pytest
from liveapp import DEMO_PLANT, ROOT, free_port, running_app, start_app, stop_app, wait_http  # noqa: F401 - for the tests


async def eventually(check: Callable[[], object], timeout: float = 5.0, interval: float = 0.05, what: str = "",
                     retry_on: tuple[type[BaseException], ...] = (AssertionError,)) -> object:
    """Retry ``check`` (which raises AssertionError, or returns falsy; a coroutine's result is awaited) until it
    passes or ``timeout`` ends; returns what it returned. The one way the suite waits on a condition."""
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while True:
        try:
            result = check()
            if asyncio.iscoroutine(result):
                result = await result
            if result is None or result:
                return result
            error: BaseException = AssertionError(f"not true within {timeout} s: {what or check}")
        except retry_on as exc:
            error = exc
        if loop.time() >= end:
            raise error
        await asyncio.sleep(interval)


def eventually_sync(check: Callable[[], object], timeout: float = 5.0, interval: float = 0.05, what: str = "",
                    retry_on: tuple[type[BaseException], ...] = (AssertionError,)) -> object:
    """:func:`eventually` for a test without an event loop (a thread, a process beside it)."""
    end = time.monotonic() + timeout
    while True:
        try:
            result = check()
            if result is None or result:
                return result
            error: BaseException = AssertionError(f"not true within {timeout} s: {what or check}")
        except retry_on as exc:
            error = exc
        if time.monotonic() >= end:
            raise error
        time.sleep(interval)


async def stop_worker_tasks(runtime, timeout: float = 5.0) -> None:
    """End the worker's bus tasks before the app's shutdown, bounded, so a test's teardown cannot hang."""
    await asyncio.wait_for(runtime.worker.stop(), timeout + 1)


@contextlib.asynccontextmanager
async def simulated_user(runtime):
    """NiceGUI's simulated user on the app of ``runtime``, with NiceGUI's globals of its own.

    The app is registered (``server.register``: the simulated user's host name is "test"), its
    lifespan started, and on leaving the worker stopped (bounded) and the app shut down, also when
    the test failed inside, so that the next app can start.
    """
    import httpx
    from nicegui import core, ui
    from nicegui.functions.download import download
    from nicegui.functions.navigate import Navigate
    from nicegui.functions.notify import notify
    from nicegui.testing import User
    from nicegui.testing.general import nicegui_reset_globals, prepare_simulation

    from app import runtime as rt

    with nicegui_reset_globals():
        os.environ["NICEGUI_USER_SIMULATION"] = "true"
        try:
            prepare_simulation()
            # nicegui_reset_globals drops the module of every page function (server): import it afresh
            importlib.import_module("server").register(runtime, allowed_hosts=("test",))
            ui.run(storage_secret="test secret")
            failure: BaseException | None = None
            async with core.app.router.lifespan_context(core.app):
                async with httpx.AsyncClient(transport=httpx.ASGITransport(core.app), base_url="http://test") as client:
                    try:
                        yield User(client)
                    except BaseException as exc:  # noqa: BLE001 - re-raised below, after the app has shut down
                        failure = exc
                    finally:
                        await stop_worker_tasks(runtime)  # Worker.stop() can hang in the lifespan's shutdown
            if failure is not None:
                raise failure
        finally:
            os.environ.pop("NICEGUI_USER_SIMULATION", None)
            ui.navigate = Navigate()
            ui.notify = notify
            ui.download = download
            rt.set_current(None)


@contextlib.asynccontextmanager
async def user_on(plant, simulate: bool = True, data_dir: Path | None = None) -> AsyncIterator[tuple]:
    """NiceGUI's simulated user on ``plant``, its twins simulated here (unless ``simulate`` is false), its data in
    ``data_dir`` (a folder of its own by default): yields ``(user, runtime)``."""
    from app.runtime import Runtime

    runtime = Runtime(plant, simulate=simulate, data_dir=data_dir)
    async with simulated_user(runtime) as user:
        yield user, runtime


def lone_m3io_user() -> contextlib.AbstractAsyncContextManager[tuple]:
    """:func:`user_on` an M3IO HM ``io`` on a virtual CAN bus ``can9`` of its own, without a twin (nothing answers)."""
    from plants import can_bus, channel, m3io_can, plant

    return user_on(plant(can_bus(m3io_can("io", "can9"), name="can9", channel_name=channel("can9"), simulate=None),
                         name="w"), simulate=False)


def by_testid(user, testid: str):
    """The one element of the simulated user's page with ``data-testid=testid``."""
    found = [e for e in user.client.elements.values() if e.props.get("data-testid") == testid]
    assert len(found) == 1, f"{testid}: {len(found)} elements"
    return found[0]


def switch_starting(user, text: str):
    """The switch on the user's page whose label starts with ``text``."""
    from nicegui import ui

    return next(e for e in user.client.elements.values() if isinstance(e, ui.switch) and e.text.startswith(text))


def project_card_table(user):
    """The table of the device page's project card (the one with an actions column) open in ``user``."""
    from nicegui import ui

    return next(e for e in user.client.elements.values()
                if isinstance(e, ui.table) and any(c["name"] == "actions" for c in e.columns))


def dialog_button(user, text: str):
    """The buttons labelled ``text`` inside an open dialog of ``user``'s page, to click."""
    from nicegui import ui
    from nicegui.testing.user_interaction import UserInteraction

    def in_dialog(element) -> bool:
        while element is not None:
            if isinstance(element, ui.dialog):
                return True
            element = element.parent_slot.parent if element.parent_slot else None
        return False

    found = {e for e in user.client.elements.values() if isinstance(e, ui.button) and e.text == text and in_dialog(e)}
    assert found, f"no {text!r} button in a dialog"
    return UserInteraction(user, found, None)


@dataclass
class PageEnv:
    """NiceGUI's simulated user and the app it talks to."""

    user: object  # nicegui.testing.User
    runtime: object  # app.runtime.Runtime


@contextlib.asynccontextmanager
async def demo_user(folder: Path, tag: str) -> AsyncIterator[tuple]:
    """NiceGUI's simulated user on the demo plant, its twins simulated here on endpoints of their own (``tag``: see
    :func:`private_endpoints`), its RS485 line polled every 0.2 s, data in ``folder``: yields ``(user, runtime)``."""
    from app.plant import load_plant
    from app.runtime import Runtime

    plant = private_endpoints(load_plant(DEMO_PLANT), tag)
    plant.buses["line1"].options.update(timeout=0.2, poll_period=0.2)
    runtime = Runtime(plant, simulate=True, data_dir=folder / "data")
    async with simulated_user(runtime) as user:
        yield user, runtime


@contextlib.asynccontextmanager
async def pages_on(plant, folder: Path, online_within_s: float = 15) -> AsyncIterator[PageEnv]:
    """The pages of ``plant`` (its twins simulated here, data in ``folder``) for NiceGUI's simulated user,
    once every device answers."""
    from app.runtime import Runtime

    runtime = Runtime(plant, simulate=True, data_dir=folder / "data")
    async with simulated_user(runtime) as user:
        await eventually(lambda: all(s.status == "online" for s in runtime.store.devices.values()),
                         timeout=online_within_s, what="every device online")
        yield PageEnv(user, runtime)


@dataclass
class LockPages(PageEnv):
    """The simulated user on two HD-Locks (door-1 at address 1, door-2 at 2) on a simulated RTU line."""

    def twin(self, name: str = "door-1"):
        return self.runtime.twins[name]

    def state(self, name: str = "door-1"):
        return self.runtime.store.devices[name]

    async def polled(self, *names: str, point: str = "SerialNumber") -> None:
        """Wait until the worker has polled each of ``names`` (both locks by default) as far as ``point``."""

        def check() -> None:
            for name in names or ("door-1", "door-2"):
                state = self.state(name)
                assert state.status == "online", f"{name} is {state.status}: {state.last_error}"
                assert state.value(point) is not None, f"{name}: {point} not read yet"

        await eventually(check, timeout=10)

    async def open_page(self, name: str = "door-1") -> None:
        """Once ``name`` is polled, its page opened in the user's browser and its title shown."""
        await self.polled(name)
        await self.user.open(f"/device/{name}")
        await self.user.should_see(f"HD-Lock {name}")


@contextlib.asynccontextmanager
async def lock_pages(caplog) -> AsyncIterator[LockPages]:
    """:class:`LockPages` with the twins polled over real Modbus RTU frames; on leaving, no ERROR may have
    been logged meanwhile (pymodbus logs the late answers of a silent lock there: those aside)."""
    from plants import modbus_plant

    async with user_on(modbus_plant(locks=(("door-1", 1), ("door-2", 2)))) as (user, runtime):
        yield LockPages(user, runtime)
    errors = [r for r in caplog.get_records("call") if r.levelno >= logging.ERROR and not r.name.startswith("pymodbus")]
    assert not errors, "unexpected ERROR logs: " + "; ".join(r.getMessage() for r in errors)


async def lock_pages_env(caplog) -> AsyncIterator[LockPages]:
    """:func:`lock_pages` as a test module's fixture: ``env = pytest.fixture(lock_pages_env, name="env")``."""
    async with lock_pages(caplog) as env:
        yield env


# -- the app as a separate process (browser tests): bench/liveapp.py, as the benchmarks start it ----------


def demo_plant_text(bus_port: int) -> str:
    """The demo plant file with the simulated RS485 line moved to ``bus_port`` and every other
    simulated TCP endpoint (the SCU's serial line, the MO 64) to a free port of its own."""
    text = liveapp.demo_plant_text(bus_port)
    assert f"socket://127.0.0.1:{bus_port}" in text, "demo plant no longer names socket://127.0.0.1:5020"
    return text


@contextlib.contextmanager
def opened(browser, url: str, width: int = 1440, height: int = 900):
    """A new page of playwright's ``browser`` (``width`` x ``height``) at ``url``, closed on leaving."""
    page = browser.new_page(viewport={"width": width, "height": height})
    try:
        page.goto(url)
        yield page
    finally:
        page.close()


def page_at(browser, url: str, width: int = 1440, height: int = 900):
    """A new page of playwright's ``browser`` (``width`` x ``height``) opened at ``url``; every wait on it is bounded
    by 15 s."""
    page = browser.new_page(viewport={"width": width, "height": height})
    page.set_default_timeout(15_000)
    page.goto(url)
    return page


# counts the element updates the server pushes to a page and when the last one came
_PUSHES_JS = """() => {
  if (!window.__pushes) {
    window.__pushes = {n: 0, at: performance.now()};
    window.socket.on('update', () => { window.__pushes.n++; window.__pushes.at = performance.now(); });
  }
  return window.__pushes.n;
}"""


def settled(page, pushes: int = 2, quiet_ms: int = 1000, timeout_ms: int = 15_000) -> None:
    """Wait until the server has pushed ``pushes`` more element updates to ``page`` (the first is the header's, right
    after the page connects; then its timers refresh the live values, lists and counters it shows), or none for
    ``quiet_ms`` (a page with nothing live refreshes only its header, every 2 s)."""
    start = page.evaluate(_PUSHES_JS)
    page.wait_for_function("([target, quiet]) => window.__pushes.n >= target || performance.now() - window.__pushes.at >= quiet",
                           arg=[start + pushes, quiet_ms], timeout=timeout_ms)


@contextlib.contextmanager
def at_size(page, width: int, height: int):
    """``page`` (loaded once) made ``width`` x ``height`` for the checks inside, once laid out anew: its window has
    the size, and two frames have been drawn since (its resize handlers and observers have run). An assertion or a
    wait of playwright's that fails inside says the size it failed at."""
    from playwright.sync_api import Error as PlaywrightError

    page.set_viewport_size({"width": width, "height": height})
    page.wait_for_function("([w, h]) => window.innerWidth === w && window.innerHeight === h", arg=[width, height])
    page.evaluate("() => new Promise(done => requestAnimationFrame(() => requestAnimationFrame(() => done())))")
    try:
        yield page
    except (AssertionError, PlaywrightError) as exc:
        raise AssertionError(f"at {width}x{height}: {exc}") from exc


#: every plotly chart shown is drawn as wide as its box (plotly draws itself anew 100 ms after its box changed size)
_CHARTS_FIT_JS = """() => [...document.querySelectorAll('.js-plotly-plot')].filter(p => p.offsetParent !== null).every(p => {
    const svg = p.querySelector('.main-svg');
    return svg && Math.abs(svg.getBoundingClientRect().width - p.getBoundingClientRect().width) <= 1; })"""


def charts_fit(page, timeout_ms: int = 10_000) -> None:
    """Wait until every chart ``page`` shows is drawn anew for the width of its box (after a resize)."""
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    try:
        page.wait_for_function(_CHARTS_FIT_JS, timeout=timeout_ms)
    except PlaywrightTimeout:
        raise AssertionError(f"a chart is not drawn for its width within {timeout_ms} ms") from None


def click_until(button, appears, tries: int = 3, each_ms: int = 5_000) -> None:
    """Click ``button`` (a playwright locator) until ``appears`` is visible: a live table that draws its rows anew
    (a device that came back and was compared again) can take a click into the rows it replaces. It is clicked
    again only while ``appears`` is not there, so a slow answer to the first click is never doubled."""
    from playwright.sync_api import expect

    for attempt in range(tries):
        if attempt == 0 or not appears.is_visible():
            button.click()
        try:
            expect(appears).to_be_visible(timeout=each_ms)
            return
        except AssertionError:
            if attempt == tries - 1:
                raise


def serve_beyond_loopback(folder: Path, port: int, data: Path, *args: str) -> subprocess.Popen:
    """``python -m app.cli`` on ``folder/plant.toml`` listening on every interface (every browser logs in),
    its data in ``data``, its output in ``folder/app.log``; run in ``folder``, where NiceGUI keeps its storage."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    for key in ("NICEGUI_USER_SIMULATION", "PYTEST_CURRENT_TEST", "NICEGUI_STORAGE_PATH"):
        env.pop(key, None)
    liveapp.LOGS.append(folder / "app.log")
    with open(folder / "app.log", "wb") as out:
        return subprocess.Popen(
            [sys.executable, "-m", "app.cli", "--plant", str(folder / "plant.toml"), "--host", "0.0.0.0", "--port", str(port),
             "--data-dir", str(data), *args], cwd=folder, env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True,
            preexec_fn=liveapp.die_with_parent,
        )


@contextlib.contextmanager
def demo_app_serving(folder: Path, names: tuple[str, ...] | None = None, online_within_s: float = 20,
                     data_dir: Path | None = None):
    """The GUI in its own process on the demo plant (its simulated line on a free port) in ``folder``, its data
    in ``data_dir`` (default the test run's); yields its URL once ``/api/devices`` answers and ``names`` (every
    device when None) are online. A fixture that fails prints the app's last output; the app is stopped on
    leaving."""
    plant = folder / "plant.toml"
    plant.write_text(demo_plant_text(free_port()))
    port = free_port()
    log = folder / "app.log"
    url = f"http://127.0.0.1:{port}"
    with contextlib.ExitStack() as environment:
        if data_dir is not None:
            environment.enter_context(pytest.MonkeyPatch.context()).setenv("COMMISSION_DATA_DIR", str(data_dir))
        proc = start_app(plant, port, log)  # it copies os.environ
    try:
        wait_http(url + "/api/devices", proc, timeout=30)
        liveapp.wait_devices_online(url, names, proc, timeout=online_within_s)
        yield url
    except BaseException:
        print(log.read_text(errors="replace")[-4000:])
        raise
    finally:
        stop_app(proc)


def private_endpoints(plant, tag: str):
    """A loaded plant with every simulated endpoint made private to one test: each
    ``socket://127.0.0.1:PORT`` on a free port, each CAN channel suffixed with ``tag``."""
    for bus in plant.buses.values():
        port = bus.options.get("port")
        if isinstance(port, str) and port.startswith("socket://127.0.0.1:"):
            bus.options["port"] = f"socket://127.0.0.1:{free_port()}"
        if bus.type == "logited-tcp" and bus.options.get("host") == "127.0.0.1":
            bus.options["port"] = free_port()
        if bus.type == "can":
            bus.options["channel"] = f"{bus.options['channel']}-{tag}"
    return plant


__all__ = ["DEMO_PLANT", "LockPages", "PageEnv", "ROOT", "at_size", "by_testid", "charts_fit", "click_until", "demo_app_serving", "demo_user", "dialog_button", "lock_pages", "lone_m3io_user", "user_on", "pages_on", "demo_plant_text", "eventually", "free_port", "opened", "page_at", "private_endpoints", "project_card_table", "running_app", "serve_beyond_loopback",
           "simulated_user", "start_app", "stop_app", "stop_worker_tasks", "switch_starting", "wait_http"]


# -- what an open device page costs per push (issue 34): the page's view and what it reads ------------------------

def page_view(user, runtime, device: str):
    """The view of the device page open in ``user`` (the page follows the store with one of its methods)."""
    group = runtime.store._groups[user.client.id]
    views = {getattr(w.callback, "__self__", None) for w in group.watches[device]}
    (view,) = [v for v in views if hasattr(v, "cards")]
    return view


def count_reads(state, monkeypatch) -> list[str]:
    """The names read from ``state`` through live/point/entry from now on."""
    read: list[str] = []
    for method in ("live", "point", "entry"):
        original = getattr(state, method)

        def reading(name, *args, _original=original, **kwargs):
            read.append(name)
            return _original(name, *args, **kwargs)

        monkeypatch.setattr(state, method, reading)
    return read


def heard_again(state) -> None:
    """Every point of ``state`` heard again now with the same value (a slow machine may have let them go stale)."""
    now = time.time()
    state.publish_telegram(now, {n: p._replace(time=now) for n, p in list(state.points.items())})


def refresh_on_the_round(store, view) -> None:
    """``view.refresh()`` as the store's once-a-second round calls it (ages and stale marks drawn)."""
    store.age_round = True
    try:
        view.refresh()
    finally:
        store.age_round = False


async def push_the_same_values(user, runtime, device: str, monkeypatch) -> tuple[object, list[str]]:
    """Open ``device``'s page in ``user`` and draw it as the store has it; then every point heard again with the
    same values and pushed: returns the page's view and the names it read on that push (and reads from now on)."""
    await user.open(f"/device/{device}")
    view = page_view(user, runtime, device)
    state = runtime.store.devices[device]
    heard_again(state)
    view.refresh()  # everything as the store has it now
    read = count_reads(state, monkeypatch)
    heard_again(state)  # heard again, the same values
    view.refresh()
    return view, read
