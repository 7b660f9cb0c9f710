"""A replay never impersonates a device, and asks before it sends (issue 40; issue 42 item 11).

A recording of a bus holds what the devices sent (an HD-Lock's status under its own ID, Electrak status
0x07, Electrak internal traffic 0x600-0x6FF, an M3IO's inputs): replayed, those frames would make every
listener believe the device said so. Each frame is judged by the one send policy; what a device sends is
kept off, counted and named; the start asks a confirmation that says how many frames go out."""

from __future__ import annotations

import asyncio

import pytest
from plants import ELECTRAK_ACTUATORS, device
from test_replay import collect, replay_env

from app import replay as rp
from app.can_bus import FrameRecord
from app.worker import PermissionDenied
from tests.webutil import eventually

pytestmark = pytest.mark.timeout(60)
LOCK_ID = 335  # extended (section 6.5: the lock answers with its device ID as CAN ID)


@pytest.fixture
async def env():
    devices = (device("io", "m3io", "can9", variant="HM", sw1=0x1A),
               device("lock", "hdlock", "can9", device_id=LOCK_ID, extended=True),
               device("arm", "electrak", "can9", actuators=ELECTRAK_ACTUATORS))
    async with replay_env(*devices, prefix="replay-device") as env:
        yield env


def _recording() -> list[FrameRecord]:
    t0 = 1000.0
    return [
        FrameRecord(t0 + 0.00, 0x123, False, 2, b"\x01\x02", "rx"),  # nobody's frame: goes out
        FrameRecord(t0 + 0.01, LOCK_ID, True, 8, bytes.fromhex("01 00 17 01 00 00 00 00"), "rx"),  # lock status
        FrameRecord(t0 + 0.02, 0x07, False, 8, bytes.fromhex("E8 03 41 00 BE 03 00 00"), "rx"),  # Electrak status
        FrameRecord(t0 + 0.03, 0x650, False, 8, bytes(8), "rx"),  # Electrak internal traffic
        FrameRecord(t0 + 0.04, 0x423, False, 1, b"\xC1", "rx"),  # the M3IO's DigIn (SW1 0x1A: base 0x422 + 1)
        FrameRecord(t0 + 0.05, 0x124, False, 1, b"\x03", "rx"),  # nobody's frame: goes out
    ]


async def test_frames_a_device_sends_are_never_replayed_and_each_is_named(env):
    worker, listener = env
    frames = _recording()
    screening = await asyncio.to_thread(rp.screen, worker, "can9", frames)
    assert screening.blocked == frozenset({1, 2, 3, 4}), screening.reasons
    assert screening.going_out(frames) == 2
    text = screening.text()
    assert text.startswith("4 frame(s) will not be sent") and all(n == 1 for n in screening.reasons.values()), text
    for i in (1, 2, 3, 4):  # each names why, as the send policy judged it
        rec = frames[i]
        assert rp.frame_reason(list(worker.plant.devices_on("can9")), rec.arbitration_id, rec.is_extended_id, rec.data)
    with pytest.raises(rp.NeedsConfirmation) as asked:
        await rp.start_replay(worker, "can9", frames, name="site.log", session="s1")
    assert asked.value.frames == 2
    assert "Replay 2 recorded frame(s) of site.log onto can9 (a live bus" in asked.value.question, asked.value.question
    assert "4 frame(s) will not be sent" in asked.value.question
    assert worker.extra_holders.get(rp.holder_name("can9")) is None and not worker.audit.rows  # nothing started
    replay = await rp.start_replay(worker, "can9", frames, name="site.log", session="s1", confirmed=True)
    await eventually(lambda: replay.state == "done", timeout=5)
    assert replay.sent == 2 and replay.filtered == 4
    assert "4 kept off the bus by the device policies" in replay.summary()
    got = await collect(listener, 6, 1.0, poll_s=0.1)
    assert sorted((m.arbitration_id, m.is_extended_id) for m in got) == [(0x123, False), (0x124, False)], got
    row = worker.audit.rows[-1]
    assert "2 of 6 frames" in row.get("result", "") or "2 of 6 frames" in str(row), row


async def test_a_recording_of_device_frames_only_is_refused_with_the_reasons(env):
    worker, _listener = env
    frames = _recording()[1:5]
    with pytest.raises(rp.ReplayError, match="nothing of dev.log may go out onto can9: 4 frame"):
        await rp.start_replay(worker, "can9", frames, name="dev.log", session="s1")


async def test_a_viewer_is_refused_before_any_question(env):
    worker, _listener = env
    with pytest.raises(PermissionDenied):
        await rp.start_replay(worker, "can9", _recording(), session="v", role="viewer", user="vera")
