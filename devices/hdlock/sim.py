"""HD-Lock twin: several simulated locks on one Modbus RTU line.

The line is a TCP port carrying RTU frames (a pyserial ``socket://`` URL on the
master side), served by pymodbus. Behaviour follows the document: factory
defaults, volatile holding registers with Save/Restore to a simulated flash,
Set-Address with its condition (also by broadcast to address 255), firmware-protected
registers, answers to broadcast address 0, garbled answers when two locks share an
address, and a door/bolt model with motor current.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass
from urllib.parse import urlparse

from pymodbus.constants import ExcCodes
from pymodbus.datastore import ModbusServerContext
from pymodbus.exceptions import NoSuchIdException
from pymodbus.framer import FramerType
from pymodbus.server import ModbusTcpServer

from devices.hdlock import codec
from devices.hdlock.params import HOLDING, INPUT, PARAMS
from devices.hdlock.tables import LOCK_REQUEST_SOURCE
from devices.params import Access
from devices.simcontrols import NP_, SimAction, SimControls, SimParam

log = logging.getLogger(__name__)

TICK_S = 0.05
BOLT_MAX = 115  # section 3.1: ~115 increments when fully extended
BOLT_SPEED = 160.0  # increments per second (about 0.7 s for a full stroke)
DOOR_TRAVEL_S = 1.2  # time for the strike plate to swing in or out of range

# Plausible values for registers whose factory value the document does not print.
TYPICAL_HOLDING = {
    3: 1, 10: 112, 11: 100, 12: 180, 13: 400, 14: 400, 15: 20, 16: 1500, 17: 900, 18: 20, 19: 50,
    20: 2, 21: 12, 22: 180, 23: 400, 24: 400, 25: 10, 26: 1500, 27: 900, 28: 20, 29: 50,
    30: 500, 31: 10, 32: 3, 33: 5, 40: 4, 41: 2, 3007: 0, 3008: 0,
}
TYPICAL_INPUT = {14: 72, 15: 0b100111, 100: 57, 102: 3, 103: 2}


@dataclass
class BoltMotion:
    """The bolt's motion and the lock's retry state machine (input 9 states 3-12, counters inputs 12/13, settings
    holding 16/26, 30-33)."""

    attempt_start: float
    move_start: float | None = None  # when the current lock or unlock motion started (its time, max_time)
    direction: int = 0  # +1 locking, -1 unlocking, 0 not yet decided
    fails: int = 0  # failed attempts in the current interval-1 series
    series: int = 0  # interval-1 series done
    pause_until: float | None = None
    error_state: int | None = None  # an error state of input 9 the lock is in, None while it is not


class HdLockTwin:
    """One simulated lock: its registers and its physics."""

    def __init__(self, address: int = 1, serial: int = 0x000A1234, door_closed: bool = False, name: str = ""):
        self.name = name or f"lock@{address}"
        self.address = address
        self.input: dict[int, int] = {}
        self.holding: dict[int, int] = {}
        for param in PARAMS:
            store = self.input if param.space == INPUT else self.holding
            default = param.default
            if default is None:
                default = (TYPICAL_INPUT if param.space == INPUT else TYPICAL_HOLDING).get(param.address, 0)
            for address_, word in zip(param.addresses, param.split(default)):
                store[address_] = word
        self.holding[103] = address
        self.input[104], self.input[105] = serial >> 16 & 0xFFFF, serial & 0xFFFF
        self.input[12] = self.input[13] = 0  # RetryLockCounter, RetryUnlockCounter: failed attempts since power-up
        self.writable = {a for p in PARAMS.space(HOLDING) if p.access is Access.RW for a in p.addresses}
        self.flash = self._settings()
        self.factory = dict(self.flash)  # what a new lock out of the box holds (swap_for_new)
        self.refuse_writes = False  # fault injection: every parameter write answered with exception 04
        # physics
        self.door_target_closed = door_closed
        self.door_pos = 0.0 if door_closed else 1.0  # 0 = in place, 1 = out of range
        self.bolt = 0.0
        self.current_ma = 0.0
        self.line_input = True  # LOCK-REQUEST input (>10 V)
        self.strong_magnet = False
        self.in_place_since: float | None = None
        self.state_since = time.monotonic()
        self.motor_since = time.monotonic()
        self.toggle = False
        self._last_line = self.line_input
        self.silent = False  # fault injection: stops answering
        # Section 4.3 does not say whether the lock answers the write of 2003 (Set Modbus Address)
        # at its old address: False stays silent, True answers there. Tests run both.
        self.answers_address_command = False
        # on a CAN bus (HdLockCanSim sets them): the ID it answers under, the bit rate it runs at and the bus's
        self.device_id: codec.DeviceId | None = None
        self.can_bitrate: int | None = None
        self.bus_bitrate: int | None = None
        self.fwu_mode = False  # firmware-update mode: FWU status instead of status (CAN)
        self.keeps_device_id = False  # fault injection: Set Device Address is not taken (the ID stays)
        self.max_time = {"lock": 0, "unlock": 0}
        # fault injection: the bolt is blocked and never leaves the end position it is in (the motor runs, nothing moves)
        self.bolt_stuck = False
        self.ignores_door = False  # fault injection: condition 2 (door closed, section 3.2.2) is never checked
        # the lock's retry state machine (input 9 states 3-12, counters inputs 12/13, settings holding 16/26, 30-33)
        self.motion = BoltMotion(attempt_start=time.monotonic())
        self.step(0.0)

    # -- registers ---------------------------------------------------------------------
    def _settings(self) -> dict[int, int]:
        return {a: self.holding[a] for a in self.writable if a < 2000 or a >= 3000}

    def read(self, space: str, address: int, count: int) -> list[int] | ExcCodes:
        store = self.input if space == INPUT else self.holding
        values = []
        for a in range(address, address + count):
            if a not in store:
                return ExcCodes.ILLEGAL_ADDRESS
            values.append(store[a])
        return values

    def write(self, address: int, value: int) -> ExcCodes | None:
        if address not in self.holding:
            return ExcCodes.ILLEGAL_ADDRESS
        if self.refuse_writes and address != codec.REG_COMMAND:
            return ExcCodes.DEVICE_FAILURE  # fault injection: the lock refuses the write (exception 04)
        if address not in self.writable:
            return None  # firmware protection: acknowledged, not taken (read-back shows it)
        param = PARAMS.get(HOLDING, address)
        if param is not None and param.enum is not None and param.decode(value) not in param.enum:
            return None  # refused by the firmware; the old value stays
        self.holding[address] = value & 0xFFFF  # 4 and 1002 are two registers (section 3.2), not mirrors ...
        if address == codec.REG_LOCK_REQUEST_SOURCE_SETTING:
            # ... but 1002 controls the bolt (section 3.2.2): what is written there becomes the source in use,
            # which holding 4 reports (section 6.5.1); a write of 4 (or cmdSetLockRequestSource) leaves 1002 alone
            self.holding[codec.REG_LOCK_REQUEST_SOURCE] = value & 0xFFFF
        if address == codec.REG_COMMAND and value:
            self._command(value)
        if address == 32770 and value == 1:
            self.reset()
        return None

    def _command(self, command: int) -> None:
        p0, p1, p2 = (self.holding[a] for a in (codec.REG_PARAM0, codec.REG_PARAM1, codec.REG_PARAM2))
        if command == codec.SystemCommand.SAVE_SETTINGS:
            self.flash = self._settings()
            # section 6.6.1.1: of LockRequestSource only the low byte is stored; the high byte is 0 after a reset
            self.flash[codec.REG_LOCK_REQUEST_SOURCE] &= 0xFF
            self.input[101] = (self.input[101] + 1) & 0xFFFF
            self.holding[0] = (self.holding[0] + 1) & 0xFFFF
        elif command == codec.SystemCommand.RESTORE_SETTINGS:
            self.holding.update(self.flash)
        elif command == codec.SystemCommand.SET_MODBUS_ADDRESS:
            if codec.set_address_accepted(p1, p2, self.holding[1000]) and 1 <= p0 <= 254:
                self.address = p0
                self.holding[103] = p0
        self.holding[codec.REG_COMMAND] = 0

    def reset(self) -> None:
        """Power cycle: unsaved holding registers are lost."""
        self.holding.update(self.flash)

    def set_lock_request_source(self, value: int) -> None:
        """cmdSetLockRequestSource (CAN 0x700, section 6.6.1.1): sets holding 4, the source in use.

        A value whose low byte is not in the table is refused (the old source stays); the
        change is volatile like every holding-register change until Save-Settings (section 3).
        """
        if value & 0xFF not in LOCK_REQUEST_SOURCE or codec.REG_LOCK_REQUEST_SOURCE not in self.writable:
            return
        self.holding[codec.REG_LOCK_REQUEST_SOURCE] = value & 0xFFFF

    @property
    def serial(self) -> int:
        return codec.serial_number(self.input[104], self.input[105])

    def swap_for_new(self, serial: int, firmware: int | None = None) -> None:
        """Replace this lock by a new one at the same address (a service swap): another serial number,
        optionally another firmware version, factory settings in its registers and its flash."""
        self.input[104], self.input[105] = serial >> 16 & 0xFFFF, serial & 0xFFFF
        if firmware is not None:
            self.input[100] = firmware & 0xFFFF
        self.holding.update(self.factory)
        self.holding[103] = self.address
        self.flash = self._settings()

    # -- controls of the simulated plant -------------------------------------------------
    def close_door(self) -> None:
        self.door_target_closed = True

    def open_door(self) -> None:
        self.door_target_closed = False

    def toggle_door(self) -> None:
        """Open a closed (or closing) door, close an open one: what a checkout asks a person to do."""
        self.door_target_closed = not self.door_target_closed

    def set_line_input(self, active: bool) -> None:
        self.line_input = active

    def controls(self) -> SimControls:
        """What an engineer may do to this lock in simulation (shown by pages/simcontrols.py); the service
        swap and the refused writes are what the replacement assistant and batch apply are tried with."""
        can = self.device_id is not None

        def switch(name: str, label: str, attribute: str, testid: str = "") -> SimAction:
            return SimAction(name, label, lambda on: setattr(self, attribute, on),
                             state=lambda: bool(getattr(self, attribute)), testid=testid)

        actions = [
            SimAction(NP_("simulation", "close door"), "Close door", self.close_door, icon="door_front", testid="close"),
            SimAction(NP_("simulation", "open door"), "Open door", self.open_door, icon="meeting_room", testid="open"),
            SimAction(NP_("simulation", "toggle door"), "Open / close door", self.toggle_door, testid="toggle-door"),
            switch(NP_("simulation", "LOCK-REQUEST input"), "LOCK-REQUEST input active", "line_input", "line-input"),
            switch(NP_("simulation", "strong magnet"), "Strong magnet", "strong_magnet", "strong-magnet"),
            switch(NP_("simulation", "bolt blocked"), "Bolt blocked (never leaves its end position)", "bolt_stuck",
                   "bolt-stuck"),
            switch(NP_("simulation", "ignores the door"), "Locks with the door open (broken)", "ignores_door",
                   "ignores-door"),
            switch(NP_("simulation", "stop answering"), "Stop answering", "silent", "silent"),
        ]
        if can:
            actions += [switch(NP_("simulation", "firmware-update mode"), "Firmware-update mode", "fwu_mode", "fwu"),
                        SimAction(NP_("simulation", "back to the bus bit rate"), "Back to the bus bit rate",
                                  self.back_to_bus_bitrate, testid="bus-bitrate")]
        else:
            actions.append(switch(NP_("simulation", "answer Set Modbus Address"),
                                  "Answer Set Modbus Address at the old address", "answers_address_command", "answer-address"))
        actions += [
            switch(NP_("simulation", "refuse writes"), "Refuse every write (exception 04)", "refuse_writes", "refuse-writes"),
            SimAction(NP_("simulation", "swap for a new device"), "Swap for a new device",
                      lambda **args: self.swap_for_new(args["new-serial"]), icon="swap_horiz", testid="swap",
                      params=(SimParam(NP_("simulation", "new-serial"), "New serial number", min(self.serial + 100000, 0xFFFFFFFF),
                                       1, 0xFFFFFFFF),)),
        ]
        note = (f"simulated lock runs at {self.can_bitrate} bit/s, device ID {self.device_id}. " if can else "") + (
            "Answer Set Modbus Address: section 4.3 does not say whether the lock answers the command write; "
            "off = it stays silent. " if not can else "") + \
            "Swap puts a factory-new unit with this serial number at the same address."
        return SimControls("Simulated lock (demo)", tuple(actions), note=note)

    def back_to_bus_bitrate(self) -> None:
        """After cmdSetCANbaudrate: the lock runs at the bus's bit rate again (as if switched back by hand)."""
        self.can_bitrate = self.bus_bitrate or codec.CAN_DEFAULT_BITRATE

    # -- the lock's retry state machine (input 9, sections 3.1 and 3.2) ----------------------
    def _drive(self, request: bool, now: float) -> int:
        """Which way the motor drives now (+1 out, -1 in, 0 off), and the error and retry states.

        A lock or unlock attempt must bring the bolt to its Ok position (holding 11 / 21) within
        LockMaximumTime / UnlockMaximumTime (holding 16 / 26); a failed attempt counts in
        RetryLockCounter / RetryUnlockCounter (inputs 12 / 13), and is retried after Lock/UnlockFailDelay1
        (holding 30, ms), Lock/UnlockInterval1 (32) times; then after Lock/UnlockFailDelay2 (31, s), the
        series Lock/UnlockInterval2 (33) times; then the lock gives up until the request changes. States
        (input 9): locking fails 7, pause short 8, pause long 9, given up 10 (then 11 once the request is
        gone); unlocking fails 12 (also in its pauses), given up 6. The document names the states and the
        settings, not how they follow each other: this order is the twin's reading (docs/spec-notes.md)."""
        h, i = self.holding, self.input
        direction = 1 if request else -1
        if direction != self.motion.direction:
            if self.motion.error_state == 10 and direction < 0:
                self.motion.error_state = 11  # the lock request is gone after locking failed for good: open with an error
            else:
                self.motion.error_state = None
            self.motion.direction, self.motion.attempt_start, self.motion.fails, self.motion.series, self.motion.pause_until = direction, now, 0, 0, None
        if direction > 0:
            at_ok, at_end, limit_ms = round(self.bolt) >= h[11], self.bolt >= BOLT_MAX, h[16]
        else:
            at_ok, at_end, limit_ms = round(self.bolt) <= h[21], self.bolt <= 0, h[26]
        if self.motion.error_state in (6, 10) or (self.motion.error_state == 11 and direction < 0 and at_end):
            return 0  # given up until the request changes
        if self.motion.pause_until is not None:
            if now < self.motion.pause_until:
                return 0
            self.motion.pause_until, self.motion.attempt_start = None, now
            self.motion.error_state = None if self.motion.error_state != 11 else 11
        if at_ok:
            if self.motion.error_state != 11 or direction > 0:
                self.motion.error_state = None
            self.motion.fails = self.motion.series = 0
            self.motion.attempt_start = now
            return 0 if at_end else direction
        if (now - self.motion.attempt_start) * 1000 <= limit_ms:
            return direction
        # this attempt failed
        counter = 12 if direction > 0 else 13
        i[counter] = min(0xFFFF, i.get(counter, 0) + 1)
        self.motion.fails += 1
        if self.motion.fails < max(1, h[32]):
            self.motion.error_state, self.motion.pause_until = (8 if direction > 0 else 12), now + h[30] / 1000
        else:
            self.motion.fails, self.motion.series = 0, self.motion.series + 1
            if self.motion.series < max(1, h[33]):
                self.motion.error_state, self.motion.pause_until = (9 if direction > 0 else 12), now + h[31]
            else:
                self.motion.error_state = 10 if direction > 0 else 6
        return 0

    # -- physics -----------------------------------------------------------------------
    def step(self, dt: float) -> None:
        now = time.monotonic()
        h, i = self.holding, self.input
        # door: the strike plate swings into range
        target = 0.0 if self.door_target_closed else 1.0
        travel = dt / DOOR_TRAVEL_S
        if abs(self.door_pos - target) <= travel:
            self.door_pos = target
        else:
            self.door_pos += travel if target > self.door_pos else -travel
        proximity = round(self.door_pos * 100)
        locked_side = self.bolt > 5
        # section 3.2.7: the closed-door window is wider while locked (thresholds -30 / -60)
        threshold = -codec.to_signed16(h[3006] if locked_side else h[3004])
        in_place = proximity < threshold and not self.strong_magnet
        if in_place and self.in_place_since is None:
            self.in_place_since = now
        if not in_place:
            self.in_place_since = None
        door_in_position = in_place and (now - self.in_place_since) * 1000 >= h[3000]
        # lock request (section 3.2.2) by the source in use, holding 4 (section 6.5.1)
        source = h[codec.REG_LOCK_REQUEST_SOURCE]
        line = self.line_input
        if line != self._last_line:
            kind = source & 0x7F
            if kind == 5 or (kind == 6 and line) or (kind == 7 and not line):
                self.toggle = not self.toggle
            self._last_line = line
        cond1 = {0: False, 1: True, 2: self.strong_magnet, 3: not line, 4: line}.get(source & 0x7F, self.toggle)
        cond2 = True if source & 0x80 or self.ignores_door else door_in_position
        request = cond1 and cond2
        # bolt, with the lock's own time limits and retries
        old_bolt = self.bolt
        drive = self._drive(request, now)
        if drive > 0 and not self.bolt_stuck:
            self.bolt = min(BOLT_MAX, self.bolt + BOLT_SPEED * dt)
        elif drive < 0 and not self.bolt_stuck:
            self.bolt = max(0.0, self.bolt - BOLT_SPEED * dt)
        moving_out, moving_in = self.bolt > old_bolt, self.bolt < old_bolt
        moving = moving_out or moving_in
        if moving and self.motion.move_start is None:
            self.motion.move_start = now
        if not moving and self.motion.move_start is not None:
            took = int((now - self.motion.move_start) * 1000)
            key = "lock" if self.bolt > 5 else "unlock"
            register = 1004 if key == "lock" else 1003
            h[register] = max(h[register], min(took, 0xFFFF))
            self.motion.move_start = None
        target_ma = 420.0 if moving else (35.0 if self.bolt >= BOLT_MAX else 0.0)
        self.current_ma += (target_ma - self.current_ma) * min(1.0, dt * 12) if dt else 0
        bolt = round(self.bolt)
        locked = bolt >= h[11]
        unlocked = bolt <= h[21]
        status = 0
        status |= codec.LOCK_REQUEST | codec.LOCK_REQUEST_BIT4 if request else 0
        status |= codec.PROXIMITY_IN_PLACE if in_place else 0
        status |= codec.DOOR_IN_POSITION if door_in_position else 0
        status |= codec.PROXIMITY_OVERRANGE if self.strong_magnet else 0
        status |= codec.FORCE_ACTIVE if source & 0x80 else 0
        status |= codec.BOLT_LOCKED if locked and not moving_in else 0
        status |= codec.BOLT_UNLOCKED if unlocked and not moving_out else 0
        status |= codec.BOLT_MOVING_OUT if moving_out else 0
        status |= codec.BOLT_MOVING_IN if moving_in else 0
        # state machine (input 9)
        state = 4 if locked and not moving else 2 if unlocked and not moving else 3 if moving_out else 5
        if self.motion.error_state is not None:
            state = self.motion.error_state
        elif drive and not moving:  # the motor drives a blocked bolt
            state = 3 if drive > 0 else 5
        if state != i[9]:
            self.state_since = now
        motor = 1 if moving_out else 2 if moving_in else 0
        if motor != i[3]:
            self.motor_since, i[61] = now, i[60]
            if motor == 0:
                i[54] = 1  # MotorResult AtPos
        hall1 = 255 if self.strong_magnet else max(0, 200 - proximity * 2)
        hall2 = 255 if self.strong_magnet else max(0, 190 - proximity * 2)
        current = round(self.current_ma)
        i.update({
            0: int(locked), 1: int(request), 2: bolt, 3: motor, 4: round(BOLT_SPEED) if moving else 0,
            5: hall1, 6: hall2, 7: proximity, 8: 3 if door_in_position else (2 if in_place else 1),
            9: state, 10: min(0xFFFF, int((now - self.state_since) * 1000)), 11: 0,
            16: h[3006] if locked_side else h[3004],
            50: bolt, 51: round(BOLT_SPEED) if moving_out else (0x10000 - round(BOLT_SPEED) if moving_in else 0),
            52: round(BOLT_SPEED) if moving else 0, 53: 4 if moving else 0xFFFF, 55: 80 if moving else (5 if bolt else 0),
            56: 19 if moving else 0, 57: current, 58: max(i.get(58, 0), current),
            59: 0, 60: min(0xFFFF, int((now - self.motor_since) * 1000)), 62: 24, 63: current,
        })
        h.update({
            2: bolt, 1000: status, 1001: bolt, 1005: proximity, 1006: hall1 << 8 | hall2,
            1007: 31, 1008: 24100, 1009: current, 1010: max(h.get(1010, 0), current),
        })


