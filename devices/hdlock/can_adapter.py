"""HD-Lock conversation on a CAN bus (section 6): status frames, register reads and writes, CAN commands.

The write checks, backup and the worker's session hooks are shared with the Modbus adapter
(:class:`devices.hdlock.adapter.HdLockBackup`)."""

from __future__ import annotations

import asyncio
import contextlib
import time

from devices.decoding import decoded
from devices.hdlock import STATUS_FRAME_BOLT, codec
from devices.hdlock.adapter import (CAN_SETTINGS_BLOCKS, CAN_STATUS_BLOCKS, HISTORY_CAN, HISTORY_MIN_GAP_S,
                                    NEW_ID_LISTEN_S, P_DEVICE_ID, P_FWU, P_PROXIMITY_FRAME, P_SOURCE_FRAME,
                                    P_STATUS_FRAME, SERIAL_PARAM, CommandError, HdLockBackup, chart_sample, fwu_text,
                                    status_frame_text)
from devices.hdlock.params import HOLDING, INPUT, PARAMS
from devices.live import DeviceState, Point
from devices.message import Message, N_, message_of
from devices.params import Accepted
from devices.transport import CanTransport


def _arrival(msg) -> float:
    """The frame's receive time from the interface, or now when it has none or one from another clock."""
    now = time.time()
    stamp = msg.timestamp
    return stamp if 0 <= now - stamp < 5.0 else now


CAN_FRAME_BITS = 135  # an extended 6-byte answer with stuffing, roughly


