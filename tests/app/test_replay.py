"""Replay of a recording onto a CAN bus (issue 17 item 5): order and timing, stop, refusal while a
device is under control, engineers only and audited, and the dead-man rule."""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import time
from collections.abc import AsyncIterator
from pathlib import Path

import can
import pytest
from plants import can_bus, device, plant

from app import recording as rec
from app import replay as rp
from app.can_bus import FrameRecord
from app.worker import PermissionDenied, Worker
from tests.webutil import eventually

_channels = itertools.count()


class Audit:
    def __init__(self):
        self.rows: list[dict] = []

    async def arecord(self, **row):
        self.rows.append(dict(row))
        return len(self.rows) - 1

    async def afinish(self, row, result):
        self.rows[row]["result"] = result


@contextlib.asynccontextmanager
async def replay_env(*devices: str, prefix: str = "replay-test") -> AsyncIterator[tuple[Worker, can.BusABC]]:
    """A worker on the virtual CAN bus can9 (no twins) with ``devices``, and a listener on the same channel;
    on leaving, every replay still running is stopped and the bus closed."""
    channel = f"{prefix}-{next(_channels)}-{time.monotonic_ns()}"
    worker = Worker(plant(can_bus(*devices, name="can9", channel_name=channel, bitrate=500000, simulate=None)),
                    audit=Audit())
    await worker.can_buses["can9"].start()
    await eventually(lambda: worker.can_buses["can9"].bus is not None, timeout=5)
    listener = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
    try:
        yield worker, listener
    finally:
        for replay in [h for h in worker.extra_holders.values() if isinstance(h, rp.Replay)]:
            replay.stop("test over")
        await worker.can_buses["can9"].stop()
        listener.shutdown()


@pytest.fixture
async def env():
    async with replay_env(device("io", "m3io", "can9", variant="HM", sw1=0x1A)) as env:
        yield env


def _frames(n: int, gap_s: float) -> list[FrameRecord]:
    frames = []
    for i in range(n):
        ext = i % 3 == 0
        frames.append(FrameRecord(1000.0 + i * gap_s, (0x1ABCDE00 + i) if ext else (0x100 + i), ext, 2, bytes([i & 0xFF, 0x5A]), "rx"))
    frames.insert(3, FrameRecord(1000.0 + 2.5 * gap_s, 0, False, 0, b"", "rx", is_error_frame=True))
    return frames


async def collect(listener: can.Bus, count: int, timeout: float, poll_s: float = 0.2) -> list[can.Message]:
    """Up to ``count`` frames that ``listener`` hears within ``timeout``."""
    got: list[can.Message] = []
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while len(got) < count and loop.time() < end:
        msg = await asyncio.to_thread(listener.recv, poll_s)
        if msg is not None:
            got.append(msg)
    return got


async def test_replay_of_a_recording_reproduces_its_frames_in_order(env, tmp_path: Path):
    worker, listener = env
    path = tmp_path / "source.trc"
    writer = rec.WRITERS[".trc"][0](path)
    for f in _frames(30, 0.02):
        if not f.is_error_frame:
            writer.on_message_received(can.Message(timestamp=f.time, arbitration_id=f.arbitration_id,
                                                   is_extended_id=f.is_extended_id, data=f.data))
    writer.stop()
    loaded = rec.read_log(path)
    started = time.monotonic()
    replay = await rp.start_replay(worker, "can9", loaded.frames, name=loaded.name, speed=2.0, session="s1", confirmed=True)
    assert replay.running and rp.running_replay(worker, "can9") is replay
    got = await collect(listener, len(loaded.frames), timeout=10)
    await eventually(lambda: replay.state == "done", timeout=5)
    elapsed = time.monotonic() - started
    assert [(m.arbitration_id, m.is_extended_id, bytes(m.data)) for m in got] == [
        (f.arbitration_id, f.is_extended_id, f.data) for f in loaded.frames]
    assert replay.sent == 30 and replay.fraction == 1.0
    assert 0.25 < elapsed < 5  # 0.58 s recorded at 2x: about 0.29 s (loose bound)
    shown = [f for f in worker.can_buses["can9"].state.frames if f.direction == "tx"]  # the monitor shows them as sent
    assert [(f.arbitration_id, f.data) for f in shown] == [(f.arbitration_id, f.data) for f in loaded.frames]
    assert "replay" not in " ".join(worker.extra_holders)  # done: no longer a holder
    assert worker.audit.rows[-1]["action"] == "replay source.trc onto can9 at 2 x" and worker.audit.rows[-1]["result"].startswith("ok")


