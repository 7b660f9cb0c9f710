"""The record page on the loopback address: an approval and a sign-off ask for an engineer account at
that moment, a sign-off lists what is open first, and the record's check says whether it was altered."""

from __future__ import annotations

import asyncio

import pytest
from webutil import simulated_user

from tests.conftest import wait_for
from tests.recordutil import demo_plant

pytestmark = pytest.mark.timeout(90)


def _present(user, **query) -> list:
    """The elements of the page that match (none: an empty list, not an error)."""
    try:
        return list(user.find(**query).elements)
    except AssertionError:
        return []


def _one(user, marker):
    return next(iter(user.find(marker=marker).elements))


def _account(user, name: str, password: str) -> None:
    """The account asked for in the open dialog, given."""
    _one(user, "account-name").value = name
    _one(user, "account-password").value = password
    user.find(marker="account-ok").click()


async def test_sign_off_on_loopback_asks_for_an_account_and_lists_what_is_open(tmp_path):
    from app.runtime import Runtime

    runtime = Runtime(demo_plant(("door-1",)), simulate=True, data_dir=tmp_path / "data")
    async with simulated_user(runtime) as user:
        state = runtime.store.devices["door-1"]
        assert await wait_for(lambda: state.status == "online" and state.value("LockRequestDelay") is not None, 15)
        await asyncio.to_thread(runtime.users.add, "anna", "engineer", "anna-password")
        await asyncio.to_thread(runtime.users.add, "vera", "viewer", "vera-password")
        await user.open("/record/door-1")

        # approve: asks for the account
        user.find(marker="record-approve").click()
        await user.should_see("Approving the set of door-1: who is it?", retries=100)
        user.find(marker="account-name").type("vera")
        user.find(marker="account-password").type("vera-password")
        user.find(marker="account-ok").click()
        await user.should_see("vera has the viewer role: an engineer account approves and signs", retries=100)
        _account(user, "anna", "anna-password")
        await user.should_see("approved set stored (account anna)", retries=100)
        approved = await runtime.record.timeline("door-1", ("approved",))
        assert approved[0].user == "anna" and approved[0].data["account"] == "anna"

        # sign the plant: no checkout yet, listed first; cancelled, nothing signed
        _one(user, "sign-name").value = "Anna Berg"
        user.find(marker="sign-plant").click()
        await user.should_see("door-1: no checkout run", retries=100)
        user.find(marker="gaps-cancel").click()
        await asyncio.sleep(0.2)  # time for a cancelled sign-off to be written: none may be
        assert await runtime.record.timeline(None, ("signoff",)) == []

        # signed anyway, with the account given at that moment (a wrong password first)
        user.find(marker="sign-plant").click()
        await user.should_see("door-1: no checkout run", retries=100)
        user.find(marker="gaps-sign").click()
        await user.should_see("Signing plant demo: who is it?", retries=100)
        _account(user, "anna", "wrong")
        await user.should_see("Wrong user name or password", retries=100)
        assert await runtime.record.timeline(None, ("signoff",)) == []
        _one(user, "account-password").value = "anna-password"
        user.find(marker="account-ok").click()
        await user.should_see("signed by Anna Berg with account anna", retries=100)
        signoff = (await runtime.record.timeline(None, ("signoff",)))[0]
        assert signoff.user == "anna" and signoff.data["account"] == "anna" and signoff.data["name"] == "Anna Berg"

        user.find(marker="check-record").click()
        await user.should_see("intact", retries=100)


async def test_no_account_yet_is_said_with_what_to_do(tmp_path):
    from app.runtime import Runtime

    runtime = Runtime(demo_plant(("door-1",)), simulate=True, data_dir=tmp_path / "data")
    async with simulated_user(runtime) as user:
        assert await wait_for(lambda: runtime.store.devices["door-1"].status == "online", 15)
        await user.open("/record/door-1")
        _one(user, "sign-name").value = "Anna Berg"
        user.find(marker="sign-device").click()
        await user.should_see("door-1: no checkout run", retries=100)
        user.find(marker="gaps-sign").click()
        await user.should_see("commission user add NAME --role engineer", retries=100)
        assert await runtime.record.timeline(None, ("signoff",)) == []


async def test_a_question_to_act_on_a_simulated_device_offers_the_twin_control_in_the_same_tab(tmp_path):
    """The M3IO checkout asks to toggle an input: on the demo the inputs are the twin's, so the question
    offers its control, and the checkout passes in one tab."""
    from nicegui import ui

    from app.runtime import Runtime

    runtime = Runtime(demo_plant(("heater-hmr",)), simulate=True, data_dir=tmp_path / "data")
    async with simulated_user(runtime) as user:
        state = runtime.store.devices["heater-hmr"]
        assert await wait_for(lambda: state.status == "online", 15)
        await user.open("/record/heater-hmr")
        user.find(marker="checkout-run").click()
        run = None
        for _ in range(300):
            runtime.worker.heartbeat(user.client.id)  # the page's browser is alive (the simulated user sends no beats)
            run = runtime.record.runs.get("heater-hmr")
            if run is not None and run.status not in ("ready", "running"):
                break
            if _present(user, marker="checkout-yes"):
                question = " ".join(e.text for e in _present(user, kind=ui.label) if e.text.startswith(("Toggle", "Is ", "Are ")))
                if "Toggle" in question:
                    name = question.split()[1]
                    before = state.entry(name)["value"]
                    user.find(marker="checkout-twin-action").click()
                    assert await wait_for(lambda: state.entry(name)["value"] != before, 5), question
                user.find(marker="checkout-yes").click()
            await asyncio.sleep(0.1)
        assert run is not None and run.status == "passed", "; ".join(f"{r.name}: {r.status} {r.reason}" for r in run.results if r.status != "passed")
        audit = await runtime.audit.aquery(device="heater-hmr", limit=50)
        assert any(a.action.startswith("simulation: toggle E") for a in audit), [a.action for a in audit]
        timeline = _one(user, "record-timeline")  # the run's row shows up in the page's timeline, without a reload
        assert await wait_for(lambda: any(r["title"] == "SSR outputs on and off: passed" for r in timeline.rows), 5), \
            timeline.rows
