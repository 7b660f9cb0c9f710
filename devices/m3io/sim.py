"""CAN-M3IO twin (KM, HM, HMR) on a CAN bus, following the document.

Silent until the first master telegram; DigIn on change (at most every 10 ms) and in
answer to DigOut; temperatures every 500 ms while the watchdog runs; outputs off and
temperatures stopped after 2 s without DigOut; the Si/Triac/Last bits per SSR with
fault injection (remove a load, blow a fuse, break or short a triac); Si = 0 latched
until the 24 V are cut; the HMR load check of the three-phase output (three phases, or
exactly two with P2); both ID schemes; the SYNC cfg byte (not stored: lost at any
reset); addressed data with customer-data storage.

Strict modes a real module may have (plant options of the simulated twin): ``firmware`` before 17.0
(``0x1100``) knows no P2 (section 4.3): it ignores area 1 index 15 (undefined addresses are ignored,
7.2.4.2) and the P2 bit of the cfg byte; ``store_s``: how long storing a customer record takes, deaf and
silent meanwhile (7.2.4.2.4: the document gives no time; a real EEPROM may take far longer than the
twin's default).
"""

from __future__ import annotations

import asyncio
import math
import time
from dataclasses import dataclass

from devices import simserver
from devices.m3io import codec
from devices.m3io.codec import Variant
from devices.simcontrols import NP_, SimAction, SimControls, SimParam

TICK_S = 0.01
STORE_S = 0.03  # a customer record takes this long to store (7.2.4.2.4)
FIRMWARE = 0x1201  # 18.1, the document's firmware
P2_FIRMWARE = 0x1100  # P2 exists from firmware 17.0 on (section 4.3): older firmware ignores it


@dataclass
class SsrTwin:
    load: bool = True  # a heater is connected and the mains supply is there
    fuse_ok: bool = True
    triac_ok: bool = True
    triac_shorted: bool = False  # a triac with a permanent short circuit
    si_blown: bool = False  # the module's latch: Si = 0 until the 24 V are cut (7.2.3)
    on: bool = False  # what the module switches (after its own checks)
    commanded: bool = False

    @property
    def last(self) -> bool:
        """Last: supply and a load; a blown fuse or a shorted triac read 0 too (7.2.3)."""
        return self.load and self.fuse_ok and not self.triac_shorted