class HdLockContext(ModbusServerContext):
    """pymodbus datastore that routes each request to the twin(s) with that address.

    Two locks at one address both take a write and answer together: the answer is
    garbled on the wire (``garble_next``, applied by :class:`HdLockSim`).
    """

    def __init__(self, twins: Sequence[HdLockTwin], wire_delay: float = 0.0):
        # not calling super().__init__: this context answers by itself
        self.twins = list(twins)
        self.old_simulator = True
        self.simdevices = []
        self._echo_twin = self.twins[0]
        self.wire_delay = wire_delay  # seconds per character (11 bits / baud), 0 = none
        self.garble_next = False

    def device_ids(self) -> list[int]:
        return [t.address for t in self.twins]

    def _answering(self, device_id: int) -> list[HdLockTwin]:
        """The twins that take a request to ``device_id``; more than one answer together."""
        if device_id == codec.MODBUS_BROADCAST:  # section 5.6: every lock answers the broadcast
            answering = [t for t in self.twins if not t.silent]
        else:
            answering = [t for t in self.twins if t.address == device_id and not t.silent]
        if not answering:
            raise NoSuchIdException(f"no lock at {device_id}")
        self.garble_next = len(answering) > 1
        return answering

    async def _line_time(self, request_chars: int, response_chars: int) -> None:
        if self.wire_delay:
            # both frames on the wire plus the 3.5-character gap after each
            await asyncio.sleep((request_chars + response_chars + 7) * self.wire_delay)

    async def async_getValues(self, device_id, func_code, address, count=1):
        if func_code == 6:  # the echo after a write, from the lock written (its address may just have changed)
            return [self._echo_twin.holding.get(address, 0)]
        twin = self._answering(device_id)[0]
        space = INPUT if func_code == 4 else HOLDING
        await self._line_time(8, 5 + 2 * count)
        return twin.read(space, address, count)

    async def async_setValues(self, device_id, func_code, address, values):
        if func_code != 6:
            return ExcCodes.ILLEGAL_FUNCTION  # SPEC-NOTES: only 0x03, 0x04, 0x06 are used
        if device_id == codec.MODBUS_BROADCAST_SET_ADDRESS:  # section 4.3: every lock takes it, none answers
            for twin in self.twins:
                if not twin.silent:
                    twin.write(address, values[0])
            raise NoSuchIdException("broadcast 255: no answer")
        twins = self._answering(device_id)
        await self._line_time(8, 8)
        results = [twin.write(address, values[0]) for twin in twins]
        self._echo_twin = twins[0]
        address_command = address == codec.REG_COMMAND and values[0] == codec.SystemCommand.SET_MODBUS_ADDRESS
        if address_command and not all(t.answers_address_command for t in twins):
            self.garble_next = False
            raise NoSuchIdException("Set Modbus Address: this lock does not answer the command write")
        return results[0]


