"""The replay page (/monitor/BUS/replay) with NiceGUI's simulated user: choose a recording of the data
folder, replay it, progress and the end state shown."""

from __future__ import annotations

import can
from nicegui import ui
from plants import can_bus, channel, plant

from app import recording as rec
from app.runtime import Runtime
from tests.webutil import eventually, simulated_user



def replay_runtime(tmp_path, tag: str) -> Runtime:
    """A runtime with one CAN bus ``can9`` (a channel of its own, no twin) and a recording of 20 frames,
    ``can9-test.log``, in its data folder."""
    runtime = Runtime(plant(can_bus(name="can9", channel_name=channel(tag), bitrate=500000, simulate=None)), simulate=False,
                      data_dir=tmp_path / "data")
    folder = runtime.data_dir / "recordings"
    folder.mkdir(parents=True)
    writer = rec.WRITERS[".log"][0](folder / "can9-test.log")
    for i in range(20):
        writer.on_message_received(can.Message(timestamp=100 + i * 0.01, arbitration_id=0x300 + i, data=bytes([i])))
    writer.stop()
    return runtime


async def test_replay_page_replays_a_recording(tmp_path):
    runtime = replay_runtime(tmp_path, "replay-page")
    async with simulated_user(runtime) as user:
        await user.open("/monitor/can9/replay")
        await user.should_see("Replay onto can9")
        select = user.find(kind=ui.select).elements
        choice = next(e for e in select if e.props.get("label") == "Recordings in the data folder")
        choice.set_value("can9-test.log")
        await user.should_see("can9-test.log: 20 frames")
        user.find("Start replay").click()
        # asks first, naming how many frames go out (issue 42 item 11: 297 frames went out unasked)
        await user.should_see("Replay 20 recorded frame(s) of can9-test.log onto can9 (a live bus")
        assert not any(f.direction == "tx" for f in runtime.worker.can_buses["can9"].state.frames)
        user.find("Send 20 frames").click()
        await eventually(lambda: any(f.direction == "tx" for f in runtime.worker.can_buses["can9"].state.frames), timeout=5)
        await user.should_see("done: 20 of 20 frames sent", retries=50)
        sent = [f.arbitration_id for f in runtime.worker.can_buses["can9"].state.frames if f.direction == "tx"]
        assert sent == [0x300 + i for i in range(20)]