class M3ioTwin:
    """One module: its switches, inputs, temperatures and stored data."""

    def __init__(self, variant: Variant, sw1: int, serial: int = 33852, name: str = "m3io", firmware: int = FIRMWARE,
                 store_s: float = STORE_S):
        self.name = name
        self.variant = variant
        self.sw1 = sw1
        self.ids = codec.derive_ids(sw1)
        self.serial = serial
        self.product = {Variant.HM: 0x3000, Variant.KM: 0x3009, Variant.HMR: 0x300A}[variant]
        self.version = firmware  # the SW version word (area 2 index 3): 0x1201 = 18.1
        self.store_s = float(store_s)  # strict mode: a slow EEPROM (7.2.4.2.4)
        self.inputs = {f"E{i}": False for i in range(1, 7)}
        self.temps_tenths = [215 + 10 * i for i in range(6)]  # Pt100 readings, 0.1 C
        self.ssr = {i: SsrTwin() for i in range(1, 7)}
        self.led = False
        self.cfg = 0
        self.customer: dict[int, bytes] = {}
        self.last_digout: float | None = None  # None: no master telegram yet (silent)
        self.powered = True
        self.storing_until = 0.0
        self.store_fails = False  # fault injection: the next customer-data write does not stick
        self.resets = 0

    def wake(self) -> None:
        """Called before a control changes the module (the simulated bus steps it at once: M3ioSim)."""

    # -- controls of the simulated plant ----------------------------------------------------
    def toggle_input(self, name: str) -> None:
        self.wake()
        self.inputs[name] = not self.inputs[name]

    def set_temperature(self, channel: int, celsius: float) -> None:
        self.wake()
        self.temps_tenths[channel - 1] = round(celsius * 10)

    def power_cycle(self) -> None:
        """Cut the 24 V: blown fuses are forgotten by the module, cfg is lost, silence until the master talks."""
        self.wake()
        self.cfg = 0
        self.last_digout = None
        self.led = False
        for s in self.ssr.values():
            s.on = s.commanded = s.si_blown = False
        self.resets += 1

    def repair(self, channel: int) -> None:
        """Fuse replaced, triac sound: the module still reports Si = 0 until its 24 V are cut (7.2.3)."""
        self.wake()
        ssr = self.ssr[channel]
        ssr.fuse_ok = ssr.triac_ok = True
        ssr.triac_shorted = False

    def _ssr_action(self, name: str, label: str, attribute: str, value: bool, danger: bool = False) -> SimAction:
        def run(channel: int) -> None:
            self.wake()
            setattr(self.ssr[channel], attribute, value)

        return SimAction(name, label, run, params=(SimParam(NP_("simulation", "channel"), "SSR", 1, 1, 6),),
                         icon="warning" if danger else "")

    def controls(self) -> SimControls:
        """What an engineer may do to this module in simulation (shown by pages/simcontrols.py)."""
        toggle = NP_("simulation", "toggle E{0}")  # the input's number as {0}, as the catalog words it
        actions = [SimAction(toggle.format(i), f"E{i}", lambda i=i: self.toggle_input(f"E{i}"), testid=f"toggle-e{i}")
                   for i in range(1, 7)]
        if self.variant is not Variant.KM:
            channel = NP_("simulation", "channel")
            actions += [
                self._ssr_action(NP_("simulation", "remove load"), "Remove load", "load", False),
                self._ssr_action(NP_("simulation", "connect load"), "Connect load", "load", True),
                self._ssr_action(NP_("simulation", "blow fuse"), "Blow fuse", "fuse_ok", False, danger=True),
                self._ssr_action(NP_("simulation", "break triac"), "Break triac", "triac_ok", False, danger=True),
                self._ssr_action(NP_("simulation", "short triac"), "Short triac", "triac_shorted", True, danger=True),
                SimAction(NP_("simulation", "repair"), "Repair", self.repair, params=(SimParam(channel, "SSR", 1, 1, 6),)),
                SimAction(NP_("simulation", "set temperature"), "Set",
                          lambda channel, tenths: self.set_temperature(channel, tenths / 10),
                          params=(SimParam(channel, "Pt100 input", 1, 1, 6),
                                  SimParam(NP_("simulation", "tenths"), "0.1 °C", 250, -500, 2047))),
            ]
        actions.append(SimAction(NP_("simulation", "cut 24 V"), "Cut 24 V (reset)", self.power_cycle, icon="power_off",
                                 testid="power-cycle"))
        note = "Toggle the inputs E1-E6" + ("" if self.variant is Variant.KM else
                                           "; an SSR's faults by its number. The module reports a blown fuse until "
                                           "its 24 V are cut, even after repair.")
        return SimControls("Simulated module (demo)", tuple(actions), note=note)

    @property
    def watchdog_alive(self) -> bool:
        return self.last_digout is not None and time.monotonic() - self.last_digout <= codec.WATCHDOG_S

    # -- protocol --------------------------------------------------------------------------
    def on_dig_out(self, data: bytes) -> None:
        outputs = codec.decode_dig_out(self.variant, data)
        self.last_digout = time.monotonic()
        self.led = outputs.get("LED", False)
        if self.variant is Variant.HM:
            for i in range(1, 7):
                self.ssr[i].commanded = outputs[f"SSR{i}"]
        elif self.variant is Variant.HMR:
            for i in (1, 2, 3):
                self.ssr[i].commanded = outputs["SSR1-3"]
            for i in (4, 5, 6):
                self.ssr[i].commanded = outputs[f"SSR{i}"]
        self.apply()

    def load_fault(self) -> bool:
        """HMR three-phase output: without P2 all three phases must report a load, with P2 exactly two (4.3)."""
        loaded = sum(self.ssr[i].last for i in (1, 2, 3))
        return loaded != (2 if self.cfg & codec.P2 else 3)

    def apply(self) -> None:
        """Switch only when all is well (7.2.3); HMR: a fault on SSR1-3 switches all three off (4.3)."""
        alive = self.watchdog_alive and self.powered
        for s in self.ssr.values():
            if self.powered and not s.fuse_ok and s.load:
                s.si_blown = True  # found blown: the module keeps Si = 0 until the 24 V are cut
            s.on = alive and s.commanded and not s.si_blown
        if self.variant is Variant.HMR and (
            any(self.ssr[i].si_blown or not self.ssr[i].triac_ok for i in (1, 2, 3)) or self.load_fault()
        ):
            for i in (1, 2, 3):
                self.ssr[i].on = False
        if self.variant is Variant.KM:
            for s in self.ssr.values():
                s.on = False

    def word(self, channel: int) -> codec.TempWord:
        """Temperature word of a channel with the status of its SSR."""
        s = self.ssr[channel]
        sensor = 1 if self.variant is Variant.HMR and channel <= 3 else channel  # HMR: t1-t3 carry TEMP1
        triac = s.triac_ok if s.commanded else True  # conduction is watched while switched on
        return codec.TempWord.make(self.temps_tenths[sensor - 1], load=s.last, triac=triac, fuse=not s.si_blown, addressed=self.ids.addressed)

    def temp_frames(self) -> list[tuple[int, bytes]]:
        words = [self.word(i) for i in range(1, 7)]
        return [(self.ids.temp14, codec.encode_temps(words[:4])), (self.ids.temp56, codec.encode_temps(words[4:]))]

    def dig_in(self) -> bytes:
        return codec.encode_dig_in(self.inputs)

    @property
    def knows_p2(self) -> bool:
        return self.version >= P2_FIRMWARE

    def _take_cfg(self, cfg: int) -> None:
        self.cfg = cfg if self.knows_p2 else cfg & ~codec.P2  # before 17.0 the bit means nothing
        self.apply()

    def on_sync(self, data: bytes) -> bytes | None:
        """SYNC: cfg byte (length 1) or addressed request (length >= 2, addressed mode). Returns MData."""
        if len(data) <= 1:
            if data:
                self._take_cfg(data[0])
            return None
        if not self.ids.addressed:
            return None
        area, index, payload = data[0], data[1], bytes(data[2:8])
        now = time.monotonic()
        if area == codec.AREA_WRITE_CONFIG and index == codec.CONFIG_DYNAMIC:
            if not self.knows_p2:
                return None  # an undefined address for this firmware: ignored (7.2.4.2)
            self._take_cfg(payload[0] if payload else self.cfg)
            return codec.MData(area, index, bytes([self.cfg])).encode()
        if area == codec.AREA_READ_CONFIG:
            values = {
                codec.CONFIG_SERIAL: codec.encode_serial(self.serial),
                codec.CONFIG_PRODUCT: codec.encode_u16(self.product),
                codec.CONFIG_VERSION: codec.encode_u16(self.version),
                codec.CONFIG_DYNAMIC: bytes([self.cfg]),
            }
            return codec.MData(area, index, values[index]).encode() if index in values else None
        if area == codec.AREA_READ_CUSTOMER and index in codec.CUSTOMER_RECORDS:
            return codec.MData(area, index, self.customer.get(index, b"\xff" * 6)).encode()
        if area == codec.AREA_WRITE_CUSTOMER and index in codec.CUSTOMER_RECORDS:
            record = codec.pad6(payload)
            if self.store_fails:
                self.store_fails = False
                record = bytes(b ^ 0x01 for b in record)  # a failed write: what is stored differs
            self.customer[index] = record
            self.storing_until = now + self.store_s  # deaf while storing; answers when done
            return codec.MData(area, index, record).encode()
        if area == codec.AREA_LOAD_DATA and 1 <= index <= 6:
            return codec.MData(area, index, self.word(index).raw.to_bytes(2, "little") + b"\x00\x00\x00\x00").encode()
        return None  # undefined addresses are ignored


