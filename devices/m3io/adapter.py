"""A CAN-M3IO module on a shared CAN bus: watchdog keep-alive, outputs, inputs, temperatures,
SSR status evaluation, SYNC cfg and addressed data.

The module is a slave that waits for a master's DigOut and keeps its outputs on only while
DigOut frames keep coming (7, 7.1). This tool is that master only while an engineer controls
the module (:meth:`M3ioAdapter.take_control`): it listens first and refuses while another node
(a PLC) sends DigOut, and stops sending as soon as one appears. Outputs belong to the page
session that switched them on: :meth:`M3ioAdapter.holders` names those sessions for the worker's
dead-man rule, :meth:`M3ioAdapter.session_lost` switches a session's outputs off at once, and the
DigOut keep-alive runs on python-can's cyclic task under a lease (devices/lease.py): a program
that stalls sends the outputs-off form by itself.

Those rules live in :mod:`devices.m3io.control` (sans-I/O, in virtual time); this adapter feeds it the
events (operators, pages, frames, time) and carries its actions out on the bus.
"""

from __future__ import annotations

import asyncio
import time
from dataclasses import dataclass

from devices import errors
from devices.decoding import decoded
from devices.lease import Lease
from devices.live import DeviceState, session_tag
from devices.message import Message, N_, joined, message_of
from devices.control import Decision, Report
from devices.m3io import codec
from devices.m3io.codec import Variant
from devices.m3io.params import P2_OPTION, PARAMS
from devices.m3io.settings import ModuleSettings
from devices.m3io.control import (ALL_OFF, FOREIGN_MASTER, FOREIGN_WINDOW_S, IDLE_DIGOUT_PERIOD_S,  # noqa: F401 (names of this module)
                                  LISTEN_S, MDATA_TIMEOUT_S, RELEASED, TEMP_SLACK_S, DigOut, EndKeepAlive, KeepAlive,
                                  LeaseChange, M3ioControl, stop_form)
from devices.transport import CanTransport

OFFLINE_AFTER_S = 2.5
VERIFY_RETRY_S = 2.0  # product code not answered: ask again after this long


# -- what the adapter publishes besides the frames' points (DigIn E1-E6, TEMPx, SSRx Last/Si/Triac, the outputs) --
P_ADDRESSING = "Addressing"  # Addressing record: SW1, mode, bit rates, the module's CAN IDs (section 5.8)
P_VARIANT = "Variant"  # the plant file's variant (KM, HM, HMR)
P_VARIANT_CHECK = "Variant check"  # ok / mismatch / unchecked / not possible; text says why; raw: may switch on
P_BITRATE_CHECK = "Bit rate check"
P_WATCHDOG = "Watchdog"  # True while this tool serves it (DigOut); text in words
P_IDLE_SERVED = "Served with every output off"  # master = "always" and nobody in control
P_OTHER_MASTER = "Other master"  # OtherMaster record: another node's DigOut, and whether it is active (2 s)
P_CONTROLLED_BY = "Controlled by"  # the controlling engineer's user name (the tile's line)
P_CONTROL = "Control"  # Control record (user, since, session tag) or None
P_OWNERS = "Output owners"  # OutputOwner records: which session switched each output on
P_OUTPUTS_ON = "Outputs on"  # names of the outputs on
P_FAULTS = "Faults"  # the faults in words
P_P2 = "P2"  # HMR: two-phase load (Sync cfg bit 7)
P_P2_CHECK = "P2 check"  # addressed mode: the cfg the module reports against the P2 this tool sends
P_LOAD_CHECK = "SSR1-3 load check"
P_IDENTITY = "Identity"  # Identity record (addressed mode, read on demand)
P_SERIAL = "Serial number"
P_PRODUCT_CODE = "Product code"
P_PRODUCT = "Product"
P_SOFTWARE = "Software version"
P_CONFIGURATION = "Configuration"
OUTPUT_NAMES = ("LED", "SSR1-3", *(f"SSR{i}" for i in range(1, 7)))


def temp_channels(variant: Variant) -> tuple[int, ...]:
    """The Pt100 inputs a variant reports (TEMPx points): KM none, HMR 1, 4, 5, 6 (t1-t3 carry TEMP1), HM 1-6."""
    if variant is Variant.KM:
        return ()
    return (1, 4, 5, 6) if variant is Variant.HMR else (1, 2, 3, 4, 5, 6)


