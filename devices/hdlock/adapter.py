"""HD-Lock conversation on a Modbus RTU line: polling, writes with read-back, system commands."""

from __future__ import annotations

import asyncio
import time
import weakref
from collections.abc import Mapping
from dataclasses import dataclass, field

from devices.adapter import BackupDefaults
from devices import errors
from devices.hdlock import STATUS_FRAME_BOLT, codec
from devices.hdlock.params import HOLDING, INPUT, PARAMS
from devices.live import DeviceState
from devices.message import Message, N_, Word, message_of
from devices.params import Accepted, Param, ParamError, backup_entry
from devices.transport import LineCrcError, LineError, LineException, LineTimeout, ModbusTransport

# -- published facts (DeviceState.fact): every fact the page shows besides the registers ----------------
P_ADDRESS = "Modbus address"  # the address this tool talks to (a number; changes with Set Modbus Address)
P_LINE_LOCKS = "Locks found on the line"  # FoundLock records of the scans of this lock's Modbus line
P_DEVICE_ID = "CAN device ID"  # the device ID it answers under (value; text with std/ext and hex)
P_STATUS_FRAME = "Status frame"  # the last periodic status (section 6.5.1), a codec.StatusFrame record
P_FWU = "FWU status"  # firmware-update status (section 6.5.2): a codec.FwuStatusFrame record, or None
P_PROXIMITY_FRAME = "Proximity (status frame)"
P_SOURCE_FRAME = "LockRequestSource (status frame, low 6 bits)"

# the chart's quantities, sampled by their own names (register parameters and points alike)
HISTORY_MODBUS = ("BoltPosition", "MotorCurrent", "Calculated proxi (normalized)")
HISTORY_CAN = (STATUS_FRAME_BOLT, "MotorCurrent", P_PROXIMITY_FRAME)
HISTORY_MIN_GAP_S = 0.1  # status frames faster than this (a lock in firmware test mode, a replayed recording) are charted at 10/s

# Settings (RW and MFR holding registers) change only when written: they are read every SETTINGS_PERIOD_S,
# on the first poll, after a failed poll, a write, a restore or a backup, and in the same poll as an
# identity that changed. The live status and the identity (input registers, RO holding registers: the
# serial number that replacement detection compares among them) are read every poll.
SETTINGS_PERIOD_S = 10.0
NEW_ID_LISTEN_S = 1.3  # Set Device Address listens this long under the new ID first: a lock sends its status every 1000 ms


def _is_status(param: Param) -> bool:
    return param.space == INPUT or param.access.value in ("R", "RO")


def poll_blocks() -> tuple[list[tuple[str, int, int]], list[tuple[str, int, int]]]:
    """The read blocks of every poll (status and identity) and those of the settings, as (space, start, count)."""
    every: list[tuple[str, int, int]] = []
    settings: list[tuple[str, int, int]] = []
    for space in (INPUT, HOLDING):
        for start, count in PARAMS.blocks(space):
            inside = [p for p in PARAMS.space(space) if start <= p.address < start + count]
            (every if any(_is_status(p) for p in inside) else settings).append((space, start, count))
    return every, settings


STATUS_BLOCKS, SETTINGS_BLOCKS = poll_blocks()
SERIAL_PARAM = PARAMS.by_name["SerialNumber"]  # a new value means another lock (its settings are read at once)

# On CAN every register read costs one answer frame (section 6.5.3/6.5.4), and the lock sends its status
# (holding 1000, 1001) by itself every 1000 ms (section 6.5.1): the poll leaves those two out. A lock can
# only answer under another lock's device ID after a silence (swapped, re-addressed: its status frames stop),
# so the identity (input 100-105) is read with the settings: at the first poll, every SETTINGS_PERIOD_S,
# after a failed poll and when status frames come again after a gap, and after a write, restore or backup.
IDENTITY_BLOCK = next(b for b in STATUS_BLOCKS if b[0] == INPUT and b[1] <= SERIAL_PARAM.address < b[1] + b[2])
CAN_FRAME_REGISTERS = ((HOLDING, 1000), (HOLDING, 1001))  # in every status frame


