"""The record page in chromium: a checkout run with its question answered, the plant signed,
and the page at 1440x900 and 768x1024 (screenshots under /tmp/shots/)."""

from __future__ import annotations

import json
import urllib.request
from pathlib import Path

import pytest
from conftest import shot, wait_devices_online
from webutil import click_until, demo_plant_text, free_port, opened, running_app

pytestmark = pytest.mark.timeout(150)
SHOTS = Path("/tmp/shots")


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    from app.users import UserStore, default_data_dir

    folder = tmp_path_factory.mktemp("record")
    # who approves and signs: an account in the data folder the app will use (this run's, from the environment)
    UserStore(default_data_dir() / "users.toml").add("anna", "engineer", "anna-password")
    with running_app(demo_plant_text(free_port()), folder) as url:
        wait_devices_online(url, ["door-2"], timeout=40)
        yield url


def log_in(page) -> None:
    """The account asked for at the moment of approving or signing (the page is on the loopback address)."""
    page.get_by_label("Account").fill("anna")
    page.get_by_label("Password").fill("anna-password")
    shot(page, str(SHOTS / "record-account-1440x900.png"), full_page=False)
    page.get_by_role("button", name="Log in and continue").click()


def test_checkout_sign_and_drift_from_the_record_page(chromium, app):
    SHOTS.mkdir(exist_ok=True)
    with opened(chromium, f"{app}/record/door-2") as page:
        page.get_by_role("button", name="Approve current set").click()
        log_in(page)
        page.get_by_text("approved set stored (account anna)").wait_for(timeout=15000)
        page.get_by_role("button", name="Run checkout").click()
        passed = page.get_by_text("checkout passed")
        for _ in range(300):  # every question answered yes; a person's part done on the twin where it is offered
            if passed.count():
                break
            yes = page.get_by_role("button", name="Yes")
            if yes.count() and yes.first.is_visible():
                act = page.get_by_role("button", name="on the simulated device")
                if act.count():
                    act.first.click()
                yes.first.click()
            page.wait_for_timeout(100)
        try:
            passed.wait_for(timeout=30000)
        except Exception:
            shot(page, str(SHOTS / "record-checkout-failed.png"))
            raise
        page.get_by_label("Name").fill("Anna Berg")
        page.get_by_label("Comment").fill("door-2 cycled on site")
        page.get_by_role("button", name="Sign plant demo").click()
        page.get_by_text("Sign plant demo although these are open?").wait_for(timeout=90000)  # the other devices: no checkout
        shot(page, str(SHOTS / "record-sign-open-items-1440x900.png"), full_page=False)
        page.get_by_role("button", name="Sign anyway").click()
        log_in(page)
        try:
            page.get_by_text("signed by Anna Berg with account anna").wait_for(timeout=90000)
        except Exception:
            shot(page, str(SHOTS / "record-failed.png"))
            raise
        # the check changes nothing: pressed again if the card drawn anew after the sign-off took the first press
        click_until(page.get_by_role("button", name="Check the record"), page.get_by_text("intact ("), each_ms=15_000)
        shot(page, str(SHOTS / "record-1440x900.png"), full_page=False)
        shot(page, str(SHOTS / "record-1440x900-full.png"), full_page=True)
        page.set_viewport_size({"width": 768, "height": 1024})
        shot(page, str(SHOTS / "record-768x1024.png"), full_page=False)
        shot(page, str(SHOTS / "record-768x1024-full.png"), full_page=True)
    with urllib.request.urlopen(f"{app}/api/devices", timeout=5) as response:
        door = next(d for d in json.load(response) if d["name"] == "door-2")
    # the lock raises its measured maximum bolt times (RW holding 1003/1004) during the cycle: measured
    # values (Param.device_updates), never drift
    assert door["drift"]["approved"] and door["drift"]["changed"] == []
