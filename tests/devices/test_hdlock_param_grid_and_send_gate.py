"""HD-Lock page: the address changes' Send buttons are off (with the reason) until a valid new address is entered,
and the Parameters card's long names stay inside their column (chromium at 768 and 1440 px)."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import CHROMIUM, shot, wait_devices_online
from nicegui import ui
from nicegui.testing import User
from webutil import LockPages, at_size, demo_plant_text, eventually, free_port, lock_pages_env, running_app

pytestmark = pytest.mark.timeout(90)

NO_ADDRESS = "enter the new address first (allowed 1 .. 254)"


env = pytest.fixture(lock_pages_env, name="env")  # a simulated user on the app of two locks (door-1 at 1, door-2 at 2)


def by_testid(user: User, testid: str) -> ui.element:
    assert user.client is not None
    if testid == "sa-address":  # the Set Modbus Address card's entry: the New address without a data-testid
        (element,) = [e for e in user.client.elements.values() if isinstance(e, ui.number)
                      and e.props.get("label") == "New address" and "data-testid" not in e.props]
        return element
    (element,) = [e for e in user.client.elements.values() if e.props.get("data-testid") == testid and e.visible]
    return element


async def test_send_buttons_are_off_with_the_reason_until_an_address_is_entered(env: LockPages):
    user = env.user
    await eventually(lambda: env.state("door-1").status == "online", timeout=10)
    await user.open("/device/door-1")
    await user.should_see("HD-Lock door-1")
    for prefix in ("sa", "bc"):
        send, address = by_testid(user, f"{prefix}-send"), by_testid(user, f"{prefix}-address")

        def off() -> None:
            assert not send.enabled
            assert send.props.get("data-disabled-reason") == NO_ADDRESS
            assert send.props.get("title") == NO_ADDRESS

        await eventually(off, timeout=3)
        address.value = 9
        await eventually(lambda: send.enabled and "data-disabled-reason" not in send.props, timeout=3)
        address.value = 300  # the field refuses it: Send is off with the field's reason
        await eventually(lambda: not send.enabled and send.props.get("data-disabled-reason")
                         == "address 300 is refused: out of range: allowed 1 .. 254", timeout=3)
        address.value = None
        await eventually(off, timeout=3)
    # a silent lock: the reason is its silence, whatever is entered
    by_testid(user, "sa-address").value = 9
    env.twin("door-1").silent = True
    send = by_testid(user, "sa-send")
    await eventually(lambda: not send.enabled
                     and send.props.get("data-disabled-reason", "").startswith("the device does not answer"), timeout=10)
    env.twin("door-1").silent = False
    await eventually(lambda: send.enabled, timeout=10)


if CHROMIUM.exists():
    from playwright.sync_api import Browser, expect

    @pytest.fixture(scope="module")
    def app_url(tmp_path_factory: pytest.TempPathFactory):
        with running_app(demo_plant_text(free_port()), tmp_path_factory.mktemp("param-grid")) as url:
            wait_devices_online(url, ("door-1",), timeout=30)
            yield url

    GRID_SIZES = ((1440, 900), (768, 1024))

    def test_parameter_names_stay_in_their_column(app_url: str, chromium: Browser, tmp_path: Path):
        """At 1440x900 and with the page made 768x1024 (loaded once), each checked once laid out anew."""
        page = chromium.new_context(viewport={"width": GRID_SIZES[0][0], "height": GRID_SIZES[0][1]}).new_page()
        page.set_default_timeout(10_000)
        try:
            page.goto(app_url + "/device/door-1")
            grid = page.locator('[data-testid="param-grid"]')
            grid.scroll_into_view_if_needed()
            expect(page.locator('[data-param-name="SettingsProximityThresholdUnlock"]')).to_be_visible()
            for width, height in GRID_SIZES:
                with at_size(page, width, height):
                    grid.scroll_into_view_if_needed()
                    expect(page.locator('[data-param-name="SettingsProximityThresholdUnlock"]')).to_be_visible()
                    boxes = page.evaluate(_GRID_ROWS_JS)
                    assert len(boxes) >= 13
                    for row in boxes:
                        assert row["nameRight"] <= row["currentLeft"] + 0.5, row  # the name never runs into the value
                        assert row["currentRight"] <= row["entryLeft"] + 0.5, row
                    widest = max(row["currentRight"] for row in boxes)
                    assert boxes[0]["entryLeft"] - widest <= 48, boxes  # no wide gap between Current and New value
                    shot(page, str(tmp_path / f"param-grid-{width}.png"), full_page=True)
        finally:
            page.context.close()

    _GRID_ROWS_JS = """() => {
        const text = (element) => { const r = document.createRange(); r.selectNodeContents(element);
                                    return r.getBoundingClientRect(); };
        const cells = [...document.querySelector('[data-testid="param-grid"]').children];
        const rows = [];
        for (let i = 5; i + 4 < cells.length; i += 5) {
            rows.push({name: cells[i + 1].innerText,
                       nameRight: text(cells[i + 1].querySelector('[data-param-name]')).right,
                       currentLeft: cells[i + 2].getBoundingClientRect().left,
                       currentRight: text(cells[i + 2].querySelector('.mono')).right,
                       entryLeft: cells[i + 3].getBoundingClientRect().left});
        }
        return rows;
    }"""