def can_poll_blocks() -> tuple[list[tuple[str, int, int]], list[tuple[str, int, int]]]:
    """The CAN poll's blocks: (every poll, with the settings), as (space, start, count)."""
    every = []
    for space, start, count in STATUS_BLOCKS:
        if (space, start, count) == IDENTITY_BLOCK:
            continue
        if (space, start) == CAN_FRAME_REGISTERS[0]:
            start, count = start + len(CAN_FRAME_REGISTERS), count - len(CAN_FRAME_REGISTERS)
        if count > 0:
            every.append((space, start, count))
    # the settings' read takes holding 1000-1001 along (2 frames): a backup or a lock heard again after a gap has
    # them from the same read, not only from the next status frame
    return every, [IDENTITY_BLOCK, (HOLDING, CAN_FRAME_REGISTERS[0][1], len(CAN_FRAME_REGISTERS))] + SETTINGS_BLOCKS


CAN_STATUS_BLOCKS, CAN_SETTINGS_BLOCKS = can_poll_blocks()


@dataclass(frozen=True, slots=True)
class FoundLock:
    """A lock found by a scan of a Modbus line (discover()): its address, serial number and how it was found."""

    address: int
    serial: int | None = None
    via: str = "scan"


def chart_sample(state: DeviceState, names: tuple[str, ...]) -> dict:
    """One chart sample keyed by the quantities' own names (a point's value, else the parameter's)."""
    return {n: state.points[n].value if n in state.points else state.value(n) for n in names}


def status_frame_text(frame: codec.StatusFrame) -> Message:
    """The periodic status frame (section 6.5.1) in words, its fields by the document's names; the source's name
    (LockRequestSource, section 3.2.2) is worded by the page."""
    source = PARAMS.by_name["LockRequestSource"].enum.get(frame.lock_request_source, "?")
    return Message(N_("Status 0x{status:04X} · motorPos {motor_pos} Inc · proximity {proximity} Inc · LockRequestSource "
                      "0x{code:02X} {source}"), status=frame.status, motor_pos=frame.motor_pos, proximity=frame.proximity,
                   code=frame.lock_request_source, source=Word(source, "LockRequestSource"))


def fwu_text(frame: codec.FwuStatusFrame | None) -> str:
    """The FWU status (section 6.5.2) in words, a :class:`~devices.message.Message` ("" without a frame)."""
    if frame is None:
        return ""
    return Message(N_("FWU status: firmware-update mode, {flashing}, {program} (no status frames meanwhile)"),
                   flashing=Message(N_("flashing")) if frame.flashing else Message(N_("not flashing")),
                   program=Message(N_("application")) if frame.application else Message(N_("boot loader")))


class CommandError(errors.CommandError):
    """A command or write that did not take effect; the message says what to do."""


@dataclass
class AddressChange:
    """Outcome of Set Modbus Address (section 4.3), told from what answers afterwards."""

    new_address: int
    taken: bool  # one lock answers cleanly at the new address
    text: str  # a Message, worded by the page that shows it
    answered_old: bool | None = None  # the write of 2003 at the old address: answered, silent, or garbled (None)
    collision: bool = False  # a garbled answer at the new address: more than one lock took it
    serial: int | None = None  # serial number of the lock that answers at the new address
    moved: list[str] = field(default_factory=list)  # known locks no longer answering at their old address


# Locks found by scans of a Modbus line (discover()), by address; shown on every lock of that line.
_LINE_SCANS: weakref.WeakKeyDictionary[ModbusTransport, dict[int, dict]] = weakref.WeakKeyDictionary()
# The plant's locks on each Modbus line (their adapters), so a scan knows how many may answer a broadcast.
_LINE_LOCKS: weakref.WeakKeyDictionary[ModbusTransport, weakref.WeakSet] = weakref.WeakKeyDictionary()


def known_addresses(line: ModbusTransport) -> set[int]:
    """Addresses of the locks known on ``line``: the plant's and those found by earlier scans."""
    return {a.address for a in _LINE_LOCKS.get(line, ())} | set(_LINE_SCANS.get(line, {}))


