"""Uploads to the replay page (issue 33, items 6 and 9): a file named '..' gets a clear message, not a
traceback; an upload is stored in the one uploads folder (no temporary folder per upload) and replayable."""

from __future__ import annotations

import tempfile
from pathlib import Path

from nicegui import ui
from nicegui.elements.upload_files import SmallFileUpload
from plants import can_bus, channel, plant

from app.runtime import Runtime
from tests.webutil import simulated_user

TRACE = b"(1700000000.000000) can0 301#01\n(1700000000.010000) can0 302#02\n"


async def test_replay_uploads_are_named_and_stored_in_one_folder(tmp_path):
    runtime = Runtime(plant(can_bus(name="can9", channel_name=channel("replay-upload"), bitrate=500000, simulate=None)), simulate=False, data_dir=tmp_path / "data")
    temporary = set(Path(tempfile.gettempdir()).glob("replay-*"))
    async with simulated_user(runtime) as user:
        await user.open("/monitor/can9/replay")
        await user.should_see("Replay onto can9")
        upload = user.find(kind=ui.upload).elements.pop()
        await upload.handle_uploads([SmallFileUpload("..", "text/plain", TRACE)])
        await user.should_see("is not a file name for a recording")
        await upload.handle_uploads([SmallFileUpload("trace.log", "text/plain", TRACE)])
        await user.should_see("trace.log: 2 frames", retries=50)
    stored = list((runtime.data_dir / "recordings" / "uploads").iterdir())
    assert len(stored) == 1 and stored[0].name.endswith("-trace.log")
    assert set(Path(tempfile.gettempdir()).glob("replay-*")) == temporary  # no folder left per upload
