"""The worker's command gate (issues 26 and 33): the role at the moment of the action, stops first and
audited afterwards, kinds from the declarations, and a viewer whose every non-stop action changes nothing."""

from __future__ import annotations

import asyncio
import itertools
import time
from pathlib import Path

import can
import pytest

from app import replay as rp
from app import transmit as tx
from app.can_bus import FrameRecord
from app.modbus_poll import ModbusPoll
from app.plant import load_plant, parse_plant
from app.runtime import Runtime
from app.worker import PermissionDenied, Worker
from devices.commands import KINDS, commands_of
from devices.registry import DEVICE_TYPES
from plants import channel, heater_and_lock
from tests.conftest import wait_for

DEMO = Path(__file__).resolve().parents[2] / "plants" / "demo.toml"
_n = itertools.count()


class SlowAudit:
    """An audit log that holds every row until released (a database locked by another program)."""

    path = "locked.sqlite"

    def __init__(self):
        self.rows: list[dict] = []
        self.release = asyncio.Event()

    async def arecord(self, **row):
        await self.release.wait()
        self.rows.append(dict(row))
        return len(self.rows) - 1

    async def afinish(self, row, result):
        self.rows[row]["result"] = result


def _can_plant():
    """:func:`plants.heater_and_lock` on a channel of its own: an HD-Lock "lock" and an M3IO "heater", no twins."""
    return parse_plant(heater_and_lock(channel("gate")))


# -- 33.2: a stop goes to the bus first, audited afterwards ------------------------------------------------


async def test_stop_runs_before_its_audit_row_and_never_waits_for_it():
    worker = Worker(_can_plant(), audit=SlowAudit())
    ran: list[float] = []

    async def stop() -> str:
        ran.append(time.monotonic())
        return "stopped"

    # the audit holds every row: the stop must not wait for it
    result = await asyncio.wait_for(worker.gate.run(stop, device="lock", role="viewer", user="tablet",
                                    describe="stop", kind="stop"), timeout=1.0)
    assert result == "stopped" and ran and worker.audit.rows == []
    worker.audit.release.set()
    assert await wait_for(lambda: worker.audit.rows, timeout=2)
    assert worker.audit.rows[0]["action"] == "stop" and worker.audit.rows[0]["result"].startswith("ok")


async def test_an_action_by_its_wording_gets_the_declared_kind_or_counts_as_a_write():
    """An action submitted as a callable and its wording gets the kind its type declares for that name;
    a wording the type does not declare is checked as a write, never let through as a read."""
    worker = Worker(_can_plant(), audit=SlowAudit())
    assert worker.gate.kind_for("lock", "Save-Settings") == "system"
    assert worker.gate.kind_for("lock", "read something") == "write"  # not declared: checked as a write


# -- 33.1: the role is the account store's at the moment of the action --------------------------------------


@pytest.fixture
def accounts(can_rig):
    """conftest's ``can_rig`` with accounts: the engineer anna, each action checked against the account store."""
    runtime, listener = can_rig
    runtime.auth_required = True  # read at each action (Runtime.role_of), as it is when the GUI listens beyond loopback
    runtime.users.add("anna", "engineer", "correct horse")
    return runtime, listener


def _drain(listener) -> list[can.Message]:
    got = []
    while (msg := listener.recv(0)) is not None:
        got.append(msg)
    return got


async def test_downgraded_or_removed_account_loses_its_rights_on_an_open_page(accounts):
    runtime, listener = accounts
    tl = tx.transmit_list(runtime.worker, "can1", runtime.data_dir)
    await tl.load()
    # the page was built while anna was an engineer: it still says so when it calls
    row = await tl.add(tx.make_row(0x123, False, b"\x01"), user="anna", role="engineer")
    await tl.send_once(row.key, user="anna", role="engineer")
    assert await wait_for(lambda: any(m.arbitration_id == 0x123 for m in _drain(listener)), timeout=2)
    runtime.users.add("anna", "viewer", "correct horse")  # `commission user add anna --role viewer`
    with pytest.raises(PermissionDenied):
        await tl.send_once(row.key, user="anna", role="engineer")
    runtime.users.remove("anna")  # `commission user remove anna`
    with pytest.raises(PermissionDenied):
        await tl.send_once(row.key, user="anna", role="engineer")
    with pytest.raises(PermissionDenied):
        await runtime.worker.gate.run(lambda: asyncio.sleep(0), user="anna", role="engineer", describe="x", kind="write")
    assert await wait_for(lambda: False, timeout=0.1) is False
    assert not [m for m in _drain(listener) if m.arbitration_id == 0x123]


