"""What app/ words itself on the bus tools, in German (issue 47): a recording's and a recorded file's errors, the
transmit list's and the Modbus poll's refusals and the send policy's questions, a replay's question, screening and
summary, the overview's bus line and the server's pages for an unknown bus. The English stays as it was (the audit
rows keep it)."""

from __future__ import annotations

import pytest
from nicegui import ui
from nicegui.elements.upload_files import SmallFileUpload
from test_i18n_pages import english_on, german_demo, german_user

pytestmark = pytest.mark.timeout(60)


async def test_a_recorded_files_errors_in_german(tmp_path, monkeypatch):
    """The CAN monitor's file tab (pages/can_files.py): a file of no known format and a broken BLF file, said in German
    with where reading stopped."""
    async with german_demo(tmp_path, monkeypatch) as (runtime, user):
        await user.open("/monitor/can1")
        await user.should_see("Busmonitor can1", retries=50)
        upload = next(iter(user.find(marker="upload").elements))
        await upload.handle_uploads([SmallFileUpload("notes.txt", "text/plain", b"hello")])
        await user.should_see("notes.txt: Dateityp .txt wird nicht unterstützt", retries=50)
        await upload.handle_uploads([SmallFileUpload("broken.blf", "application/octet-stream", b"not a blf file" * 10)])
        await user.should_see("broken.blf: kann nicht als .blf-Datei geöffnet werden (Byte-Offset", retries=50)
        assert not [m for m in user.notify.messages if "cannot open" in m or "unsupported" in m], user.notify.messages
        found = english_on(user)
        assert found == [], "\n".join(map(str, found))


async def test_a_replays_refused_upload_in_german(tmp_path):
    """The replay page (pages/bus_replay.py): an upload named '..' is refused in German."""
    from test_replay_page import replay_runtime

    runtime = replay_runtime(tmp_path, "replay-upload-de")
    async with german_user(runtime) as user:
        await user.open("/monitor/can9/replay")
        await user.should_see("Wiedergabe auf can9", retries=50)
        upload = user.find(kind=ui.upload).elements.pop()
        await upload.handle_uploads([SmallFileUpload("..", "text/plain", b"(1700000000.000000) can0 301#01\n")])
        await user.should_see("'..' ist kein Dateiname für eine Aufzeichnung (z. B. trace.log)", retries=50)
        assert english_on(user) == []