async def test_error_frames_are_skipped_and_speed_scales(env):
    worker, listener = env
    frames = _frames(10, 0.05)  # 0.45 s recorded
    started = time.monotonic()
    replay = await rp.start_replay(worker, "can9", frames, speed=0.5, session="s1", confirmed=True)
    await eventually(lambda: replay.state == "done", timeout=10)
    elapsed = time.monotonic() - started
    assert replay.sent == 10 and replay.skipped == 1
    assert elapsed > 0.8  # at half speed about 0.9 s
    got = await collect(listener, 10, timeout=3)
    assert len(got) == 10


async def test_stop_at_any_time_and_the_dead_man_rule(env):
    worker, listener = env
    frames = _frames(200, 0.01)
    replay = await rp.start_replay(worker, "can9", frames, session="s1", confirmed=True)
    await eventually(lambda: replay.sent >= 5, timeout=5)
    replay.stop()
    sent = replay.sent
    assert replay.state == "stopped" and not replay.holders() and rp.holder_name("can9") not in worker.extra_holders
    await asyncio.sleep(0.1)  # (a stopped replay would have sent ~10 more meanwhile)
    assert replay.sent == sent < 200
    again = await rp.start_replay(worker, "can9", frames, session="s2", confirmed=True)
    await eventually(lambda: again.sent >= 5, timeout=5)
    assert again.holders() == {"s2"}
    worker.session_closed("s1")  # another browser leaving changes nothing
    assert again.running
    worker.heartbeat("s2")
    worker.beats["s2"] -= 10  # s2 froze: the supervisor trips it
    worker._supervise_deadman(time.monotonic())
    assert again.state == "stopped" and "dead-man" in again.reason


async def test_refused_while_a_device_is_under_control_and_for_viewers(env, monkeypatch: pytest.MonkeyPatch):
    worker, _listener = env
    frames = _frames(5, 0.01)
    with pytest.raises(PermissionDenied):
        await rp.start_replay(worker, "can9", frames, session="v", role="viewer", user="vera")
    assert worker.audit.rows[-1]["result"].startswith("refused")
    monkeypatch.setattr(worker.adapters["io"], "holders", lambda: {"other"}, raising=False)
    with pytest.raises(rp.ReplayError, match="io on can9 is under control"):
        await rp.start_replay(worker, "can9", frames, session="s1", confirmed=True)
    assert worker.audit.rows[-1]["result"].startswith("failed: io on can9 is under control")
    monkeypatch.setattr(worker.adapters["io"], "holders", lambda: set(), raising=False)
    long = _frames(300, 0.01)
    replay = await rp.start_replay(worker, "can9", long, session="s1", confirmed=True)
    with pytest.raises(rp.ReplayError, match="runs on can9 already"):
        await rp.start_replay(worker, "can9", frames, session="s1", confirmed=True)
    monkeypatch.setattr(worker.adapters["io"], "holders", lambda: {"other"}, raising=False)  # taken meanwhile
    await eventually(lambda: replay.state == "stopped", timeout=2)
    assert "io came under control" in replay.reason and replay.sent < 300
    with pytest.raises(rp.ReplayError, match="outside"):
        await rp.start_replay(worker, "can9", frames, speed=1000, session="s1", confirmed=True)