# -- 33.3, 26: every declared command and every send path with a viewer ------------------------------------------


class Spy:
    """Counts what reached a transport: CAN frames sent and Modbus tool requests (the real objects, wrapped)."""

    def __init__(self, worker: Worker):
        self.calls: list[str] = []
        for name, can_bus in worker.can_buses.items():
            real = can_bus.send
            can_bus.send = lambda *a, _r=real, _n=name, **k: (self.calls.append(f"{_n} send"), _r(*a, **k))[1]
        for name, line in worker.lines.items():
            real = getattr(line, "tool_request", None)
            if real is not None:
                async def request(*a, _r=real, _n=name, **k):
                    self.calls.append(f"{_n} tool request")
                    return await _r(*a, **k)

                line.tool_request = request


async def test_a_viewer_reaches_no_bus_through_any_declared_command_or_send_path(tmp_path):
    plant = load_plant(DEMO)
    runtime = Runtime(plant, simulate=False, data_dir=tmp_path)
    worker = runtime.worker
    spy = Spy(worker)
    ran: list[str] = []
    walked = 0
    for dev in plant.devices.values():
        adapter = worker.adapters[dev.name]
        for command in commands_of(dev.type, plant.buses[dev.bus].type).values():  # what its bus kind serves (the rest:
            assert command.kind in KINDS  # not a command of it, test_a_command_the_bus_kind_cannot_serve...)
            if command.open:
                continue
            if (function := command.function_for(type(adapter))) is not None:
                setattr(adapter, function.__name__, lambda *a, _c=command.name, **k: ran.append(_c))
            args = {a.name: getattr(a, "low", 0) for a in command.args}
            with pytest.raises(PermissionDenied):
                await worker.gate.invoke(dev.name, command.name, args, user="tablet", role="viewer", session="v")
            # the older way (an adapter callable with the command's wording): the declaration decides the kind
            with pytest.raises(PermissionDenied):
                await worker.gate.run(lambda _c=command.name: ran.append(_c), device=dev.name, describe=command.name,
                                      user="tablet", role="viewer")
            walked += 1
    assert walked >= 10 and ran == []
    assert {t for t in DEVICE_TYPES if commands_of(t)} >= {"hdlock", "mo64", "electrak", "m3io", "scu"}
    # the raw send paths
    for bus in worker.can_buses:
        tl = tx.transmit_list(worker, bus, None)
        row = tx.make_row(0x123, False, b"\x01", 100)
        tl.rows.append(row)
        with pytest.raises(PermissionDenied):
            await tl.send_once(row.key, user="tablet", role="viewer", confirmed=True)
        with pytest.raises(PermissionDenied):
            await tl.start(row.key, user="tablet", role="viewer", session="v", confirmed=True)
        with pytest.raises(PermissionDenied):
            await rp.start_replay(worker, bus, [FrameRecord(1.0, 0x123, False, 1, b"\x01", "rx")], user="tablet",
                                  role="viewer", session="v")
    for bus in [b for b, line in worker.lines.items() if type(line).__name__ == "ModbusLine"]:
        with pytest.raises(PermissionDenied):
            await ModbusPoll(worker, bus).write(1, 3000, [200], user="tablet", role="viewer", confirmed=True)
    assert spy.calls == []
    await asyncio.sleep(0)


async def test_a_command_the_bus_kind_cannot_serve_is_refused_before_any_started_row():
    """The HD-Lock's CAN-only commands are no commands of a lock on Modbus (and the reverse): refused as not
    declared, with a refusal row and no "started" row, before anything reaches an adapter."""
    from devices.commands import CommandError
    from plants import modbus_plant

    audit = SlowAudit()
    audit.release.set()
    worker = Worker(modbus_plant(locks=(("door-1", 1),)), audit=audit)
    can_only = set(commands_of("hdlock", "can")) - set(commands_of("hdlock", "modbus-rtu"))
    assert can_only, "the HD-Lock declares commands for CAN only"
    for name in sorted(can_only):
        with pytest.raises(CommandError, match="is not a command of door-1"):
            worker.gate.question("door-1", name, {})
        with pytest.raises(CommandError, match="is not a command of door-1"):
            await worker.gate.invoke("door-1", name, {}, user="anna", role="engineer")
    assert [(row["action"], row["result"]) for row in audit.rows] == [
        (name, f"refused: {name!r} is not a command of door-1") for name in sorted(can_only)]
    assert worker.gate.question("door-1", "Save-Settings", {}) is not None  # a command both adapters serve
    lock = Worker(_can_plant(), audit=SlowAudit())
    assert lock.gate.declared("lock", sorted(can_only)[0], served=True) is not None