def _own(param: Param) -> None:
    if param not in PARAMS.params:
        raise CommandError(f"{param.name} is not an HD-Lock parameter")


class HdLockBackup(BackupDefaults):
    """Write checks, backup/restore (see app/backup.py) and the worker's session hooks,
    shared by the Modbus and the CAN adapter."""

    def holders(self) -> set[str]:
        """Sessions that keep motion or mains outputs running here: none.

        Every HD-Lock command is a single write the lock keeps by itself; nothing is kept
        alive on behalf of a browser, so the dead-man rule has nothing to stop.
        """
        return set()

    def session_lost(self, session: str, reason: str) -> None:
        """Nothing runs on behalf of a session (see :meth:`holders`): nothing to stop."""

    async def write_param(self, param: Param, value, *, confirmed: bool = False) -> int:
        """An entry for ``param``, checked by the parameter model, written by the adapter's ``write_accepted``
        (what the declared write runs with the value the model accepted)."""
        _own(param)
        try:
            accepted = param.accept(value)
        except ParamError as exc:
            raise CommandError(str(exc)) from None
        return await self.write_accepted(accepted, confirmed=confirmed)

    @staticmethod
    def _cleared(accepted: Accepted, confirmed: bool) -> int:
        """The raw value to write: refused when the value needs a confirmation nobody gave."""
        _own(accepted.param)
        try:
            return accepted.cleared(confirmed)
        except ParamError as exc:
            raise CommandError(str(exc)) from None

    _settings_due = 0.0  # monotonic time the settings are read next (0: at the next poll)
    status_blocks = STATUS_BLOCKS  # read every poll
    settings_blocks = SETTINGS_BLOCKS  # read every SETTINGS_PERIOD_S and when something suggests a change

    def _setup_periods(self) -> None:
        for space, start, count in self.settings_blocks:
            for address in range(start, start + count):
                if (space, address) not in CAN_FRAME_REGISTERS:  # those come with every status frame
                    self.state.register_every[(space, address)] = SETTINGS_PERIOD_S

    def read_settings_next(self) -> None:
        """Read the settings with the next poll (after a write, a restore, a replacement)."""
        self._settings_due = 0.0

    def _blocks_now(self) -> tuple[list[tuple[str, int, int]], bool]:
        """The blocks this poll reads, and whether the settings are among them."""
        if time.monotonic() >= self._settings_due:
            return self.status_blocks + self.settings_blocks, True
        return self.status_blocks, False

    def _settings_read(self) -> None:
        self._settings_due = time.monotonic() + SETTINGS_PERIOD_S

    def _serial_word(self) -> int | None:
        return self.state.raw(SERIAL_PARAM)

    async def backup_read(self, progress=None) -> list[dict]:
        started = time.time()
        self.read_settings_next()
        await self.poll()
        missing = [p.label or p.name for p in PARAMS if (self.state.read_time(p) or 0) < started]
        if missing:
            raise CommandError(Message(N_("could not read {n} parameters (first: {first}): {error}"), n=len(missing),
                                       first=missing[0], error=self.state.last_error))
        if progress:
            progress(1.0)
        return [backup_entry(p, self.state.raw(p)) for p in PARAMS]

    def backup_identity(self) -> dict:
        values = self.state.values()
        identity = {key: values[key]["value"] for key in ("SerialNumber", "FirmwareVersion", "HardwareVersion") if key in values}
        if "SerialNumber" in identity:
            identity["serial"] = identity.pop("SerialNumber")
        return identity

    async def save_step(self) -> str:
        await self.save_settings()
        return "Save-Settings"


