"""32.15: a .trc recording of one bus writes every frame on one bus number, received and sent alike
(received frames carried their interface channel, "demo-can1", and went to bus 2; sent ones to bus 1)."""

from __future__ import annotations

from pathlib import Path

import can
from can.io.trc import TRCReader

from app import recording as rec
from app.can_bus import CanBusState


def test_received_and_sent_frames_on_the_same_bus(tmp_path: Path):
    state = CanBusState("can1", "can", "virtual demo-can1")
    recording = rec.start_recording(state, ".trc", tmp_path)
    frames = [
        can.Message(timestamp=1000.0, arbitration_id=0x422, data=b"\x03", is_rx=True, channel="demo-can1"),
        can.Message(timestamp=1000.01, arbitration_id=0x0A, data=bytes(8), is_rx=False, channel=None),
        can.Message(timestamp=1000.02, arbitration_id=0x07, data=bytes(8), is_rx=True, channel=0),
    ]
    for msg in frames:
        recording.on_message_received(msg)
    rec.stop_recording(state)
    assert recording.error == "" and recording.frames == 3
    read = list(TRCReader(recording.path))
    assert [(m.arbitration_id, m.is_rx) for m in read] == [(0x422, True), (0x0A, False), (0x07, True)]
    assert {m.channel for m in read} == {read[0].channel}, [m.channel for m in read]
