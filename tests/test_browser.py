"""Real-browser tests: Debian's chromium, driven by playwright, on ``python -m app.cli``.

The app runs as a separate process on a copy of the demo plant whose simulated RTU line
listens on a free port; the HD-Lock twins are polled over real Modbus RTU frames.
"""

from __future__ import annotations

import json
import re
import shutil
import time
import urllib.request
from pathlib import Path

import pytest
from webutil import demo_plant_text, free_port, start_app, stop_app, wait_http

CHROMIUM = Path("/usr/bin/chromium")
if not CHROMIUM.exists():
    pytest.skip(f"{CHROMIUM} is not installed", allow_module_level=True)

from playwright.sync_api import Browser, Page, expect, sync_playwright  # noqa: E402

pytestmark = pytest.mark.timeout(60)  # includes starting the app for the first test

SHOTS = Path("/tmp/commission-shots")
STEP_MS = 10_000  # longest wait for one visible step (page timers tick every 0.5-1 s)


@pytest.fixture(scope="module")
def app_url(tmp_path_factory: pytest.TempPathFactory):
    """The GUI on the demo plant (line1 on a free port), until the module's tests are done."""
    folder = tmp_path_factory.mktemp("browser-app")
    plant = folder / "plant.toml"
    plant.write_text(demo_plant_text(free_port()))
    port = free_port()
    log = folder / "app.log"
    proc = start_app(plant, port, log)
    url = f"http://127.0.0.1:{port}"
    try:
        wait_http(url + "/api/devices", proc, timeout=30)
        _wait_online(url, ("door-1", "door-2"), proc, timeout=15)
        yield url
    except BaseException:
        print(log.read_text(errors="replace")[-4000:])
        raise
    finally:
        stop_app(proc)


def _wait_online(url: str, names: tuple[str, ...], proc, timeout: float) -> None:
    end = time.monotonic() + timeout
    status: dict[str, str] = {}
    while time.monotonic() < end:
        assert proc.poll() is None, "the app exited"
        with urllib.request.urlopen(url + "/api/devices", timeout=2) as response:
            status = {d["name"]: d["status"] for d in json.load(response)}
        if all(status.get(n) == "online" for n in names):
            return
        time.sleep(0.2)
    raise TimeoutError(f"devices not online within {timeout} s: {status}")


@pytest.fixture(scope="module")
def browser():
    with sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=str(CHROMIUM),
            args=["--no-sandbox", "--disable-gpu", "--disable-background-networking"],
        )
        try:
            yield browser
        finally:
            browser.close()


@pytest.fixture
def page(browser: Browser):
    context = browser.new_context(viewport={"width": 1400, "height": 1800})
    page = context.new_page()
    page.set_default_timeout(STEP_MS)
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        yield page
    finally:
        context.close()
    assert not errors, f"JavaScript errors on the page: {errors}"


def lamp(page: Page, name: str):
    return page.locator(f'[data-lamp="{name}"]')


def register_value(page: Page, name: str) -> str:
    """Text of the Value cell of the row named ``name`` in the visible register table."""
    row = page.locator(".q-tab-panel:visible tr", has=page.locator("td", has_text=re.compile(rf"^\s*{re.escape(name)}\s*$")))
    expect(row).to_have_count(1)
    return row.locator("td").nth(2).inner_text().strip()


def bolt_position(page: Page) -> int:
    text = register_value(page, "BoltPosition")
    match = re.fullmatch(r"(-?\d+) Inc", text)
    assert match, f"BoltPosition shows {text!r}"
    return int(match.group(1))


def save_shot(page: Page, tmp_path: Path, name: str) -> Path:
    path = tmp_path / name
    page.screenshot(path=str(path), full_page=True)
    SHOTS.mkdir(parents=True, exist_ok=True)
    shutil.copy(path, SHOTS / name)
    return path


