"""What a device page reads by itself on opening is declared by the device type (issue 44): the Electrak declares
its service parameters' read; it runs through the gate (a viewer's page too: a read) when the network answers and none was ever read, once per
device per 30 s however many pages open, and never for a type that declares nothing."""

from __future__ import annotations

import pytest
from plants import electrak_bus, plant
from webutil import eventually

from app.runtime import Runtime
from devices.registry import DEVICE_TYPES, OpenRead

pytestmark = pytest.mark.timeout(60)


def test_the_electrak_declares_its_read_and_the_others_none():
    assert DEVICE_TYPES["electrak"].open_reads == (OpenRead("read service parameters", 30.0),)
    assert all(not DEVICE_TYPES[name].open_reads for name in ("hdlock", "m3io", "mo64", "scu"))


async def test_read_once_per_device_per_window_through_the_gate(tmp_path):
    now = [1000.0]
    runtime = Runtime(plant(electrak_bus()), simulate=True, data_dir=tmp_path)
    runtime.open_reads.clock = lambda: now[0]
    await runtime.start()
    try:
        state = runtime.store.devices["lift"]
        await eventually(lambda: state.status == "online", 15, what="the network online")
        assert runtime.open_reads.never_read("lift")
        assert await runtime.open_reads.run("lift", user="tablet", role="viewer") == ["read service parameters"]
        await eventually(lambda: not runtime.open_reads.never_read("lift"), 10, what="the service parameters read")
        rows = [r for r in await runtime.audit.aquery(device="lift") if r.action == "read service parameters"]
        assert rows == []  # through the gate as any read: a read is not audited
        for param in state.params:  # as if never read: a second page within 30 s reads nothing
            for address in param.addresses:
                state.registers.pop((param.space, address), None)
        assert runtime.open_reads.never_read("lift")
        now[0] += 29.0
        assert await runtime.open_reads.run("lift", user="anna", role="engineer") == []
        now[0] += 1.0
        assert runtime.open_reads.due("lift") == [OpenRead("read service parameters")]
    finally:
        await runtime.stop()