def ssr_groups(variant: Variant) -> tuple[tuple[str, tuple[int, ...]], ...]:
    """Each switchable SSR output with the channels it drives (HMR: SSR1-3 one three-phase output); KM none."""
    if variant is Variant.KM:
        return ()
    if variant is Variant.HMR:
        return (("SSR1-3", (1, 2, 3)), *((f"SSR{i}", (i,)) for i in (4, 5, 6)))
    return tuple((f"SSR{i}", (i,)) for i in range(1, 7))


def history_points(variant: Variant) -> tuple[str, ...]:
    """The chart's quantities, by point name: the temperatures."""
    return tuple(f"TEMP{c}" for c in temp_channels(variant))


@dataclass(frozen=True, slots=True)
class Addressing:
    """What SW1 sets (section 5.8): the mode, the bit rate and the module's CAN IDs; the bus's bit rate."""

    sw1: int
    addressed: bool
    bitrate: int
    bus_bitrate: int | None
    dig_out: int
    ids: tuple[tuple[str, int], ...]  # (frame name, CAN ID)


@dataclass(frozen=True, slots=True)
class Control:
    user: str
    since: float
    session: str  # devices.live.session_tag of the controlling page


@dataclass(frozen=True, slots=True)
class OutputOwner:
    output: str
    session: str  # session tag of the page that switched it on


@dataclass(frozen=True, slots=True)
class OtherMaster:
    """DigOut frames from another node (a PLC): how many, the last one, and whether one was heard within 2 s."""

    active: bool
    frames: int = 0
    time: float | None = None
    data: str = ""


@dataclass(frozen=True, slots=True)
class Identity:
    """Addressed mode, area 2 (7.2.4.2.2): serial, product, software version (codec.VERSION_ASSUMPTION), dynamic cfg."""

    serial: str
    product_code: int
    product: str
    version: str
    version_raw: int
    config: int


class CommandError(errors.CommandError):
    """A command that did not take effect; the message says what to do."""


class ControlBusy(CommandError, errors.ControlBusy):
    """Another session controls the module."""


class ForeignMaster(CommandError):
    """Another node of the bus serves the module (sends DigOut)."""


