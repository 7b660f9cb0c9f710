"""HD-Lock conversation on a Modbus RTU line: polling, writes with read-back, system commands."""

from __future__ import annotations

import asyncio

from app.modbus_line import LineError, ModbusLine
from app.state import DeviceState
from devices.hdlock import codec
from devices.hdlock.params import HOLDING, INPUT, PARAMS
from devices.params import Param, ParamError

CHART_SERIES = {  # chart label -> parameter name
    "BoltPosition [Inc]": "BoltPosition",
    "MotorCurrent [mA]": "MotorCurrent",
    "Proximity [Inc]": "Calculated proxi (normalized)",
}


class CommandError(Exception):
    """A command or write that did not take effect; the message says what to do."""


class HdLockAdapter:
    """One lock at one Modbus address on a :class:`ModbusLine`."""

    params = PARAMS

    def __init__(self, config, state: DeviceState, line: ModbusLine):
        self.config = config
        self.state = state
        self.line = line
        self.address: int = config.options["address"]
        self.blocks = {space: PARAMS.blocks(space) for space in (INPUT, HOLDING)}
        self.state.params = PARAMS
        self.state.info["address"] = self.address
        self._fails = 0

    # -- polling ------------------------------------------------------------------------
    async def poll(self) -> None:
        """Read every register block once; one failed block marks the cycle failed."""
        try:
            for space in (INPUT, HOLDING):
                for start, count in self.blocks[space]:
                    if space == INPUT:
                        values = await self.line.read_input(self.address, start, count, self.state.counters)
                    else:
                        values = await self.line.read_holding(self.address, start, count, self.state.counters)
                    self.state.update_registers(space, start, values)
        except LineError as exc:
            self._fails += 1
            if self._fails >= 2 or self.state.online is None:
                self.state.mark_offline(f"{exc}")
            else:
                self.state.error(str(exc))
            return
        if self._fails:
            self.state.event("info", f"answering again at address {self.address}")
        self._fails = 0
        self.state.add_history({label: self.state.value(name) for label, name in CHART_SERIES.items()})

    # -- writes -------------------------------------------------------------------------
    async def write_param(self, param: Param, value, *, confirmed: bool = False) -> int:
        """Validate, write with FC 0x06 and read back; returns the new raw value."""
        if param not in PARAMS.params:
            raise CommandError(f"{param.name} is not an HD-Lock parameter")
        try:
            raw = param.validate(value)
        except ParamError as exc:
            raise CommandError(str(exc)) from None
        warning = param.needs_confirmation(raw)
        if warning and not confirmed:
            raise CommandError(f"needs confirmation: {warning}")
        try:
            await self.line.write_register(self.address, param.address, raw, self.state.counters)
            back = (await self.line.read_holding(self.address, param.address, 1, self.state.counters))[0]
        except LineError as exc:
            self.state.counters.write_errors += 1
            raise CommandError(f"writing {param.name} failed: {exc}") from None
        self.state.update_registers(HOLDING, param.address, [back])
        if back != raw:
            self.state.counters.write_errors += 1
            raise CommandError(
                f"{param.name}: the lock kept {param.display(back)} instead of {param.display(raw)} "
                "(refused by the firmware: protected register or value not accepted)"
            )
        if param.address != codec.REG_COMMAND:
            self.state.unsaved.add(param.key)
        self.state.event("info", f"{param.label or param.name} = {param.display(raw)} written and read back")
        return raw

    async def _command(self, command: codec.SystemCommand, p0: int = 0, p1: int = 0, p2: int = 0) -> None:
        try:
            writes = codec.encode_system_command(command, p0, p1, p2)
        except codec.CodecError as exc:
            raise CommandError(str(exc)) from None
        try:
            for register, value in writes.writes:
                await self.line.write_register(self.address, register, value, self.state.counters)
        except LineError as exc:
            self.state.counters.write_errors += 1
            raise CommandError(f"{command.name.replace('_', '-').title()} failed: {exc}") from None

    async def save_settings(self) -> None:
        """Command 1 (section 4.1): holding registers to non-volatile memory."""
        before = await self._read_one(INPUT, 101)
        await self._command(codec.SystemCommand.SAVE_SETTINGS)
        after = await self._read_one(INPUT, 101)
        if after == before:
            raise CommandError("Save-Settings sent, but SavedSettings (input 101) did not count up: check the lock")
        self.state.unsaved.clear()
        self.state.event("info", f"settings saved (SavedSettings = {after})")

    async def restore_settings(self) -> None:
        """Command 2 (section 4.2): reload the saved settings, dropping unsaved changes."""
        await self._command(codec.SystemCommand.RESTORE_SETTINGS)
        self.state.unsaved.clear()
        await self.poll()
        self.state.event("info", "saved settings restored; unsaved changes discarded")

    def set_address_preview(self, mask: int, expected: int) -> tuple[bool, int, int | None]:
        """Would the lock take a new address now? (accepted, result, LockStatus used)."""
        status = self.state.value("LockStatus")
        if status is None:
            return False, -1, None
        result = codec.set_address_condition(mask, expected, int(status))
        return result == 0, result, int(status)

    async def set_address(self, new_address: int, mask: int, expected: int) -> bool:
        """Command 3 (section 4.3). Returns True when the lock answers at the new address."""
        if not codec.MODBUS_ADDRESS_MIN <= new_address <= codec.MODBUS_ADDRESS_MAX:
            raise CommandError(f"new address {new_address} is outside 1..254")
        old = self.address
        await self._command(codec.SystemCommand.SET_MODBUS_ADDRESS, new_address, mask, expected)
        await asyncio.sleep(0.05)
        try:
            now = (await self.line.read_holding(new_address, 103, 1, self.state.counters))[0]
        except LineError:
            now = None
        if now == new_address and new_address != old:
            self.address = new_address
            self.state.info["address"] = new_address
            self.state.unsaved.add(PARAMS.get(HOLDING, 103).key)
            self.state.event(
                "warning",
                f"address changed {old} -> {new_address}: send Save-Settings to keep it and change "
                f"address = {new_address} in the plant file",
            )
            return True
        self.state.event("warning", f"address change to {new_address} refused: condition not met")
        return False

    async def _read_one(self, space: str, address: int) -> int:
        try:
            if space == INPUT:
                value = (await self.line.read_input(self.address, address, 1, self.state.counters))[0]
            else:
                value = (await self.line.read_holding(self.address, address, 1, self.state.counters))[0]
        except LineError as exc:
            raise CommandError(f"reading {space} {address} failed: {exc}") from None
        self.state.update_registers(space, address, [value])
        return value


async def discover(line: ModbusLine, first: int = 1, last: int = 247, progress=None) -> list[dict]:
    """Find locks on a line.

    Broadcast first (address 0: a single lock answers with its DeviceAddress, section 5.6),
    then a scan of ``first..last`` reading DeviceAddress (holding 103) and the serial
    number (input 104/105). ``progress(done, total)`` is called after each address.
    """
    found: dict[int, dict] = {}
    try:
        address = (await line.read_holding(codec.MODBUS_BROADCAST, 103, 1))[0]
        found[address] = {"address": address, "via": "broadcast"}
    except LineError:
        pass
    total = last - first + 1
    for n, unit in enumerate(range(first, last + 1), 1):
        try:
            reg = (await line.transact(
                unit, "scan holding 103", None,
                lambda c, u=unit: c.read_holding_registers(103, count=1, device_id=u), retries=0,
            )).registers[0]
            serial = await line.read_input(unit, 104, 2)
            found[unit] = {"address": reg, "serial": codec.serial_number(*serial), "via": "scan"}
        except LineError:
            pass
        if progress:
            progress(n, total)
    return sorted(found.values(), key=lambda d: d["address"])