class M3ioSim:
    """All simulated M3IO modules of one CAN bus."""

    def __init__(self, bus, devices, open_can):
        self.bus_config = bus
        self.bitrate = bus.options.get("bitrate", 500_000)
        self.twins: dict[str, M3ioTwin] = {}
        options = {k: v for k, v in bus.options.items() if k != "simulate"}
        self.can = open_can(f"{bus.name} (simulated M3IO)", options)
        for dev in devices:
            twin = M3ioTwin(Variant(dev.options["variant"]), dev.options["sw1"], dev.options.get("serial", 33852), dev.name,
                            firmware=dev.options.get("firmware", FIRMWARE), store_s=dev.options.get("store_s", STORE_S))
            self.twins[dev.name] = twin
            self.can.subscribe(False, twin.ids.dig_out, lambda msg, t=twin: self.on_dig_out(t, msg))
            self.can.subscribe(False, twin.ids.sync, lambda msg, t=twin: self.on_sync(t, msg))
        self._task: asyncio.Task | None = None
        self._inputs_sent: dict[str, tuple[bytes, float]] = {}
        self._next_temp: dict[str, float] = {}
        # steps every TICK_S while something falls due, else rests until it does (or a telegram comes)
        # (nothing to catch up when woken: no physics; the watchdog is fed by the DigOut that wakes it)
        self.ticker = simserver.Ticker(self._step, TICK_S, self._rest, catch_up=lambda dt, now: None)
        for twin in self.twins.values():
            twin.wake = self.ticker.wake

    def _on_bus(self, twin: M3ioTwin) -> bool:
        return twin.powered and twin.ids.bitrate == self.bitrate and time.monotonic() >= twin.storing_until

    def on_dig_out(self, twin: M3ioTwin, msg) -> None:
        if not self._on_bus(twin):
            return
        self.ticker.wake()  # outputs commanded: stepped up to now, then on time for the watchdog and temperatures
        try:
            twin.on_dig_out(bytes(msg.data))
        except codec.CodecError:
            return
        self._send_inputs(twin, force=True)  # DigIn answers every DigOut (since V16.0)

    def on_sync(self, twin: M3ioTwin, msg) -> None:
        if not self._on_bus(twin):
            return
        answer = twin.on_sync(bytes(msg.data))
        if answer is not None and twin.ids.mdata is not None:
            delay = max(0.0, twin.storing_until - time.monotonic())
            if delay:  # after storing a record: the answer comes when the module is done
                asyncio.get_running_loop().call_later(delay, self.can.send, twin.ids.mdata, answer)
            else:
                self.can.send(twin.ids.mdata, answer)
        if len(msg.data) <= 1:
            self._send_inputs(twin, force=True)

    def _send_inputs(self, twin: M3ioTwin, force: bool = False) -> None:
        data = twin.dig_in()
        last = self._inputs_sent.get(twin.name)
        now = time.monotonic()
        if not force:
            if twin.last_digout is None or (last and last[0] == data) or (last and now - last[1] < codec.DIGIN_MIN_INTERVAL_S):
                return
        self._inputs_sent[twin.name] = (data, now)
        self.can.send(twin.ids.dig_in, data)

    async def start(self) -> None:
        await self.can.start()
        self.ticker.start(f"sim {self.bus_config.name} m3io")
        self._task = self.ticker.task

    def _step(self, dt: float, now: float) -> None:
        for name, twin in self.twins.items():
            twin.apply()  # the watchdog switches outputs off after 2 s without DigOut
            if not self._on_bus(twin) or twin.last_digout is None:
                continue
            self._send_inputs(twin)  # on change, not more often than every 10 ms
            if twin.variant is not Variant.KM and twin.watchdog_alive and now >= self._next_temp.get(name, 0):
                self._next_temp[name] = now + codec.TEMP_PERIOD_S
                for can_id, data in twin.temp_frames():
                    self.can.send(can_id, data)

    def _rest(self, now: float) -> float:
        """How long :meth:`_step` has nothing to do (simserver.Ticker): until the next temperature frames or
        watchdog expiry of a module that gets DigOut, or at once while an input change waits to be sent."""
        rest = math.inf
        for name, twin in self.twins.items():
            if twin.last_digout is None:
                continue
            if now < twin.storing_until:
                rest = min(rest, twin.storing_until - now)
            elif self._on_bus(twin) and twin.dig_in() != self._inputs_sent.get(name, (None,))[0]:
                return 0.0
            if twin.watchdog_alive:
                rest = min(rest, twin.last_digout + codec.WATCHDOG_S + TICK_S - now)  # as the ticks found it: one late
                if twin.variant is not Variant.KM:
                    rest = min(rest, self._next_temp.get(name, 0) - now)
        return max(0.0, rest) + 0.001

    async def stop(self) -> None:
        self.ticker.stop()
        self._task = None
        await self.can.stop()
