"""A socket event naming a listener its element does not have is refused and counted (app/web.py's
SocketEventGuard), through NiceGUI's own lookup of the listener: no private attribute of NiceGUI is read."""

from __future__ import annotations

import pytest
from nicegui import Client, ui
from nicegui.testing import User

from app.web import SocketEventGuard


async def test_an_event_for_an_unknown_listener_is_refused_and_a_known_one_runs(user: User):
    clicks: list[int] = []

    @ui.page("/listener")
    def page() -> None:
        ui.button("press", on_click=lambda: clicks.append(1))

    await user.open("/listener")
    client = user.client
    button = next(e for e in client.elements.values() if isinstance(e, ui.button))
    guard = SocketEventGuard()
    handler = guard._wrap("event", lambda sid, msg: Client.instances[msg["client_id"]].handle_event(msg))  # noqa: SLF001
    base = {"client_id": client.id, "id": button.id, "args": []}

    assert await handler("test-1", {**base, "listener_id": "nope"}) is None
    assert guard.malformed == 1 and clicks == []

    # the listener's id as the page sends it to the browser (the element's events)
    listener_id = next(e["listener_id"] for e in button._to_dict()["events"])  # noqa: SLF001
    await handler("test-1", {**base, "listener_id": listener_id})
    assert clicks == [1] and guard.malformed == 1


async def test_a_key_error_of_another_kind_of_message_is_not_taken_for_a_listener():
    guard = SocketEventGuard()

    def inner(sid, msg):
        raise KeyError("x")

    with pytest.raises(KeyError):
        await guard._wrap("ack", inner)("test-1", {"client_id": "c", "next_message_id": 0})  # noqa: SLF001
