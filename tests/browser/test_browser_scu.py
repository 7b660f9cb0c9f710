"""Real browser on the SCU page: take control, move actuator 1 to a remote position, watch the
position rise on the chart, stop, release."""

from __future__ import annotations

import contextlib
import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import CHROMIUM, free_port, inside_viewport, shot
from plants import plant_text, scu_line
from webutil import running_app

pytestmark = [pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian's chromium is not installed"), pytest.mark.timeout(90)]


def scu_plant(port: int) -> str:
    return plant_text(scu_line("lift-1", "rs232-1", port, timeout=None, poll_period=None), name="scu-test")


@contextlib.contextmanager
def scu_page(chromium, folder: Path) -> Iterator[tuple[str, object]]:
    """lift-1's page in chromium (1440 x 900) on an app of its own, once its remote session is open: yields the
    app's URL and the page, closed on leaving."""
    from playwright.sync_api import expect

    with running_app(scu_plant(free_port()), folder) as url:
        page = chromium.new_page(viewport={"width": 1440, "height": 900})
        try:
            page.goto(f"{url}/device/lift-1")
            expect(page.get_by_test_id("session")).to_contain_text("open", timeout=15_000)
            yield url, page
        finally:
            page.close()


def counts(page) -> int:
    text = page.get_by_test_id("pos-A1").inner_text()
    match = re.search(r"(-?\d+) counts", text)
    assert match, text
    return int(match.group(1))


COUNTS_JS = """() => { const m = /(-?\\d+) counts/.exec(document.querySelector('[data-testid="pos-A1"]').innerText);
                         return m ? parseInt(m[1]) : null; }"""


def test_move_actuator_1_to_a_remote_position_and_stop(tmp_path, chromium):
    from playwright.sync_api import TimeoutError as PlaywrightTimeout
    from playwright.sync_api import expect

    with scu_page(chromium, tmp_path) as (_url, page):
        start = counts(page)
        page.get_by_test_id("take-control").click()
        expect(page.get_by_text("you hold control")).to_be_visible()
        target = page.get_by_test_id("remote-pos-A1")
        target.scroll_into_view_if_needed()
        target.fill("120")  # mm: 1200 counts at 10 counts per mm
        page.get_by_test_id("set-pos-A1").click()
        expect(page.get_by_text("remote position written and read back")).to_be_visible()
        page.get_by_test_id("go").click()
        page.get_by_role("button", name="The area is clear: Go").click()  # Go asks first (issue 25.4)
        # the position rises
        try:
            page.wait_for_function(f"() => ({COUNTS_JS})() >= {start + 100}", timeout=15_000)
        except PlaywrightTimeout:  # say what the page showed: the events, the drive card, the position
            raise AssertionError(f"A1 did not rise from {start} counts: it shows {counts(page)}; events: "
                                 f"{page.get_by_test_id('events').inner_text()[:1500]}") from None
        page.get_by_test_id("stop").click()
        expect(page.get_by_text("RS pending: none")).to_be_visible()
        # standing still: the shown position stops changing (two equal readings 1.5 s apart, longer than the page refresh)
        page.wait_for_function(
            f"""() => new Promise(done => {{ const a = ({COUNTS_JS})();
                    setTimeout(() => done(a !== null && ({COUNTS_JS})() === a), 1500); }})""",
            polling=100,
        )
        stopped = counts(page)
        assert stopped < 1200, f"actuator 1 reached its target {stopped} counts: Stop (RS) did nothing"
        page.get_by_test_id("pos-A1").scroll_into_view_if_needed()
        inside_viewport(page, page.get_by_test_id("pos-A1"))
        shot(page, str(tmp_path / "scu-moved.png"))
        try:
            expect(page.get_by_text("you hold control")).to_be_visible()
        except AssertionError:
            raise AssertionError("control lost after the stop; events: "
                                 f"{page.get_by_test_id('events').inner_text()[:1500]}") from None
        page.get_by_role("button", name="Release control").click()
        expect(page.get_by_text("nobody holds control")).to_be_visible()
