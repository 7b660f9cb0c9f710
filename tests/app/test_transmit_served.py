"""A transmitted frame that this tool's own cyclic frame overrides (issue 42 item 11): an M3IO DigOut with SSR1
on, sent from the transmit list while the tool serves that module's watchdog with every output off. The engineer
is told before sending (with the mains question) and after it: the module is served by this tool, and its next
DigOut sets the outputs back to what the module's page shows."""

from __future__ import annotations

import time

import pytest

from app.transmit import NeedsConfirmation, make_row, named_row, transmit_list
from devices.m3io import codec as m3io
from plants import can_bus, device, hdlock_can, plant_text
from tests.conftest import free_port, listening, wait_for

pytestmark = pytest.mark.timeout(60)
SW1 = 0x1A
DIG_OUT = m3io.derive_ids(SW1).dig_out


@pytest.fixture
async def served(tmp_path):
    """An M3IO HM that this tool serves from the start (``master = "always"``: its DigOut, every output off, every
    500 ms) on a virtual bus without twins, and a python-can listener there."""
    channel = f"served-{free_port()}-{time.monotonic_ns()}"
    text = plant_text(can_bus(device("heater", "m3io", "can1", variant="HM", sw1=SW1, master="always"),
                              hdlock_can("lock", 335, extended=True),
                              channel_name=channel, bitrate=500000, poll_period=0.5, simulate=None), name=None)
    async with listening(text, channel, tmp_path) as rig:
        yield rig


def _keepalive_running(runtime) -> bool:
    stats = runtime.store.buses["can1"].ids.get((False, DIG_OUT))
    return stats is not None and stats.direction == "tx" and bool(stats.cycles())


async def test_a_digout_the_tools_own_keepalive_overrides_says_so_before_and_after(served):
    runtime, _listener = served
    await wait_for(lambda: _keepalive_running(runtime), timeout=10)
    tl = transmit_list(runtime.worker, "can1", runtime.data_dir)
    await tl.load()
    row = await tl.add(named_row("m3io", "heater", {"variant": "HM", "sw1": SW1}, "DigOut", {"SSR1": True}),
                       user="anna", role="engineer")
    with pytest.raises(NeedsConfirmation) as asked:
        await tl.send_once(row.key, user="anna", role="engineer")
    question = str(asked.value)
    assert "mains voltage" in question  # the policy's own question stays
    assert "heater is served by this tool" in question and "every 500 ms" in question, question
    assert "sets heater back to what its page shows" in question, question
    note = await tl.send_once(row.key, user="anna", role="engineer", confirmed=True)
    assert "heater is served by this tool" in note and "M3IO DigOut: all off" in note, note
    assert tl.sent[row.key] == 1


async def test_a_frame_nothing_of_this_tool_sends_cyclically_says_nothing_more(served):
    runtime, _listener = served
    tl = transmit_list(runtime.worker, "can1", runtime.data_dir)
    await tl.load()
    row = await tl.add(make_row(0x321, False, b"\x01"), user="anna", role="engineer")
    assert await tl.send_once(row.key, user="anna", role="engineer") == ""
