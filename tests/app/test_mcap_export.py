"""MCAP export of a CAN recording and of the demo plant's live data, read back with the ``mcap`` package's reader."""

from __future__ import annotations

import asyncio
import json

import can
import pytest
from mcap.reader import make_reader
from webutil import private_endpoints

from app.cli import main
from app.mcap_export import collect_live, write_live
from app.plant import load_plant
from app.runtime import Runtime

pytestmark = pytest.mark.timeout(90)


def _read(path):
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        messages = [(channel.topic, schema, message, json.loads(message.data))
                    for schema, channel, message in reader.iter_messages(log_time_order=False)]
    return summary, messages


def test_recording_as_mcap_through_the_command_line(tmp_path, capsys):
    source = tmp_path / "can2.log"
    frames = [can.Message(timestamp=1_700_000_000 + i * 0.01, arbitration_id=0x0A1234 + (i % 2), is_extended_id=True,
                          data=bytes([i, 0xFF, 0x10, 0, 0, 0, 0, i]), channel="can0") for i in range(50)]
    frames.append(can.Message(timestamp=1_700_000_001, arbitration_id=0x123, is_extended_id=False, data=b"\x01\x02"))
    with can.CanutilsLogWriter(str(source)) as writer:
        for msg in frames:
            writer.on_message_received(msg)
    out = tmp_path / "can2.mcap"
    assert main(["export", "--format", "mcap", str(source), "--bus", "can2", "--out", str(out)]) == 0
    assert "51 messages" in capsys.readouterr().out
    summary, messages = _read(out)
    assert [c.topic for c in summary.channels.values()] == ["/can/can2"]
    assert {s.encoding for s in summary.schemas.values()} == {"jsonschema"}
    assert {c.message_encoding for c in summary.channels.values()} == {"json"}
    assert len(messages) == 51
    first = messages[0][3]
    assert first["id"] == 0x0A1234 and first["extended"] is True and first["data"] == list(frames[0].data)
    assert messages[0][2].log_time == 1_700_000_000 * 10**9
    assert messages[-1][3]["id"] == 0x123 and messages[-1][3]["hex"] == "01 02"
    assert all(isinstance(m[3]["decoded"], str) for m in messages)
    assert main(["export", "--format", "mcap", "--out", str(out)]) == 2  # neither a recording nor --live


async def test_live_points_and_frames_of_the_demo_plant(tmp_path):
    plant = private_endpoints(load_plant("plants/demo.toml"), f"mcap-{tmp_path.name}")
    runtime = Runtime(plant, data_dir=tmp_path / "data")
    await runtime.start()
    try:
        for _ in range(200):
            if all(s.history for n, s in runtime.store.devices.items() if s.type in ("electrak", "hdlock")) and \
                    all(runtime.worker.can_buses[b].state.frames for b in ("can1", "can2")):
                break
            await asyncio.sleep(0.1)
        rows = collect_live(runtime)
    finally:
        await runtime.stop()
    out = tmp_path / "live.mcap"
    count = await asyncio.to_thread(write_live, rows, out)
    summary, messages = _read(out)
    topics = {c.topic for c in summary.channels.values()}
    assert {f"/points/{d}" for d in plant.devices} <= topics
    assert {"/can/can1", "/can/can2"} <= topics
    assert count == len(messages) == sum(summary.statistics.channel_message_counts.values())
    times = [m[2].log_time for m in messages]
    assert times == sorted(times)
    lift = [m[3] for m in messages if m[0] == "/points/lift"]
    assert any(isinstance(v, int | float) for sample in lift for v in sample["values"].values())  # plottable numbers
    last = lift[-1]
    assert set(last["units"]) == set(last["values"]) and set(last["quality"]) == set(last["values"])
    frames = [m[3] for m in messages if m[0] == "/can/can2"]
    assert frames and all({"id", "data", "direction", "device", "decoded"} <= set(f) for f in frames)
    assert any(f["decoded"] for f in frames) and any(f["device"] == "lift" for f in frames)