class HdLockAdapter(HdLockBackup):
    """One lock at one Modbus address on a :class:`ModbusTransport`."""

    params = PARAMS

    def __init__(self, config, state: DeviceState, line: ModbusTransport):
        self.config = config
        self.state = state
        self.line = line
        self.address: int = config.options["address"]
        self.blocks = {space: PARAMS.blocks(space) for space in (INPUT, HOLDING)}
        self.state.params = PARAMS
        self.state.fact(P_ADDRESS, self.address)
        self.state.fact(P_LINE_LOCKS, ())  # none found by a scan of the line yet
        self._fails = 0
        self._changing_address = False  # polling waits while the address is being changed
        self._setup_periods()
        _LINE_LOCKS.setdefault(line, weakref.WeakSet()).add(self)

    # -- polling ------------------------------------------------------------------------
    async def poll(self) -> None:
        """Read the status and identity blocks (and the settings when due, see SETTINGS_PERIOD_S);
        one failed block marks the cycle failed."""
        scans = _LINE_SCANS.get(self.line)
        if scans is not None:
            self.state.fact(P_LINE_LOCKS, tuple(FoundLock(e["address"], e.get("serial"), e.get("via", "scan"))
                                                for _address, e in sorted(scans.items())))
        blocks, with_settings = self._blocks_now()
        serial = self._serial_word()
        try:
            if not await self._read_blocks(blocks):
                return
            if not with_settings and serial is not None and self._serial_word() != serial:
                with_settings = True  # another lock answers here: its settings now, not in 10 s
                if not await self._read_blocks(SETTINGS_BLOCKS):
                    return
            if with_settings:
                self._settings_read()
        except LineError as exc:
            self.read_settings_next()
            self._fails += 1
            if self._fails >= 2 or self.state.online is None:  # the line's diagnosis (a Message the pages word)
                self.state.mark_offline(message_of(exc))
            else:
                self.state.error(message_of(exc))
            return
        if self._fails:
            self.state.event("info", Message(N_("answering again at address {address}"), address=self.address))
        self._fails = 0
        self.state.add_history(chart_sample(self.state, HISTORY_MODBUS))

    async def _read_blocks(self, blocks: list[tuple[str, int, int]]) -> bool:
        """Read ``blocks`` in turn; False when an address change began meanwhile (the poll stops)."""
        for space, start, count in blocks:
            if self._changing_address:
                return False
            if space == INPUT:
                values = await self.line.read_input(self.address, start, count, self.state.counters)
            else:
                values = await self.line.read_holding(self.address, start, count, self.state.counters)
            self.state.update_registers(space, start, values)
        return True

    # -- writes -------------------------------------------------------------------------
    async def write_accepted(self, accepted: Accepted, *, confirmed: bool = False) -> int:
        """Write with FC 0x06 and read back; returns the new raw value."""
        param, raw = accepted.param, self._cleared(accepted, confirmed)
        try:
            await self.line.write_register(self.address, param.address, raw, self.state.counters)
            back = (await self.line.read_holding(self.address, param.address, 1, self.state.counters))[0]
        except LineError as exc:
            self.state.counters.write_errors += 1
            raise CommandError(Message(N_("writing {name} failed: {error}"), name=param.name, error=message_of(exc))) from None
        self.state.update_registers(HOLDING, param.address, [back])
        if back != raw:
            self.state.counters.write_errors += 1
            raise CommandError(
                f"{param.name}: the lock kept {param.display(back)} instead of {param.display(raw)} "
                "(refused by the firmware: protected register or value not accepted)"
            )
        if param.address != codec.REG_COMMAND:
            self.state.unsaved.add(param.key)
        self.read_settings_next()  # a write may move other settings (a command register, a derived value)
        self.state.event("info", Message(N_("{name} = {value} written and read back"), name=param.label or param.name,
                                         value=param.display(raw)))
        return raw

    async def _command(self, command: codec.SystemCommand, p0: int = 0, p1: int = 0, p2: int = 0) -> None:
        try:
            writes = codec.encode_system_command(command, p0, p1, p2)
        except codec.CodecError as exc:
            raise CommandError(str(exc)) from None
        try:
            for register, value in writes.writes:
                await self.line.write_register(self.address, register, value, self.state.counters)
            self.read_settings_next()
        except LineError as exc:
            self.state.counters.write_errors += 1
            raise CommandError(Message(N_("{command} failed: {error}"), command=command.name.replace("_", "-").title(),
                                       error=message_of(exc))) from None

    async def save_settings(self) -> None:
        """Command 1 (section 4.1): holding registers to non-volatile memory."""
        before = await self._read_one(INPUT, 101)
        await self._command(codec.SystemCommand.SAVE_SETTINGS)
        after = await self._read_one(INPUT, 101)
        if after == before:
            raise CommandError("Save-Settings sent, but SavedSettings (input 101) did not count up: check the lock")
        self.state.unsaved.clear()
        self.state.event("info", Message(N_("settings saved (SavedSettings = {count})"), count=after))

    async def restore_settings(self) -> None:
        """Command 2 (section 4.2): reload the saved settings, dropping unsaved changes."""
        await self._command(codec.SystemCommand.RESTORE_SETTINGS)
        self.state.unsaved.clear()
        self.read_settings_next()
        await self.poll()
        self.state.event("info", Message(N_("saved settings restored; unsaved changes discarded")))

    def set_address_preview(self, mask: int, expected: int) -> tuple[bool, int, int | None]:
        """Would the lock take a new address now? (accepted, result, LockStatus used)."""
        status = self.state.value("LockStatus")
        if status is None:
            return False, -1, None
        result = codec.set_address_condition(mask, expected, int(status))
        return result == 0, result, int(status)

    async def set_address(self, new_address: int, mask: int, expected: int) -> AddressChange:
        """Command 3 (section 4.3) at this lock's address; the outcome is read at the new address.

        The write of 2003 may go unanswered at the old address (the document does not say
        that the lock answers it); the lock is then looked for at the new address, and
        when it is not there, at the old one.
        """
        _check_address(new_address)
        old = self.address
        if new_address == old:
            raise CommandError(f"the lock has address {old} already")
        writes = await self._set_address_writes(new_address, mask, expected)
        self._changing_address = True
        try:
            try:
                for register, value in writes[:-1]:
                    await self.line.write_register(old, register, value, self.state.counters)
            except LineError as exc:
                self.state.counters.write_errors += 1
                raise CommandError(Message(N_("Set Modbus Address: writing the parameters failed: {error}"),
                                           error=message_of(exc))) from None
            answered = await self._write_command(old, *writes[-1])
            await asyncio.sleep(codec.ADDRESS_SETTLE_S)
            found = await self._probe(new_address)
            serial = self.state.value("SerialNumber")
            how = _command_answer_text(answered, old)
            if isinstance(found, int) and serial is not None and found != serial:
                raise CommandError(f"a lock with serial {found} answers at address {new_address}, not this one ({serial}); {how}")
            if found == "garbled":
                raise CommandError(f"garbled answer at address {new_address}: two locks may answer there now; {how}")
            if found is not None:
                self._moved_to(old, new_address)
                text = Message(N_("the lock answers at address {new} now ({how}): send Save-Settings to keep it and "
                                  "change address = {new} in the plant file"), new=new_address, how=how)
                self.state.event("warning", Message(N_("address changed {old} -> {new}: {text}"), old=old, new=new_address,
                                                    text=text))
                return AddressChange(new_address, True, text, answered_old=answered, serial=serial)
            if await self._probe(old) is not None:
                text = Message(N_("no answer at address {new}; the lock still answers at address {old} ({how}): the "
                                  "condition did not hold"), new=new_address, old=old, how=how)
                self.state.event("warning", Message(N_("address change to {new} refused: {text}"), new=new_address, text=text))
                return AddressChange(new_address, False, text, answered_old=answered)
            raise CommandError(
                f"no answer at the new address {new_address} nor at the old address {old} ({how}): "
                "the outcome is unknown; check the lock's power and cabling, then run Discover on the line"
            )
        finally:
            self._changing_address = False

    async def broadcast_set_address(self, new_address: int, mask: int, expected: int,
                                    known: Mapping[int, str] | None = None) -> AddressChange:
        """Set Modbus Address to broadcast address 255 (section 4.3): every lock on the line
        whose LockStatus meets the condition takes ``new_address``; none answers.

        :param known: address -> name of the locks known on this line (plant file and scans);
            each is looked for at its old address afterwards, to tell which ones moved.
        """
        _check_address(new_address)
        known = dict(known or {})
        if new_address in known:
            raise CommandError(f"address {new_address} is {known[new_address]}: choose an address no lock uses")
        writes = await self._set_address_writes(new_address, mask, expected)
        unit = codec.MODBUS_BROADCAST_SET_ADDRESS

        async def send_quietly(client, register: int, value: int) -> None:
            await client.write_register(register, value, device_id=unit, no_response_expected=True)
            await asyncio.sleep(codec.BROADCAST_TURNAROUND_S)  # still holding the line: nobody talks meanwhile

        self._changing_address = True
        try:
            try:
                for register, value in writes:
                    await self.line.transact(
                        unit, Message(N_("broadcast write holding {address}={value}"), address=register, value=value),
                        self.state.counters,
                        lambda c, r=register, v=value: send_quietly(c, r, v), retries=0,
                    )
            except LineError as exc:
                self.state.counters.write_errors += 1
                raise CommandError(Message(N_("broadcast Set Modbus Address failed: {error}"), error=message_of(exc))) from None
            await asyncio.sleep(max(0.0, codec.ADDRESS_SETTLE_S - codec.BROADCAST_TURNAROUND_S))
            found = await self._probe(new_address)
            moved = [name for address, name in sorted(known.items()) if await self._probe(address) is None]
            serial = self.state.value("SerialNumber")
            if isinstance(found, int) and serial is not None and found == serial:
                self._moved_to(self.address, new_address)
        finally:
            self._changing_address = False
        gone = Message(N_("; no longer answering at their old address: {names}"), names=", ".join(moved)) if moved else ""
        if found == "garbled":
            text = Message(N_("garbled answers at address {new}: more than one lock took it and they now answer together"
                              "{gone}. Give each its own address again (Set Modbus Address at {new} with a condition only "
                              "one of them meets), then change the plant file"), new=new_address, gone=gone)
            result = AddressChange(new_address, False, text, collision=True, moved=moved)
        elif found is None:
            text = Message(N_("no lock answers at address {new}: no lock met the condition{gone}"), new=new_address, gone=gone)
            result = AddressChange(new_address, False, text, moved=moved)
        else:
            text = Message(N_("lock serial {serial} answers at address {new}{gone}. Send Save-Settings to it at {new} to keep "
                              "the address, and change the plant file"), serial=found, new=new_address, gone=gone)
            result = AddressChange(new_address, True, text, serial=found, moved=moved)
        scans = _LINE_SCANS.setdefault(self.line, {})
        for address, name in known.items():
            if name in moved:
                scans.pop(address, None)
        if result.taken:
            scans[new_address] = {"address": new_address, "serial": found, "via": "broadcast address change"}
        self.state.event("warning", Message(N_("broadcast Set Modbus Address {new} (P1 {mask}, P2 {expected}): {text}"),
                                            new=new_address, mask=f"0x{mask:04X}", expected=f"0x{expected:04X}", text=text))
        return result

    # -- address change helpers ------------------------------------------------------------
    async def _write_command(self, unit: int, register: int, value: int) -> bool | None:
        """The write of 2003: True answered, False silent (expected, see codec), None garbled."""
        self.state.counters.requests += 1
        try:
            await self.line.write_register(unit, register, value)
        except LineTimeout:
            if codec.ADDRESS_COMMAND_ANSWERED:
                self.state.counters.timeouts += 1
            return False
        except LineCrcError:
            return None
        except LineException as exc:
            self.state.counters.write_errors += 1
            raise CommandError(Message(N_("the lock refused Set Modbus Address: {error}"), error=message_of(exc))) from None
        except LineError as exc:
            self.state.counters.write_errors += 1
            raise CommandError(Message(N_("Set Modbus Address failed: {error}"), error=message_of(exc))) from None
        self.state.counters.responses += 1
        return True

    async def _probe(self, unit: int) -> int | str | None:
        """Who answers at ``unit``: its serial number, "garbled" (several at once), or None."""
        try:
            await self.line.read_holding(unit, codec.REG_DEVICE_ADDRESS, 1)
            high, low = await self.line.read_input(unit, 104, 2)
        except LineCrcError:
            return "garbled"
        except LineError:
            return None
        return codec.serial_number(high, low)

    async def _set_address_writes(self, new_address: int, mask: int, expected: int) -> tuple[tuple[int, int], ...]:
        """The register writes of Set Modbus Address (section 4.3), once no lock answers at ``new_address``; a value
        the codec refuses is a :class:`CommandError`."""
        await self._address_free(new_address)
        try:
            return codec.encode_system_command(codec.SystemCommand.SET_MODBUS_ADDRESS, new_address, mask, expected).writes
        except codec.CodecError as exc:
            raise CommandError(str(exc)) from None

    async def _address_free(self, address: int) -> None:
        """Section 2.2: every lock needs an address of its own."""
        found = await self._probe(address)
        if found is not None:
            who = "several locks" if found == "garbled" else f"the lock with serial {found}"
            raise CommandError(f"address {address} is already in use ({who} answers there): choose a free address")

    def _moved_to(self, old: int, new: int) -> None:
        self.address = new
        self.state.fact(P_ADDRESS, new)
        self.state.update_registers(HOLDING, codec.REG_DEVICE_ADDRESS, [new])
        self.state.unsaved.add(PARAMS.get(HOLDING, codec.REG_DEVICE_ADDRESS).key)
        self._fails = 0

    async def _read_one(self, space: str, address: int) -> int:
        try:
            if space == INPUT:
                value = (await self.line.read_input(self.address, address, 1, self.state.counters))[0]
            else:
                value = (await self.line.read_holding(self.address, address, 1, self.state.counters))[0]
        except LineError as exc:
            words = N_("reading input {address} failed: {error}") if space == INPUT else N_("reading holding {address} failed: {error}")
            raise CommandError(Message(words, address=address, error=message_of(exc))) from None
        self.state.update_registers(space, address, [value])
        return value