class HdLockCanAdapter(HdLockBackup):
    """One lock on a shared :class:`~devices.transport.CanTransport`, addressed by its device ID (section 6)."""

    params = PARAMS
    transport = "can"
    status_blocks = CAN_STATUS_BLOCKS
    settings_blocks = CAN_SETTINGS_BLOCKS

    def __init__(self, config, state: DeviceState, bus: CanTransport):
        self.config = config
        self.state = state
        self.bus = bus
        self.device_id = codec.DeviceId.make(config.options["device_id"], config.options.get("extended"))
        self.blocks = {space: PARAMS.blocks(space) for space in (INPUT, HOLDING)}
        self.timeout = float(bus.options.get("timeout", 0.5))
        self.state.params = PARAMS
        self.state.stale_after = 2.5  # status every 1000 ms (section 6.5)
        self._waiting: dict[tuple[str, int], asyncio.Future] = {}
        self._setup_periods()
        self._subscribe()

    # -- frames ----------------------------------------------------------------------------
    def _subscribe(self) -> None:
        self.bus.subscribe(self.device_id.extended, self.device_id.value, self.on_frame)
        self.state.fact(P_DEVICE_ID, self.device_id.value, text=str(self.device_id), raw=self.device_id.to_u32())

    def on_frame(self, msg) -> None:
        """Every frame under this lock's device ID (called in the event loop)."""
        data = bytes(msg.data)
        memo = self._status_memo
        if data == memo[0]:  # the same status as the last frame (a lock at rest): decoded and worded already
            self._on_status(_arrival(msg), memo)
            return
        frame = decoded(self.state, codec.decode_lock_frame, data, "frame", show_bytes=True)
        if frame is None:
            return
        state = self.state
        if isinstance(frame, codec.StatusFrame):
            # the third status word as sent: (proximity << 6) + LockRequestSource (section 6.5.1; SPEC-NOTES:
            # a source of 0x80-0x87 comes with ForceActive and is taken off before the split)
            word = ((frame.proximity << 6) + frame.lock_request_source) & 0xFFFF
            source = codec.LOCK_REQUEST_SOURCE.get(frame.lock_request_source, f"undefined ({frame.lock_request_source})")
            self._status_memo = memo = (data, frame, status_frame_text(frame), word, source)
            self._on_status(_arrival(msg), memo)
        elif isinstance(frame, codec.FwuStatusFrame):
            state.fact(P_FWU, frame, text=fwu_text(frame))
            state.mark_seen()
        else:
            state.counters.responses += 1
            state.update_registers(frame.space, frame.address, [frame.value])
            future = self._waiting.pop((frame.space, frame.address), None)
            if future is not None and not future.done():
                future.set_result(frame.value)

    _status_memo: tuple = (None,)  # (frame bytes, StatusFrame, its text, third word, source text) of the last status
    _last_status = 0.0  # arrival time of the last status frame

    def _on_status(self, arrival: float, memo: tuple) -> None:
        """A periodic status (section 6.5.1), as :attr:`_status_memo` holds it: its values as points and registers,
        one change for the readers (O(1): a handful of small records, the version bumped once)."""
        _data, frame, text, word, source = memo
        state = self.state
        if arrival - self._last_status > state.stale_after:  # status frames again after a gap: perhaps another lock
            self.read_settings_next()
        self._last_status = arrival
        fwu = state.points.get(P_FWU)
        if fwu is None or fwu.value is not None or fwu.text != "":  # status frames again: out of firmware-update mode
            state.fact(P_FWU, None, text="")
        state.counters.responses += 1  # a frame heard, as the other CAN devices count them
        history = state.history
        # a chart needs no more than 10 samples a second
        sample = self._chart_sample if not history or arrival - history[-1][0] >= HISTORY_MIN_GAP_S else None
        state.publish_telegram(arrival, {
            P_STATUS_FRAME: Point(frame, "", arrival, None, text),
            P_PROXIMITY_FRAME: Point(frame.proximity, "Inc", arrival, word),
            # motorPos (section 6.5.1), with the time the frame arrived: tiles show it rather than the slower register poll
            STATUS_FRAME_BOLT: Point(frame.motor_pos, "Inc", arrival, frame.motor_pos),
            P_SOURCE_FRAME: Point(frame.lock_request_source, "", arrival, word, source),
        }, {(HOLDING, 1000): frame.status, (HOLDING, 1001): frame.motor_pos}, sample)

    def _chart_sample(self) -> dict:
        return chart_sample(self.state, HISTORY_CAN)

    def owns_frame(self, arbitration_id: int, is_extended: bool, data: bytes) -> bool:
        """Bus monitor filter: frames from this lock and requests addressed to it (or broadcast)."""
        if (is_extended, arbitration_id) == (self.device_id.extended, self.device_id.value):
            return True
        if is_extended or arbitration_id not in codec.CAN_REQUEST_IDS or len(data) < 4:
            return False
        target = codec.DeviceId.from_u32(int.from_bytes(data[0:4], "little"))
        return target == self.device_id or target == codec.BROADCAST_ID

    def _send(self, frame: codec.CanFrame) -> None:
        if not self.bus.send(frame.arbitration_id, frame.data, frame.is_extended_id):
            raise CommandError(f"CAN bus {self.bus.name} did not take the frame: {self.bus.state.last_error or 'bus not open'}")

    async def _request(self, frame: codec.CanFrame, expect: list[tuple[str, int]], *, own_answer: bool = False) -> dict[tuple[str, int], int]:
        """Send a request and wait for one answer frame per expected register.

        Reads of a register in flight together share its next answer. The lock answers a read and echoes a write alike
        (the register and its value, section 6.6.5), so a write (``own_answer``) is sent only once the answer already
        awaited for its register has come (a poll's read): the next answer is then its own echo, not the old value.
        """
        loop = asyncio.get_running_loop()
        wire = len(expect) * CAN_FRAME_BITS / self.bus.options.get("bitrate", 250_000)
        if own_answer:
            in_flight = [f for key in expect if (f := self._waiting.get(key)) is not None and not f.done()]
            if in_flight:
                await asyncio.wait(in_flight, timeout=self.timeout + 2 * wire)
        futures = {}
        for key in expect:
            old = self._waiting.get(key)
            futures[key] = old if old is not None and not old.done() and not own_answer else loop.create_future()
            self._waiting[key] = futures[key]
        self.state.counters.requests += 1
        try:
            self._send(frame)
            done, pending = await asyncio.wait(futures.values(), timeout=self.timeout + 2 * wire)
        finally:
            for key in expect:
                if self._waiting.get(key) is futures[key] and not futures[key].done():
                    self._waiting.pop(key, None)
        missing = [key for key, f in futures.items() if not f.done()]
        if missing:
            self.state.counters.timeouts += 1
            raise CommandError(
                f"lock {self.device_id} did not answer {len(missing)} of {len(expect)} registers "
                f"within {self.timeout + 2 * wire:.2f} s (first missing: {missing[0][0]} {missing[0][1]})"
            )
        return {key: f.result() for key, f in futures.items()}

    # -- polling ---------------------------------------------------------------------------
    async def poll(self) -> None:
        """Read the status and identity registers (one answer frame each), the settings when due
        (SETTINGS_PERIOD_S); status frames arrive on their own."""
        blocks, with_settings = self._blocks_now()
        serial = self._serial_word()
        try:
            await self._read_blocks(blocks)
            if not with_settings and serial is not None and self._serial_word() != serial:
                with_settings = True  # another lock answers under this ID: its settings now
                await self._read_blocks(self.settings_blocks)
            if with_settings:
                self._settings_read()
        except CommandError as exc:
            self.read_settings_next()
            if self.state.age is None or self.state.age > self.state.stale_after:
                self.state.mark_offline(message_of(exc))  # an error's Message, worded by the page
            else:
                self.state.error(message_of(exc), log=False)

    async def _read_blocks(self, blocks: list[tuple[str, int, int]]) -> None:
        for space, start, count in blocks:
            await self._request(codec.encode_read(self.device_id, space, start, count),
                                [(space, a) for a in range(start, start + count)])

    # -- writes ----------------------------------------------------------------------------
    async def write_accepted(self, accepted: Accepted, *, confirmed: bool = False) -> int:
        """Write through 0x704 and check the echoed value (section 6.6.5)."""
        param, raw = accepted.param, self._cleared(accepted, confirmed)
        back = await self._write_register(param.address, raw)
        if back != raw:
            self.state.counters.write_errors += 1
            raise CommandError(
                f"{param.name}: the lock answered {param.display(back)} instead of {param.display(raw)} "
                "(refused by the firmware: protected register or value not accepted)"
            )
        self.state.unsaved.add(param.key)
        self.read_settings_next()
        self.state.event("info", Message(N_("{name} = {value} written, echo checked"), name=param.label or param.name,
                                         value=param.display(raw)))
        return raw

    async def _write_register(self, address: int, raw: int) -> int:
        try:
            answer = await self._request(codec.encode_write(self.device_id, address, raw), [(HOLDING, address)], own_answer=True)
        except CommandError:
            self.state.counters.write_errors += 1
            raise
        return answer[(HOLDING, address)]

    async def _system_command(self, command: codec.SystemCommand) -> None:
        for register, value in codec.encode_system_command(command).writes:
            await self._write_register(register, value)
        self.read_settings_next()

    async def save_settings(self) -> None:
        before = (await self._request(codec.encode_read(self.device_id, INPUT, 101), [(INPUT, 101)]))[(INPUT, 101)]
        await self._system_command(codec.SystemCommand.SAVE_SETTINGS)
        after = (await self._request(codec.encode_read(self.device_id, INPUT, 101), [(INPUT, 101)]))[(INPUT, 101)]
        if after == before:
            raise CommandError("Save-Settings sent, but SavedSettings (input 101) did not count up: check the lock")
        self.state.unsaved.clear()
        self.state.event("info", Message(N_("settings saved (SavedSettings = {count})"), count=after))

    async def restore_settings(self) -> None:
        await self._system_command(codec.SystemCommand.RESTORE_SETTINGS)
        self.state.unsaved.clear()
        self.read_settings_next()
        await self.poll()
        self.state.event("info", Message(N_("saved settings restored; unsaved changes discarded")))

    # -- CAN commands (section 6.6.1, 6.6.2) ------------------------------------------------
    def _target(self, broadcast: bool) -> codec.DeviceId:
        return codec.BROADCAST_ID if broadcast else self.device_id

    async def set_lock_request_source(self, value: int, broadcast: bool = False) -> None:
        """cmdSetLockRequestSource; verified by reading back holding 4, the source the lock uses."""
        try:
            frame = codec.encode_can_command(self._target(broadcast), codec.CanCommand.SET_LOCK_REQUEST_SOURCE, value)
        except codec.CodecError as exc:
            raise CommandError(str(exc)) from None
        self._send(frame)
        who = Message(N_("all locks (broadcast)")) if broadcast else Message(N_("lock {device_id}"), device_id=self.device_id)
        if broadcast:
            self.state.event("warning", Message(N_("LockRequestSource {value} sent to {target}"), value=f"0x{value:02X}",
                                                target=who))
            return
        await asyncio.sleep(0.05)
        key = (HOLDING, codec.REG_LOCK_REQUEST_SOURCE)
        back = (await self._request(codec.encode_read(self.device_id, *key), [key]))[key]
        if back != value:
            raise CommandError(f"LockRequestSource (holding 4) reads 0x{back:02X} after the command, not 0x{value:02X}")
        self.state.unsaved.add(PARAMS.get(*key).key)  # volatile until Save-Settings (section 3)
        self.state.event("info", Message(N_("LockRequestSource {value} set on {target}, read back from holding 4"),
                                         value=f"0x{value:02X}", target=who))

    async def set_can_bitrate(self, code: int, broadcast: bool = False) -> None:
        """cmdSetCANbaudrate: the lock leaves this bus until the bus runs at the new rate too."""
        try:
            frame = codec.encode_can_command(self._target(broadcast), codec.CanCommand.SET_CAN_BAUDRATE, code)
        except codec.CodecError as exc:
            raise CommandError(str(exc)) from None
        self._send(frame)
        rate = codec.CAN_BITRATES[code][0]
        who = Message(N_("all locks (broadcast)")) if broadcast else Message(N_("lock {device_id}"), device_id=self.device_id)
        self.state.event("warning", Message(N_("CAN bit rate {rate} bit/s sent to {target}: switch the bus to {rate} bit/s "
                                               "to reach it again"), rate=rate, target=who))

    async def set_device_address(self, new_value: int, extended: bool | None = None) -> bool:
        """Set Device Address (0x701), section 6.6.2. Refused when anything is heard under the new ID first (a lock
        that is on the bus but not in the plant file: each CAN ID belongs to one participant, 6.2 b). True once a
        status frame (6.5.1) comes under the new ID and the lock answering there has this lock's serial number;
        False when none comes (the lock kept its ID); CommandError when another lock answers there."""
        try:
            new = codec.DeviceId.make(new_value, extended)
            frame = codec.encode_set_device_address(self.device_id, new)
        except codec.CodecError as exc:
            raise CommandError(str(exc)) from None
        old = self.device_id
        if new == old:
            raise CommandError(f"the lock has device ID {new} already: nothing to change")
        serial = await self._read_serial()
        heard = asyncio.Event()
        status = asyncio.Event()

        def on_new(msg) -> None:
            heard.set()
            if codec.looks_like_status(bytes(msg.data)):
                status.set()

        self.bus.subscribe(new.extended, new.value, on_new)
        try:
            with contextlib.suppress(asyncio.TimeoutError):  # a lock sends its status every 1000 ms (6.5.1)
                await asyncio.wait_for(heard.wait(), timeout=NEW_ID_LISTEN_S)
            if heard.is_set():
                raise CommandError(f"CAN ID {new} is heard on the bus: another participant sends under it (a lock that "
                                   "is not in the plant file?). Each CAN ID belongs to one participant only (section 6.2 b): "
                                   "choose another ID, or adopt that lock and give it another ID first")
            self._send(frame)
            try:
                await asyncio.wait_for(status.wait(), timeout=2.5)  # the status comes every 1000 ms
            except asyncio.TimeoutError:
                self.state.event("warning", Message(N_("no frame under the new ID {new} within 2.5 s: the lock kept {old}?"),
                                                    new=new, old=old))
                return False
        finally:
            self.bus.unsubscribe(new.extended, new.value, on_new)
        self._listen_under(new)
        try:
            answered = await self._read_serial()
        except CommandError as exc:
            answered, why = None, str(exc)
        if answered != serial:
            self._listen_under(old)
            self.read_settings_next()
            found = (Message(N_("no serial number answered there")) if answered is None else
                     Message(N_("the lock answering there has serial number {serial}"), serial=answered))
            self.state.event("error", Message(N_("Set Device Address {old} -> {new}: a status frame came under {new}, but "
                                                 "{found}, not {serial} (this lock's): another lock may use that ID now. "
                                                 "Check both locks"), old=old, new=new, found=found, serial=serial))
            raise CommandError(f"not confirmed: under {new} {found}, not this lock's {serial}"
                               + (f" ({why})" if answered is None else "") + f"; this page keeps talking to {old}. "
                               "Check which lock uses which ID (the bus monitor shows their status frames)")
        self.state.event("warning", Message(N_("device ID changed {old} -> {new} (serial number {serial} answers there): "
                                               "change device_id in the plant file"), old=old, new=new, serial=serial))
        return True

    def _listen_under(self, ident: codec.DeviceId) -> None:
        """Talk to the lock under ``ident`` from now on."""
        self.bus.unsubscribe(self.device_id.extended, self.device_id.value, self.on_frame)
        self.device_id = ident
        self._subscribe()

    async def _read_serial(self) -> int:
        """The serial number (input 104 high word, 105 low word, SPEC-NOTES) of the lock under the current ID."""
        high, low = (INPUT, SERIAL_PARAM.address), (INPUT, SERIAL_PARAM.address + 1)
        answer = await self._request(codec.encode_read(self.device_id, INPUT, SERIAL_PARAM.address, 2), [high, low])
        return codec.serial_number(answer[high], answer[low])