def _host_port(url: str) -> tuple[str, int]:
    parsed = urlparse(url)
    if parsed.scheme != "socket" or not parsed.port:
        raise ValueError(f"a simulated Modbus line needs a socket://host:port URL, not {url!r}")
    return parsed.hostname or "127.0.0.1", parsed.port


class HdLockSim:
    """All simulated locks of one plant-file bus, served on the bus's endpoint."""

    def __init__(self, bus, devices):
        self.bus = bus
        self.twins: dict[str, HdLockTwin] = {}
        for dev in devices:
            self.twins[dev.name] = HdLockTwin(
                address=dev.options["address"],
                serial=dev.options.get("serial") or 0x000A0000 + dev.options["address"],
                door_closed=dev.options.get("door", "open") == "closed",
                name=dev.name,
            )
        delay = 11.0 / bus.options["baudrate"] if bus.options.get("wire_delay") else 0.0
        self.context = HdLockContext(list(self.twins.values()), wire_delay=delay)
        self.server: ModbusTcpServer | None = None
        self._task: asyncio.Task | None = None
        self.corrupt_next = 0  # fault injection: damage the CRC of the next n answers

    def _trace(self, sending: bool, data: bytes) -> bytes:
        if not sending or not data:
            return data
        if self.context.garble_next:  # several locks answered at once
            self.context.garble_next = False
            return bytes(b ^ 0x5A for b in data)
        if self.corrupt_next > 0:
            self.corrupt_next -= 1
            return data[:-1] + bytes([data[-1] ^ 0xFF])
        return data

    async def start(self) -> None:
        host, port = _host_port(self.bus.options["port"])
        self.server = ModbusTcpServer(
            self.context,
            framer=FramerType.RTU,
            address=(host, port),
            ignore_missing_devices=True,
            trace_packet=self._trace,
        )
        try:
            await self.server.serve_forever(background=True)
        except RuntimeError:
            self.server = None
            raise OSError(f"cannot listen on {host}:{port} for the simulated line {self.bus.name}: port in use?") from None
        self._task = asyncio.create_task(self._run(), name=f"sim {self.bus.name}")

    async def _run(self) -> None:
        last = time.monotonic()
        while True:
            await asyncio.sleep(TICK_S)
            now = time.monotonic()
            for twin in self.twins.values():
                twin.step(now - last)
            last = now

    async def stop(self) -> None:
        if self._task:
            self._task.cancel()
            self._task = None
        if self.server:
            await self.server.shutdown()
            self.server = None


