"""The MO 64 page for a viewer with accounts required (every 127.* address is a local engineer, so a viewer
exists only with logins): what a viewer may not do is disabled with the read-only reason before any click
(issue 42 item 9: "Release the connection" and "Deactivate" were enabled and refused only after a click).

Deactivating a close or reverse level is a stop (devices/mo64/control.py): every role may stop, so those two
stay enabled for a viewer; deactivating the open level moves the boom (it lets it close) and is disabled."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_auth import login
from webutil import by_testid, eventually, simulated_user

from app.runtime import Runtime
from app.users import UserStore
from pages.command_client import VIEWER_REASON
from plants import mo64_tcp, plant

pytestmark = pytest.mark.timeout(60)


def reason_of(element) -> str:
    """Why ``element`` is disabled ("" while it is enabled)."""
    return "" if element.enabled else element.props.get("data-disabled-reason", "disabled without a reason")


async def _page(tmp_path: Path, who: tuple[str, str]):
    store = UserStore(tmp_path / "users.toml")
    store.add("anna", "engineer", "correct horse")
    store.add("tablet", "viewer", "battery staple")
    runtime = Runtime(plant(mo64_tcp("gate")), simulate=True, data_dir=tmp_path, auth_required=True)
    return store, runtime


@pytest.mark.parametrize("who", [("tablet", "battery staple"), ("anna", "correct horse")], ids=["viewer", "engineer"])
async def test_connection_and_deactivate_buttons_follow_the_role(tmp_path: Path, who: tuple[str, str]):
    _store, runtime = await _page(tmp_path, who)
    async with simulated_user(runtime) as user:
        await login(user, *who)
        await eventually(lambda: runtime.store.devices["gate"].status == "online", timeout=15, what="gate online")
        await user.open("/device/gate")
        await user.should_see("Commands (chapter 5.2.1)")
        refused = ["release", "resume", "deactivate-open", "clear-levels", "pulse-open", "activate-close"]
        stops = ["deactivate-close", "deactivate-reverse"]
        expected = VIEWER_REASON if who[0] == "tablet" else ""
        reasons = {b: reason_of(by_testid(user, b)) for b in refused + stops}
        assert reasons == {**dict.fromkeys(refused, expected), **dict.fromkeys(stops, "")}, reasons
        if who[0] == "tablet":
            hint = by_testid(user, "deactivate-close").props.get("title", "")
            assert "anyone may stop" in hint, hint