def test_closing_the_door_locks_the_bolt(app_url: str, page: Page, tmp_path: Path):
    page.goto(app_url + "/device/door-1")
    expect(page.get_by_text("HD-Lock door-1", exact=True).first).to_be_visible()
    expect(page.locator(".q-badge", has_text=re.compile(r"^\s*online\s*$")).first).to_be_visible()

    # the door of door-1 starts open: bolt retracted, nothing in position
    expect(lamp(page, "BoltUnlocked")).to_have_attribute("data-on", "1")
    expect(lamp(page, "DoorInPosition")).to_have_attribute("data-on", "0")
    expect(lamp(page, "BoltLocked")).to_have_attribute("data-on", "0")
    expect(page.locator('[data-value="DoorState"]')).not_to_have_text("-")
    assert bolt_position(page) == 0

    page.get_by_role("button", name="Close door").click()

    expect(lamp(page, "DoorInPosition")).to_have_attribute("data-on", "1")
    expect(lamp(page, "BoltLocked")).to_have_attribute("data-on", "1")
    expect(lamp(page, "BoltUnlocked")).to_have_attribute("data-on", "0")
    end = time.monotonic() + STEP_MS / 1000
    while (position := bolt_position(page)) <= 100 and time.monotonic() < end:
        page.wait_for_timeout(200)
    assert position > 100, f"BoltPosition stayed at {position} Inc"
    expect(page.locator('[data-value="StateMachineState"]')).not_to_have_text("-")

    page.wait_for_timeout(1500)  # let the live chart collect a few samples of the stroke
    shot = save_shot(page, tmp_path, "device-door-1-locked.png")
    assert shot.stat().st_size > 10_000


def test_overview_tiles_online_and_open_device(app_url: str, page: Page, tmp_path: Path):
    page.goto(app_url + "/")
    for name in ("door-1", "door-2"):
        tile = page.locator(f'[data-device="{name}"]')
        expect(tile).to_be_visible()
        expect(tile).to_contain_text(name)
        expect(tile).to_contain_text("HD-Lock on line1")
        expect(tile.locator(".q-badge")).to_have_text(re.compile(r"^\s*online\s*$"))
        expect(tile).to_contain_text(re.compile(r"req \d+"))
    save_shot(page, tmp_path, "overview.png")

    page.locator('[data-device="door-2"]').click()
    expect(page).to_have_url(re.compile(r"/device/door-2$"))
    expect(page.get_by_text("HD-Lock door-2", exact=True).first).to_be_visible()
    # door-2 starts with its door closed: its bolt is out
    expect(lamp(page, "BoltLocked")).to_have_attribute("data-on", "1")


def _field(page: Page, testid: str):
    """The text input inside the NiceGUI input/number with ``data-testid``."""
    element = page.locator(f'[data-testid="{testid}"]')
    inner = element.locator("input")
    return inner if inner.count() else element


@pytest.mark.parametrize(("width", "height"), [(1440, 900), (1024, 768)])
def test_broadcast_address_change_asks_with_the_number_of_locks(app_url: str, browser: Browser, tmp_path: Path, width: int, height: int):
    """Section 4.3, address 255: the confirmation names how many locks of the line may take the address."""
    context = browser.new_context(viewport={"width": width, "height": height})
    page = context.new_page()
    page.set_default_timeout(STEP_MS)
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        page.goto(app_url + "/device/door-1")
        expect(page.get_by_text("HD-Lock door-1", exact=True).first).to_be_visible()
        card = page.get_by_text("Set Modbus Address on every lock of line1 (broadcast 255)")
        card.scroll_into_view_if_needed()
        expect(page.locator('[data-testid="bc-known"]')).to_contain_text("2 locks known on line1 (2 in the plant")
        _field(page, "bc-address").fill("9")
        # BoltMovingIn must be set: no lock meets it, whatever the earlier tests did to the doors
        _field(page, "bc-p1").fill("0x0800")
        _field(page, "bc-p2").fill("0x0800")
        expect(page.locator('[data-testid="bc-known"]')).to_contain_text("none would take it")
        save_shot(page, tmp_path, f"device-door-1-{width}x{height}.png")
        page.locator('[data-testid="bc-send"]').click()
        dialog = page.locator(".q-dialog")
        expect(dialog).to_contain_text("Up to 2 locks on line1 may take address 9")
        expect(dialog).to_contain_text("door-1, door-2")
        page.wait_for_timeout(400)  # the dialog fades in
        page.screenshot(path=str(tmp_path / "dialog.png"))
        SHOTS.mkdir(parents=True, exist_ok=True)
        shutil.copy(tmp_path / "dialog.png", SHOTS / f"broadcast-confirm-{width}x{height}.png")
        dialog.get_by_role("button", name="Cancel").click()
        expect(dialog).to_have_count(0)
    finally:
        context.close()
    assert not errors, f"JavaScript errors on the page: {errors}"