# -- CAN twin (section 6) ------------------------------------------------------------------

STATUS_PERIOD_S = 1.0


class HdLockCanSim:
    """Simulated locks on one CAN bus: status every 1000 ms, register answers, commands.

    The twins use their own python-can bus instance on the plant bus's interface and
    channel (``virtual`` in one process, ``udp_multicast`` across processes), through the
    same kind of CAN bus the worker uses: ``open_can(name, options)`` is handed in by the
    simulated plant (app/runtime.py), so this package imports nothing of app/.
    """

    def __init__(self, bus, devices, open_can):
        self.bus_config = bus
        self.bitrate = bus.options.get("bitrate", codec.CAN_DEFAULT_BITRATE)
        self.twins: dict[str, HdLockTwin] = {}
        for n, dev in enumerate(devices):
            device_id = codec.DeviceId.make(dev.options["device_id"], dev.options.get("extended"))
            serial = dev.options.get("serial") or (device_id.value if device_id.extended else 0x000A0000 + device_id.value)
            twin = HdLockTwin(address=1, serial=serial, door_closed=dev.options.get("door", "open") == "closed", name=dev.name)
            twin.device_id = device_id
            twin.can_bitrate = self.bitrate  # cmdSetCANbaudrate changes it: the lock then leaves this bus
            twin.bus_bitrate = self.bitrate
            twin.status_phase = n * 0.137  # the locks' status frames do not all come at once
            self.twins[dev.name] = twin
        options = {k: v for k, v in bus.options.items() if k != "simulate"}
        self.can = open_can(f"{bus.name} (simulated locks)", options)
        for request_id in codec.CAN_REQUEST_IDS:
            self.can.subscribe(False, request_id, self.on_request)
        self._task: asyncio.Task | None = None

    def on_bus(self, twin: HdLockTwin) -> bool:
        return twin.can_bitrate == self.bitrate and not twin.silent

    def _send(self, twin: HdLockTwin, data: bytes) -> None:
        self.can.send(twin.device_id.value, data, twin.device_id.extended)

    def on_request(self, msg) -> None:
        try:
            req = codec.decode_request(codec.CanFrame(msg.arbitration_id, bytes(msg.data), msg.is_extended_id))
        except codec.CodecError:
            return  # a lock ignores what it cannot parse
        broadcast = req.target.value == codec.CAN_BROADCAST and not req.target.extended
        for twin in self.twins.values():
            if not self.on_bus(twin) or not (broadcast or req.target == twin.device_id):
                continue
            self._handle(twin, req, broadcast)

    def _handle(self, twin: HdLockTwin, req: codec.CanRequest, broadcast: bool) -> None:
        if req.kind == codec.CAN_COMMAND:
            if req.a == codec.CanCommand.SET_LOCK_REQUEST_SOURCE:
                twin.set_lock_request_source(req.b)
            elif req.a == codec.CanCommand.SET_CAN_BAUDRATE and req.b in codec.CAN_BITRATES:
                twin.can_bitrate = codec.CAN_BITRATES[req.b][0]
            elif req.a in (codec.CanCommand.FIRMWARE_UPDATE_ENTER, codec.CanCommand.BOOTLOADER_UPDATE_ENTER):
                twin.fwu_mode = True
            elif req.a == codec.CanCommand.UPDATE_LEAVE:
                twin.fwu_mode = False
        elif req.kind == codec.CAN_SET_DEVICE_ADDRESS and not broadcast and not twin.keeps_device_id:
            twin.device_id = req.new_id
        elif req.kind in (codec.CAN_READ_INPUT, codec.CAN_READ_HOLDING) and not twin.fwu_mode:
            space = INPUT if req.kind == codec.CAN_READ_INPUT else HOLDING
            store = twin.input if space == INPUT else twin.holding
            for address in range(req.a, min(req.a + req.b, 0x10000)):
                if address in store:
                    self._send(twin, codec.encode_register_answer(codec.RegisterAnswer(space, address, store[address])))
        elif req.kind in (codec.CAN_WRITE_HOLDING, codec.CAN_SILENT_WRITE_HOLDING) and not twin.fwu_mode:
            if req.a not in twin.holding:
                return
            twin.write(req.a, req.b)  # protected registers keep their value: the echo shows it
            if req.kind == codec.CAN_WRITE_HOLDING:
                value = twin.holding[req.a]
                self._send(twin, codec.encode_register_answer(codec.RegisterAnswer(HOLDING, req.a, value)))

    def status_data(self, twin: HdLockTwin) -> bytes:
        if twin.fwu_mode:
            return codec.encode_fwu_status(codec.FwuStatusFrame(flashing=False, application=True))
        return codec.encode_status(codec.StatusFrame(
            status=twin.holding[1000], motor_pos=twin.holding[1001],
            proximity=twin.input[7], lock_request_source=twin.holding[codec.REG_LOCK_REQUEST_SOURCE],
        ))

    async def start(self) -> None:
        await self.can.start()
        self._task = asyncio.create_task(self._run(), name=f"sim {self.bus_config.name}")

    async def _run(self) -> None:
        last = time.monotonic()
        start = last
        sent: dict[str, int] = {}
        while True:
            await asyncio.sleep(TICK_S)
            now = time.monotonic()
            for name, twin in self.twins.items():
                twin.step(now - last)
                slot = int((now - start - twin.status_phase) / STATUS_PERIOD_S)
                if slot > sent.get(name, -1) and self.on_bus(twin):
                    sent[name] = slot
                    self._send(twin, self.status_data(twin))
            last = now

    async def stop(self) -> None:
        if self._task:
            self._task.cancel()
            self._task = None
        await self.can.stop()