class M3ioAdapter(ModuleSettings):
    params = PARAMS
    transport = "can"
    error_type = CommandError  # what the settings (devices/m3io/settings.py) raise

    def __init__(self, config, state: DeviceState, bus: CanTransport):
        self.config = config
        self.state = state
        self.bus = bus
        self.variant = Variant(config.options["variant"])
        self.sw1 = config.options["sw1"]
        self.ids = codec.derive_ids(self.sw1)
        # the safety rules (devices/m3io/control.py): who controls the module, the outputs and their owners, the
        # keep-alive and its lease, another master; plant file `master = "always"`: this tool is the module's only
        # master (a bench without a PLC) and serves the watchdog with every output off while nobody controls it
        self.core = M3ioControl(self.variant, self.ids.dig_out, config.options.get("master", "on-control") == "always")
        self.product_code: int | None = None
        self.variant_check = codec.check_variant(self.variant, self.ids.addressed, None)
        self._verify_after = 0.0
        self.two_phase = bool(config.options.get(P2_OPTION, False))  # the plant file keeps P2: the module forgets it
        self._p2_off_unsent = False  # P2 switched off while this tool did not serve the module: cfg 0 still to send
        self.channels = {i: codec.ChannelMonitor() for i in range(1, 7)}
        self.inputs: dict[str, bool] | None = None
        self.temps: dict[int, codec.TempWord] = {}
        self.last_answer: float | None = None
        self.last_temps: float | None = None
        self._other = OtherMaster(False)
        self.identity: Identity | None = None
        self._p2_checked = True  # addressed HMR: the module's cfg was read back since P2 was last sent
        self._mdata: dict[tuple[int, int], asyncio.Future] = {}
        self._gone_since: float | None = None  # last answer before a silence
        self._lock = asyncio.Lock()
        state.stale_after = 1.5
        self._init_settings()
        bus_rate = self.bus_bitrate
        state.fact(P_ADDRESSING, Addressing(self.sw1, self.ids.addressed, self.ids.bitrate, bus_rate, self.ids.dig_out,
                                            tuple(self.ids.by_name().items())),
                   text=f"SW1 0x{self.sw1:02X}: " + ("addressed mode, " if self.ids.addressed else "")
                   + f"{self.ids.bitrate // 1000} kbit/s")
        state.fact(P_VARIANT, self.variant.value)
        if self.ids.addressed:  # read on demand: "not read" until then
            state.fact(P_IDENTITY, None, text=Message(N_("not read")))
            for index in range(1, 7):
                state.fact(f"SSR{index} load data", None, text="not read")
        if self.variant is Variant.HMR:
            state.fact(P_P2_CHECK, None, text=Message(N_("read back once this tool serves the module")) if self.ids.addressed
                       else Message(N_("cannot be read back in simple mode (SW1 switch 8 off): sent with every DigOut")))
        if bus_rate != self.ids.bitrate:
            state.event("warning", Message(N_("SW1 0x{sw1:02X} sets {module} kbit/s but bus {bus} runs at {rate} kbit/s"),
                                           sw1=self.sw1, module=self.ids.bitrate // 1000, bus=bus.name, rate=bus_rate // 1000))
        self._publish()
        bus.subscribe(False, self.ids.dig_in, self.on_dig_in)
        if self.variant is not Variant.KM:
            bus.subscribe(False, self.ids.temp14, self.on_temps)
            bus.subscribe(False, self.ids.temp56, self.on_temps)
        if self.ids.mdata is not None:
            bus.subscribe(False, self.ids.mdata, self.on_mdata)
        self.key = f"m3io digout {config.name}"
        self.cfg_key = f"m3io cfg {config.name}"
        self.lease = Lease()  # the sender's: granted, renewed and revoked as the core says (devices/lease.py)
        self.core.variant_checked(self.variant_check.may_switch, self.variant_check.text, time.monotonic())
        self._publish_master()
        bus.subscribe(False, self.ids.dig_out, self.on_foreign_dig_out)

    @property
    def outputs(self) -> dict[str, bool]:
        """Output -> on (the core's)."""
        return self.core.outputs

    @property
    def owners(self) -> dict[str, str]:
        """Output that is on -> page session (NiceGUI client id) that switched it on (the core's)."""
        return self.core.owners

    @property
    def always_master(self) -> bool:
        """Plant file ``master = "always"``: this tool is the module's only master (the core's)."""
        return self.core.always_master

    @property
    def bus_bitrate(self) -> int | None:
        """The bit rate the plant file gives the bus."""
        return self.bus.options.get("bitrate")

    @property
    def bitrate_mismatch(self) -> bool:
        """SW1 sets another bit rate than the bus runs at."""
        return self.bus_bitrate != self.ids.bitrate

    # -- the core's actions carried out -------------------------------------------------------------
    @property
    def controller(self):
        """The session this tool serves the watchdog for (devices.control.Holder: session, user, since, ...), or None."""
        return self.core.holder

    @property
    def served(self) -> bool:
        return self.core.served

    def _do(self, actions, now: float) -> None:
        """Carry the core's actions out on the bus, in order."""
        for action in actions:
            if isinstance(action, KeepAlive):
                # python-can's cyclic task: its clock does not depend on the event loop; without a valid lease
                # (a mains output on and the worker renewing it) only the outputs-off form leaves
                leased = {"lease": self.lease, "stop_form": stop_form, "on_lapse": self._lapsed} if action.leased else {}
                self.bus.start_periodic(self.key, action.period_s, self.ids.dig_out, action.data, False, **leased)
                self._start_cfg()
            elif isinstance(action, DigOut):
                self.bus.modify_periodic(self.key, action.data, send_now=True)
            elif isinstance(action, EndKeepAlive):
                self.bus.stop_cyclic(self.key)
                self.bus.stop_cyclic(self.cfg_key)
            elif isinstance(action, LeaseChange):
                if action.what == "grant":
                    self.lease.grant(now)
                elif action.what == "revoke":
                    self.lease.revoke()
                elif not (self.lease.valid(now) and self.lease.renew(action.at if action.at is not None else now)):
                    self._do(self.core.sender_lapsed(now), now)  # the sender found it lapsed first: the core hears of it
            elif isinstance(action, Report):
                self.state.event(action.level, action.text)

    def _decided(self, decision: Decision, now: float, error: type[Exception] | None = None) -> None:
        """Carry out a granted decision, or raise the refusal as ``error`` (ControlBusy when another holds control)."""
        if not decision.ok:
            raise (ControlBusy if decision.busy else error or CommandError)(decision.refused)
        self._do(decision.actions, now)
        self._publish()

    def _start_cfg(self) -> None:
        """P2 is not stored (7.2.4): while set, the Sync cfg goes out with the DigOut period, so a reset cannot lose it."""
        cfg = codec.cfg_with_dig_out(self.two_phase)
        self._p2_checked = False  # addressed mode: read back at the next poll
        if cfg is not None and self.served:
            self.bus.send(self.ids.sync, cfg, False)
            self.bus.start_periodic(self.cfg_key, self._dig_out_period(), self.ids.sync, cfg, False)
        else:
            self.bus.stop_cyclic(self.cfg_key)
            if self._p2_off_unsent and self.served:  # P2 was switched off while not served: the module may still hold it
                self.bus.send(self.ids.sync, codec.encode_sync_cfg(False), False)
        self._p2_off_unsent = self._p2_off_unsent and not self.served

    def _dig_out_period(self) -> float:
        """DigOut (and Sync cfg) every 100 ms while an engineer controls the module, more slowly while it is only
        served with every output off (:data:`IDLE_DIGOUT_PERIOD_S`)."""
        return codec.DIGOUT_PERIOD_S if self.controller is not None else IDLE_DIGOUT_PERIOD_S

    def on_foreign_dig_out(self, msg) -> None:
        """A DigOut from another node: a PLC serves the module. Never fight it."""
        if not msg.is_rx:  # our own frame, handed back by the interface
            return
        now = time.monotonic()
        self._other = OtherMaster(True, self._other.frames + 1, time.time(), bytes(msg.data).hex(" "))
        self._do(self.core.foreign_dig_out(now), now)
        self._publish()

    def foreign_master(self, now: float | None = None) -> bool:
        """Was another master heard within the last 2 s (its DigOut, or the module answering while this tool did not
        serve it nor ask it anything)?"""
        return self.core.foreign_master(time.monotonic() if now is None else now)

    async def take_control(self, session: str, user: str) -> None:
        """Listen for another master first; then serve the watchdog: DigOut every 100 ms, outputs off."""
        holder = self.controller
        if holder is not None and holder.session == session:
            return
        if holder is not None and holder.disconnected is None:
            raise ControlBusy(f"{holder.user} controls the module since {time.strftime('%H:%M:%S', time.localtime(holder.since))}")
        if not self.bus.state.connected:
            raise CommandError(f"CAN bus {self.bus.name} is not open: {self.bus.state.last_error or 'not connected'}")
        # (re)opened since: listen from now on; the loop may wake a timer a little early, so wait until it has passed
        for _ in range(5):  # (a bus that opens again meanwhile restarts the window; the core refuses after that)
            left = self.core.listen_left(time.monotonic(), self.bus.state.reconnects)
            if left <= 0:
                break
            await asyncio.sleep(left + 0.005)
        now = time.monotonic()
        decision = self.core.take(session, user, now, time.time(), self.bus.state.reconnects)
        if not decision.ok and self.controller is not None and self.controller is not holder:  # taken while listening
            if self.controller.session == session:
                return
            raise ControlBusy(f"{self.controller.user} took control meanwhile")
        self._decided(decision, now, ForeignMaster if self.core.foreign_master(now) else CommandError)

    def release_control(self, session: str, reason: str = RELEASED) -> bool:
        if self.controller is None or (session and self.controller.session != session):
            return False
        now = time.monotonic()
        self._do(self.core.release(session, now, reason), now)
        self._publish()
        return True

    def renew_leases(self, alive) -> None:
        """The worker's supervisor, every 50 ms: the session that switched the outputs on is alive (``alive``: a set of
        sessions, or a mapping of each to its page's last beat on the monotonic clock, from which the lease counts)."""
        now = time.monotonic()
        actions = self.core.beat(alive, now)
        if actions:
            self._do(actions, now)
            if any(not isinstance(a, LeaseChange) for a in actions):
                self._publish()

    def _lapsed(self, lapsed_at: float) -> None:
        """The lease ran out (this program stalled): the keep-alive has sent every output off by itself since."""
        if self.lease.lapsed_at != lapsed_at:
            return
        now = time.monotonic()
        self._do(self.core.sender_lapsed(now), now)
        self._publish()

    async def poll(self) -> None:
        """Serve the watchdog idle where the plant file says so; watch for silence; check the variant."""
        self._publish_master()  # another master heard within 2 s: ages out here
        mono = time.monotonic()
        actions = self.core.tick(mono) + self.core.serve_idle(mono, self.bus.state.connected, self.bus.state.reconnects)
        if actions:
            self._do(actions, mono)
            self._publish()
        now = time.time()
        if self.last_answer is None or now - self.last_answer > OFFLINE_AFTER_S:
            if self.last_answer is not None and self._gone_since is None:
                self._gone_since = self.last_answer
                if self.state.online is not False:
                    if self.controller is None and not self.foreign_master():
                        self.state.mark_offline(Message(N_("silent: the module answers only while a master serves its 2 s "
                                                           "watchdog (7.1); take control to serve it")))
                    else:
                        self.state.mark_offline(Message(N_("no DigIn/temperatures for {seconds} s: check 24 V, CAN wiring, "
                                                           "SW1 0x{sw1:02X}"), seconds=OFFLINE_AFTER_S, sw1=self.sw1))
            return
        if self._gone_since is not None:
            self.state.event("info", Message(N_("the module answers again after {seconds:.1f} s of silence"),
                                             seconds=self.last_answer - self._gone_since))
            self._gone_since = None
            if self.ids.addressed:
                self._set_product(None)  # it may have been exchanged meanwhile: check its variant again
                self._p2_checked = False  # and it lost its cfg (7.2.4): check that P2 is in force again
                self._settings_read = False  # and its records may be another module's: read them again
        if self.ids.addressed and self.product_code is None and now >= self._verify_after:
            await self._verify_variant()
        elif (self.variant is Variant.HMR and self.ids.addressed and self.served and not self._p2_checked
              and now >= self._verify_after):
            await self._verify_p2()
        if self.ids.addressed and self.product_code is not None:
            await self._read_settings_once()

    async def _verify_p2(self) -> None:
        """Addressed mode: read the dynamic configuration (area 2, index 15) and compare its bit 7 with the P2
        this tool sends with every DigOut (7.2.4); a mismatch is an event and the page's P2 line."""
        self._p2_checked = True
        try:
            answer = await self._request(codec.AREA_READ_CONFIG, codec.CONFIG_DYNAMIC)
        except CommandError as exc:
            self._p2_checked = False
            self._verify_after = time.time() + VERIFY_RETRY_S
            self.state.fact(P_P2_CHECK, "not read", text=Message(N_("P2 not verified: {error}"), error=message_of(exc)))
            return
        self._check_p2(answer.payload[0])

    def _check_p2(self, config: int) -> None:
        """The module's dynamic configuration against the P2 this tool sends (HMR only)."""
        if self.variant is not Variant.HMR:
            return
        reported = bool(config & codec.P2)
        if reported == self.two_phase:
            self.state.fact(P_P2_CHECK, "verified", raw=config,
                            text=Message(N_("verified: the module reports cfg {cfg} (P2 {p2})"), cfg=f"0x{config:02X}",
                                         p2=int(reported)))
            return
        fields = {"reported": int(reported), "cfg": f"0x{config:02X}", "p2": int(self.two_phase)}
        text = (Message(N_("the module reports P2 {reported} (cfg {cfg}), this tool sets P2 {p2}"), **fields) if self.served
                else Message(N_("the module reports P2 {reported} (cfg {cfg}), this tool sets P2 {p2}: sent once this tool "
                                "serves the module"), **fields))
        old = self.state.points.get(P_P2_CHECK)
        self.state.fact(P_P2_CHECK, "mismatch", raw=config, text=text)
        if self.served and (old is None or old.value != "mismatch"):
            self.state.event("warning", Message("P2 {text}", text=text))
            self._p2_checked = False  # sent again with the next DigOut period: read back after a while
            self._verify_after = time.time() + VERIFY_RETRY_S

    async def _verify_variant(self) -> None:
        try:
            answer = await self._request(codec.AREA_READ_CONFIG, codec.CONFIG_PRODUCT)
        except CommandError as exc:
            self._verify_after = time.time() + VERIFY_RETRY_S
            self.state.error(Message(N_("product code not read: {error}"), error=message_of(exc)), log=False)
            return
        self._set_product(codec.decode_u16(answer.payload))

    def _set_product(self, code: int | None) -> None:
        """Compare the module's product code with the plant file's variant (7.2.4.2.2)."""
        self.product_code = code
        check = codec.check_variant(self.variant, self.ids.addressed, code)
        changed = check != self.variant_check
        self.variant_check = check
        now = time.monotonic()
        self._do(self.core.variant_checked(check.may_switch, check.text, now), now)
        if check.state == "mismatch" and changed:
            self.state.event("error", check.text)
        elif check.state == "ok" and changed:
            self.state.event("info", check.text)
        self._publish()

    # -- frames ------------------------------------------------------------------------------
    def _seen(self, kind: str, key: tuple[int, int] | None = None) -> None:
        """A frame of the module: it answers although this tool does not serve it nor asked it: another master does."""
        self.last_answer = time.time()
        self.state.mark_seen(self.last_answer)
        self.core.module_frame(kind, time.monotonic(), key)
        if not self._other.active and self.foreign_master():
            self._publish_master()

    def on_dig_in(self, msg) -> None:
        inputs = decoded(self.state, codec.decode_dig_in, bytes(msg.data), "DigIn")
        if inputs is None:
            return
        self.inputs = inputs
        self.state.counters.responses += 1
        self._seen("DigIn")
        raw = bytes(msg.data)[0]
        for name, on in self.inputs.items():
            self.state.publish(name, on, raw=raw, time=self.last_answer)

    def on_temps(self, msg) -> None:
        first = 1 if msg.arbitration_id == self.ids.temp14 else 5
        count = 4 if first == 1 else 2
        words = decoded(self.state, lambda data: codec.decode_temps(data, count), bytes(msg.data), "temperature frame")
        if words is None:
            return
        self.state.counters.responses += 1
        self._seen("Temp")
        self.last_temps = self.last_answer
        for offset, word in enumerate(words):
            channel = first + offset
            self.temps[channel] = word
            monitor = self.channels[channel]
            monitor.update(word, self.channel_on(channel))
            if monitor.cleared:
                self.state.event("info", Message(N_("SSR{n} fuse fault cleared: {reason}"), n=channel, reason=monitor.cleared))
            self._publish_channel(channel, word, self.last_answer)
        self._publish()
        if first == 5 or self.variant is Variant.HMR:
            self.state.record_history(history_points(self.variant), self.last_answer)

    def on_mdata(self, msg) -> None:
        answer = decoded(self.state, codec.MData.decode, bytes(msg.data), "MData")
        if answer is None:
            return
        self._seen("MData", (answer.area, answer.index))
        future = self._mdata.get((answer.area, answer.index))
        if future is not None and not future.done():
            future.set_result(answer)

    def _publish_channel(self, channel: int, word: codec.TempWord, now: float) -> None:
        """Live points of one temperature word: TEMPx (not on HMR t2/t3, which carry TEMP1) and SSRx Last/Si/Triac (7.2.2, 7.2.3)."""
        publish, monitor = self.state.publish, self.channels[channel]
        if channel in temp_channels(self.variant):
            publish(f"TEMP{channel}", word.celsius if word.in_range else None, "°C", raw=word.raw, text=word.text(), time=now)
        publish(f"SSR{channel} Last", word.load, raw=int(word.load), text=monitor.load, time=now)
        publish(f"SSR{channel} Si", monitor.fuse, raw=int(word.fuse), text=f"fuse {monitor.fuse}", time=now)
        publish(f"SSR{channel} Triac", monitor.triac, raw=int(word.triac), text=f"triac {monitor.triac}", time=now)

    def _publish(self) -> None:
        """Facts for tiles and the plant view, and the commanded state as live points."""
        faults = []
        if self.variant_check.state == "mismatch":
            faults.append(Message(N_("variant mismatch: {product} on the bus, {variant} in the plant file"),
                                  product=codec.product_name(self.product_code), variant=self.variant.value))
        for channel, monitor in self.channels.items():
            if monitor.fuse == "blown":
                faults.append(Message(N_("SSR{n} fuse blown"), n=channel))
            if monitor.triac == "defective":
                faults.append(Message(N_("SSR{n} triac defective"), n=channel))
        group = self.group_load_fault()
        if group:
            faults.append(group)
        fact = self.state.fact  # what this tool commands or was told does not age while the module is online
        for name, on in self.outputs.items():
            fact(name, on, text="on" if on else "off")
        fact(P_OUTPUTS_ON, tuple(name for name, on in self.outputs.items() if on),
             text=", ".join(name for name, on in self.outputs.items() if on) or "none")
        fact(P_OWNERS, tuple(OutputOwner(name, session_tag(session)) for name, session in self.owners.items()
                             if self.outputs.get(name)))
        self._publish_master()
        controller = self.controller
        fact(P_CONTROLLED_BY, controller.user if controller else None, text=None if controller else "nobody")
        fact(P_CONTROL, Control(controller.user, controller.since, session_tag(controller.session)) if controller else None,
             text=f"{controller.user} controls the module" if controller else "nobody controls the module")
        fact(P_VARIANT_CHECK, self.variant_check.state, text=self.variant_check.text, raw=self.variant_check.may_switch)
        if self.variant is Variant.HMR:
            fact(P_P2, self.two_phase, text="two-phase load" if self.two_phase else "three-phase load")
        fact(P_FAULTS, tuple(faults), text=joined(faults, "; ") if faults else "none")
        rate, bus_rate = self.ids.bitrate, self.bus_bitrate
        fact(P_BITRATE_CHECK, "mismatch" if self.bitrate_mismatch else "ok",
             text=f"bit rate mismatch: module {rate // 1000} kbit/s, bus {(bus_rate or 0) // 1000} kbit/s"
             if self.bitrate_mismatch else f"{rate // 1000} kbit/s")
        if self.variant is Variant.HMR:
            fact(P_LOAD_CHECK, "fault" if group else "ok", text=group or "ok")

    def _publish_master(self) -> None:
        """The watchdog in words, and whether another master was heard within the last 2 s (it ages out: poll() calls this)."""
        foreign = self.foreign_master()
        if foreign != self._other.active:
            self._other = OtherMaster(foreign, self._other.frames, self._other.time, self._other.data)
        fact = self.state.fact
        fact(P_OTHER_MASTER, self._other, text=f"{FOREIGN_MASTER} heard" if foreign else "none heard")
        every = f"DigOut every {self._dig_out_period() * 1000:.0f} ms"  # the period it is sent at now
        idle = self.served and self.controller is None
        fact(P_IDLE_SERVED, idle)
        if self.served:
            text = f"served: {every}" + (" (every output off: nobody controls the module)" if idle else "")
        elif foreign:
            text = "served by another master (a PLC): this tool only listens"
        else:
            text = "not served: outputs are off in the module; take control to serve it"
        fact(P_WATCHDOG, self.served, text=text)

    def group_load_fault(self) -> Message | None:
        """HMR, SSR1-3 switched on: three phases must report a load, exactly two with P2 (4.3)."""
        if self.variant is not Variant.HMR or not self.outputs["SSR1-3"] or not all(i in self.temps for i in (1, 2, 3)):
            return None
        loaded = sum(self.temps[i].load for i in (1, 2, 3))
        expected = 2 if self.two_phase else 3
        if loaded == expected:
            return None
        if self.two_phase:
            return Message(N_("SSR1-3 load fault: {loaded} of 3 phases report a load, P2 (two-phase load) needs {expected}"),
                           loaded=loaded, expected=expected)
        return Message(N_("SSR1-3 load fault: {loaded} of 3 phases report a load, a three-phase load needs {expected}"),
                       loaded=loaded, expected=expected)

    # -- what the page shows ------------------------------------------------------------------
    def channel_on(self, channel: int) -> bool:
        if self.variant is Variant.HMR and channel <= 3:
            return self.outputs["SSR1-3"]
        return self.outputs.get(f"SSR{channel}", False)

    def describe_frame(self, arbitration_id: int, is_extended: bool, data: bytes) -> str | None:
        return None if is_extended else codec.describe_frame_for(self.ids, self.variant, arbitration_id, data)

    def owns_frame(self, arbitration_id: int, is_extended: bool, data: bytes) -> bool:
        return not is_extended and arbitration_id in self.ids.by_name().values()

    # -- outputs ------------------------------------------------------------------------------
    def set_output(self, session: str, name: str, on: bool) -> None:
        """Switch an output for the page session ``session``, which must control the module and then owns
        the output until it is switched off or the session is lost. Switching off is never refused."""
        now = time.monotonic()
        self._decided(self.core.set_output(session, name, on, now), now)

    def all_off(self, reason: str = ALL_OFF) -> None:
        now = time.monotonic()
        self._do(self.core.all_off(now, reason), now)
        self._publish()

    def all_off_pressed(self) -> None:
        """The page's All off (a stop: never refused)."""
        self.all_off(Message(N_("all off pressed")))

    def holders(self) -> set[str]:
        """The page sessions that keep outputs on through this adapter (for the worker's dead-man rule)."""
        return self.core.holders()

    def session_lost(self, session: str, reason: str) -> None:
        """``session`` is gone or stopped confirming it is alive: its outputs off at once, and its control released."""
        now = time.monotonic()
        actions = self.core.lost(session, reason, now)
        if actions:
            self._do(actions, now)
            self._publish()

    def session_back(self, session: str) -> None:
        """The page of ``session`` confirms it is alive again after its connection dropped: its control is its own again."""
        self._do(self.core.back(session), time.monotonic())

    def session_stop(self, session: str, reason: str) -> None:
        """The page of ``session`` disconnected: its outputs off at once; its control (the watchdog with
        every output off) stays until the page is gone for good (:meth:`session_lost`)."""
        now = time.monotonic()
        actions = self.core.disconnected(session, reason, now)
        if actions:
            self._do(actions, now)
            self._publish()

    # -- SYNC cfg (7.2.4) ----------------------------------------------------------------------
    def set_two_phase(self, on: bool) -> None:
        if self.variant is not Variant.HMR:
            raise CommandError("P2 (two-phase load) exists on the HMR only")
        on = bool(on)
        self._p2_changed(on)
        if self.served:
            self.bus.send(self.ids.sync, codec.encode_sync_cfg(on), False)
        self._p2_off_unsent = not on and not self.served
        self._start_cfg()
        self._publish()
        p2 = Message(N_("P2 on: three-phase output loaded on two phases")) if on else Message(N_("P2 off: three phases"))
        self.state.event("info", p2 if self.served else Message(N_("{p2} (sent once this tool controls the module)"), p2=p2))

    # -- addressed data (7.2.4.2) ---------------------------------------------------------------
    async def _request(self, area: int, index: int, payload: bytes = b"", timeout: float = MDATA_TIMEOUT_S) -> codec.MData:
        if not self.ids.addressed:
            raise CommandError(f"addressed data needs SW1 switch 8 on (SW1 is 0x{self.sw1:02X})")
        async with self._lock:
            future = asyncio.get_running_loop().create_future()
            self._mdata[(area, index)] = future
            self.state.counters.requests += 1
            try:
                self.core.request_sent(area, index, time.monotonic())  # its answer is no sign of another master
                self.bus.send(self.ids.sync, codec.encode_sync_request(area, index, payload), False)
                return await asyncio.wait_for(future, timeout)
            except asyncio.TimeoutError:
                self.state.counters.timeouts += 1
                raise CommandError(f"no MData for area {area} index {index} within {timeout:g} s") from None
            finally:
                self._mdata.pop((area, index), None)

    async def read_identity(self) -> dict:
        serial = await self._request(codec.AREA_READ_CONFIG, codec.CONFIG_SERIAL)
        product = await self._request(codec.AREA_READ_CONFIG, codec.CONFIG_PRODUCT)
        version = await self._request(codec.AREA_READ_CONFIG, codec.CONFIG_VERSION)
        config = await self._request(codec.AREA_READ_CONFIG, codec.CONFIG_DYNAMIC)
        code = codec.decode_u16(product.payload)
        raw_version = codec.decode_u16(version.payload)
        identity = Identity(codec.decode_serial(serial.payload), code, codec.product_name(code),
                            codec.decode_version(raw_version), raw_version, config.payload[0])
        self.identity = identity
        fact = self.state.fact  # read on demand: does not age while online
        fact(P_IDENTITY, identity, text=Message(N_("serial {serial} · product {code} {product} · software {version} (assumed "
                                                   "decoding) · configuration {config}"), serial=str(identity.serial),
                                                code=f"0x{code:04X}", product=identity.product, version=identity.version,
                                                config=f"0x{identity.config:02X}"))
        fact(P_SERIAL, identity.serial, raw=serial.payload.hex(" "))
        fact(P_PRODUCT_CODE, code, raw=code, text=identity.product)
        fact(P_PRODUCT, identity.product, raw=code)
        fact(P_SOFTWARE, identity.version, raw=raw_version,
             text=f"{identity.version} (assumed: {codec.VERSION_ASSUMPTION})")
        fact(P_CONFIGURATION, identity.config, raw=identity.config, text=f"0x{identity.config:02X}")
        self._keep_identity(int.from_bytes(serial.payload[:4], "little"), code, raw_version, identity.config)
        self._set_product(code)
        self._check_p2(identity.config)
        return {"serial": identity.serial, "product_code": code, "product": identity.product, "version": identity.version,
                "config": identity.config}

    async def read_load_data(self) -> dict[int, codec.TempWord]:
        result = {}
        for index in range(1, 7):
            answer = await self._request(codec.AREA_LOAD_DATA, index)
            result[index] = codec.TempWord(codec.decode_u16(answer.payload))
        for index, word in result.items():  # area 5: actual load data of SSR 1-6 (7.2.4.2)
            self.state.publish(f"SSR{index} load data", word.load, raw=word.raw,
                               text=f"{word.text()} load {int(word.load)} triac {int(word.triac)} fuse {int(word.fuse)}",
                               periodic=False)
        return result