def _check_address(address: int) -> None:
    if not codec.MODBUS_ADDRESS_MIN <= address <= codec.MODBUS_ADDRESS_MAX:
        raise CommandError(f"new address {address} is outside {codec.MODBUS_ADDRESS_MIN}..{codec.MODBUS_ADDRESS_MAX}")


def _command_answer_text(answered: bool | None, old: int) -> Message:
    if answered is None:
        return Message(N_("the write of the command at address {old} got a garbled answer"), old=old)
    if answered:
        return Message(N_("the lock answered the command at address {old}"), old=old)
    if codec.ADDRESS_COMMAND_ANSWERED:
        return Message(N_("no answer to the command at address {old}"), old=old)
    return Message(N_("no answer to the command at address {old}, as expected"), old=old)


async def discover(line: ModbusTransport, first: int = 1, last: int = 247, progress=None) -> list[dict]:
    """Find locks on a line.

    Broadcast first (address 0: a single lock answers with its DeviceAddress, section 5.6) - only
    where at most one lock is known on the line (the plant's and earlier scans'), since several
    would answer together - then a scan of ``first..last`` reading DeviceAddress (holding 103) and the serial
    number (input 104/105). ``progress(done, total)`` is called after each address.
    The locks found are remembered for the line (``line_discovered`` on each lock of it).
    """
    found: dict[int, dict] = {}
    if len(known_addresses(line)) <= 1:  # section 5.6: with several locks on the line their answers collide
        try:
            address = (await line.read_holding(codec.MODBUS_BROADCAST, 103, 1))[0]
            found[address] = {"address": address, "via": "broadcast"}
        except LineError:
            pass
    total = last - first + 1
    for n, unit in enumerate(range(first, last + 1), 1):
        try:
            reg = (await line.transact(
                unit, Message(N_("scan holding {address}"), address=103), None,
                lambda c, u=unit: c.read_holding_registers(103, count=1, device_id=u), retries=0,
            )).registers[0]
            serial = await line.read_input(unit, 104, 2)
            found[unit] = {"address": reg, "serial": codec.serial_number(*serial), "via": "scan"}
        except LineError:
            pass
        if progress:
            progress(n, total)
    scans = _LINE_SCANS.setdefault(line, {})
    for unit in range(first, last + 1):  # a lock no longer found in the scanned range is forgotten
        if unit not in found:
            scans.pop(unit, None)
    scans.update({entry["address"]: entry for entry in found.values()})
    return sorted(found.values(), key=lambda d: d["address"])
