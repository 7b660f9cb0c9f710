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
"""

from __future__ import annotations

import asyncio
import time
from dataclasses import dataclass

from devices.lease import Lease
from devices.live import DeviceState
from devices.m3io import codec
from devices.m3io.codec import Variant
from devices.transport import CanTransport

MDATA_TIMEOUT_S = 0.5
OFFLINE_AFTER_S = 2.5
TEMP_SLACK_S = 0.6  # after the watchdog ran out, a temperature telegram already under way may still come
VERIFY_RETRY_S = 2.0  # product code not answered: ask again after this long
LISTEN_S = 0.6  # listened this long since the bus opened before taking control: longer than the 500 ms temperature period (7.2.2)
FOREIGN_WINDOW_S = codec.WATCHDOG_S  # a master must send DigOut within 2 s (7.1): one heard within this window is active
FOREIGN_MASTER = "a PLC or another master"


class CommandError(Exception):
    """A command that did not take effect; the message says what to do."""


class ControlBusy(CommandError):
    """Another session controls the module."""


class ForeignMaster(CommandError):
    """Another node of the bus serves the module (sends DigOut)."""


@dataclass
class Controller:
    session: str
    user: str
    since: float
    disconnected: float | None = None  # monotonic time its page's connection dropped (it may reconnect)


def stop_form(data: bytes) -> bytes:
    """DigOut with every SSR off (bits 1-6 cleared); the LED (bit 0) is no mains output and stays."""
    return bytes([data[0] & 0x01]) + bytes(data[1:]) if data else bytes(data)


class M3ioAdapter:
    params = None
    transport = "can"

    def __init__(self, config, state: DeviceState, bus: CanTransport):
        self.config = config
        self.state = state
        self.bus = bus
        self.variant = Variant(config.options["variant"])
        self.sw1 = config.options["sw1"]
        self.ids = codec.derive_ids(self.sw1)
        self.outputs = {name: False for name in codec.OUTPUT_BITS[self.variant]}
        self.owners: dict[str, str] = {}  # output that is on -> page session (NiceGUI client id) that switched it on
        self.controller: Controller | None = None  # the engineer whose session this tool serves the watchdog for
        self.product_code: int | None = None
        self.variant_check = codec.check_variant(self.variant, self.ids.addressed, None)
        self._verify_after = 0.0
        self.two_phase = False
        self.channels = {i: codec.ChannelMonitor() for i in range(1, 7)}
        self.inputs: dict[str, bool] | None = None
        self.temps: dict[int, codec.TempWord] = {}
        self.last_answer: float | None = None
        self.last_temps: float | None = None
        self.served = False
        self.info: dict = {}
        self._mdata: dict[tuple[int, int], asyncio.Future] = {}
        self._gone_since: float | None = None  # last answer before a silence
        self._lock = asyncio.Lock()
        state.stale_after = 1.5
        bus_rate = bus.options.get("bitrate")
        state.info.update(ids=self.ids, variant=self.variant, sw1=self.sw1,
                          bitrate_mismatch=bus_rate != self.ids.bitrate, bus_bitrate=bus_rate)
        if bus_rate != self.ids.bitrate:
            state.event("warning", f"SW1 0x{self.sw1:02X} sets {self.ids.bitrate // 1000} kbit/s but bus {bus.name} runs at {bus_rate // 1000} kbit/s")
        self._publish()
        bus.subscribe(False, self.ids.dig_in, self.on_dig_in)
        if self.variant is not Variant.KM:
            bus.subscribe(False, self.ids.temp14, self.on_temps)
            bus.subscribe(False, self.ids.temp56, self.on_temps)
        if self.ids.mdata is not None:
            bus.subscribe(False, self.ids.mdata, self.on_mdata)
        self.key = f"m3io digout {config.name}"
        self.cfg_key = f"m3io cfg {config.name}"
        self.lease = Lease()  # renewed by the worker's dead-man supervisor while a mains output is on
        self._listening_since = time.monotonic()  # since when another master's DigOut would have been heard
        self._listening_reconnects = -1
        self._foreign_at: float | None = None  # monotonic time of the last sign of another master
        self._served_until = 0.0  # monotonic: the module may still answer our last DigOut until then
        # plant file `master = "always"`: this tool is the module's only master (a bench without a PLC) and
        # serves the watchdog with every output off while nobody controls it and no other master is heard
        self.always_master = config.options.get("master", "on-control") == "always"
        self._idle_serving = False
        state.info.update(foreign_master=None, controlled_by=None)
        bus.subscribe(False, self.ids.dig_out, self.on_foreign_dig_out)

    # -- keep-alive (section 7.1), only while an engineer controls the module ----------------------
    def _dig_out_data(self) -> bytes:
        sent = self.outputs if self.variant_check.may_switch else {}  # nothing on before the variant matched
        return codec.encode_dig_out(self.variant, sent)

    def _send_now(self) -> None:
        """The new DigOut at once (not only at the next period) and as the keep-alive's contents from now on."""
        if self.controller is None:  # nobody controls the module: this tool sends nothing
            return
        if any(on for name, on in self.outputs.items() if name != "LED"):
            self.lease.grant()  # the controlling session acted just now
        else:
            self.lease.revoke()
        self.bus.modify_periodic(self.key, self._dig_out_data(), send_now=True)

    def _start_cfg(self) -> None:
        """P2 is not stored (7.2.4): while set, the Sync cfg goes out with the DigOut period, so a reset cannot lose it."""
        cfg = codec.cfg_with_dig_out(self.two_phase)
        if cfg is not None and self.controller is not None:
            self.bus.send(self.ids.sync, cfg, False)
            self.bus.start_periodic(self.cfg_key, codec.DIGOUT_PERIOD_S, self.ids.sync, cfg, False)
        else:
            self.bus.stop_cyclic(self.cfg_key)

    def on_foreign_dig_out(self, msg) -> None:
        """A DigOut from another node: a PLC serves the module. Never fight it."""
        if getattr(msg, "is_rx", True) is False:  # our own frame, handed back by the interface
            return
        self._foreign_at = time.monotonic()
        foreign = self.state.info.get("foreign_master") or {"frames": 0}
        self.state.info["foreign_master"] = {"frames": foreign["frames"] + 1, "time": time.time(), "text": bytes(msg.data).hex(" ")}
        if self.controller is not None:
            self._release(f"lost: another master sends DigOut 0x{self.ids.dig_out:03X} ({FOREIGN_MASTER}); "
                          "this tool stopped sending so as not to fight it", level="error")
        elif self._idle_serving:
            self._stop_idle_serving(f"another master sends DigOut 0x{self.ids.dig_out:03X} ({FOREIGN_MASTER}): this tool only listens now")

    def _start_idle_serving(self) -> None:
        """``master = "always"``: the watchdog served with every output off, nobody in control (no lease needed)."""
        self._idle_serving = True
        self.served = True
        self.bus.start_periodic(self.key, codec.DIGOUT_PERIOD_S, self.ids.dig_out, codec.encode_dig_out(self.variant, {}), False)
        self._start_cfg_idle()
        self._publish()
        self.state.event("info", f"serving the watchdog with every output off (master = \"always\" in the plant file): "
                                 f"DigOut 0x{self.ids.dig_out:03X} every {codec.DIGOUT_PERIOD_S * 1000:.0f} ms")

    def _start_cfg_idle(self) -> None:
        cfg = codec.cfg_with_dig_out(self.two_phase)
        if cfg is not None:
            self.bus.start_periodic(self.cfg_key, codec.DIGOUT_PERIOD_S, self.ids.sync, cfg, False)

    def _stop_idle_serving(self, reason: str) -> None:
        self._idle_serving = False
        self.served = False
        self.bus.stop_cyclic(self.key)
        self.bus.stop_cyclic(self.cfg_key)
        self._served_until = time.monotonic() + codec.WATCHDOG_S + TEMP_SLACK_S
        self._publish()
        self.state.event("warning", f"stopped serving the watchdog: {reason}")

    def foreign_master(self, now: float | None = None) -> bool:
        """Was another master heard within the last 2 s (its DigOut, or the module answering while this tool did not serve it)?"""
        now = time.monotonic() if now is None else now
        return self._foreign_at is not None and now - self._foreign_at <= FOREIGN_WINDOW_S

    async def take_control(self, session: str, user: str) -> None:
        """Listen for another master first; then serve the watchdog: DigOut every 100 ms, outputs off."""
        if self.controller is not None and self.controller.session != session and self.controller.disconnected is not None:
            self._release("taken over by another page: the page that held it had disconnected")
        if self.controller is not None and self.controller.session != session:
            raise ControlBusy(f"{self.controller.user} controls the module since "
                              f"{time.strftime('%H:%M:%S', time.localtime(self.controller.since))}")
        if self.controller is not None:
            return
        if not self.bus.state.connected:
            raise CommandError(f"CAN bus {self.bus.name} is not open: {self.bus.state.last_error or 'not connected'}")
        if self._listening_reconnects != self.bus.state.reconnects:  # (re)opened since: listen from now on
            self._listening_reconnects, self._listening_since = self.bus.state.reconnects, time.monotonic()
        heard_for = time.monotonic() - self._listening_since
        if heard_for < LISTEN_S:
            await asyncio.sleep(LISTEN_S - heard_for)
        if self.foreign_master():
            raise ForeignMaster(
                f"another master serves this module ({FOREIGN_MASTER}: DigOut 0x{self.ids.dig_out:03X} or the module's "
                f"answers heard within {FOREIGN_WINDOW_S:g} s): taking control would fight it. Stop that master and try again."
            )
        if self.controller is not None:  # taken while this session listened
            if self.controller.session == session:
                return
            raise ControlBusy(f"{self.controller.user} took control meanwhile")
        for name in self.outputs:
            self.outputs[name] = False
        self.owners.clear()
        self.lease.revoke()
        self._idle_serving = False  # the controlled keep-alive below takes over
        self.controller = Controller(session, user, time.time())
        self.served = True
        # python-can's cyclic task: its clock does not depend on the event loop; without a valid lease
        # (a mains output on and the worker renewing it) only the outputs-off form leaves
        self.bus.start_periodic(self.key, codec.DIGOUT_PERIOD_S, self.ids.dig_out, self._dig_out_data(), False,
                                lease=self.lease, stop_form=stop_form, on_lapse=self._lapsed)
        self._start_cfg()
        self.state.info["controlled_by"] = user
        self._publish()
        self.state.event("info", f"{user} took control (no other master heard): DigOut 0x{self.ids.dig_out:03X} "
                                 f"every {codec.DIGOUT_PERIOD_S * 1000:.0f} ms serves the 2 s watchdog")

    def _release(self, reason: str, level: str = "warning") -> None:
        """Every output off (sent at once), then the keep-alive stops: the module's watchdog runs out in 2 s."""
        user = self.controller.user if self.controller else "nobody"
        on = [name for name, value in self.outputs.items() if value]
        for name in self.outputs:
            self.outputs[name] = False
        self.owners.clear()
        self.lease.revoke()
        if self.controller is not None:
            self.bus.modify_periodic(self.key, self._dig_out_data(), send_now=True)
        self.bus.stop_cyclic(self.key)
        self.bus.stop_cyclic(self.cfg_key)
        self.controller = None
        self.served = False
        self._served_until = time.monotonic() + codec.WATCHDOG_S + TEMP_SLACK_S
        self.state.info["controlled_by"] = None
        self._publish()
        self.state.event(level, f"control {reason} ({user})" + (f": {', '.join(on)} off" if on else "") + "; DigOut stopped")

    def release_control(self, session: str, reason: str = "released") -> bool:
        if self.controller is None or (session and self.controller.session != session):
            return False
        self._release(reason)
        return True

    def renew_leases(self, alive: set[str]) -> None:
        """The worker's supervisor, every 50 ms: the session that switched the outputs on is alive."""
        if self.controller is None or not any(self.owners.get(n) in alive for n, on in self.outputs.items() if on):
            return
        if not self.lease.renew() and self.lease.lapsed_at is not None:
            self._lapsed(self.lease.lapsed_at)

    def _lapsed(self, lapsed_at: float) -> None:
        """The lease ran out (this program stalled): the keep-alive has sent every output off by itself since."""
        if self.lease.lapsed_at != lapsed_at:
            return
        names = [name for name, on in self.outputs.items() if on and name != "LED"]
        if not names:
            return
        renewed = self.lease.renewed_at
        stalled_ms = (time.monotonic() - renewed) * 1000 if renewed is not None else 0.0
        for name in names:
            self.outputs[name] = False
            self.owners.pop(name, None)
        self._send_now()
        self._publish()
        self.state.event("error", f"{', '.join(names)} off: this program stalled ({stalled_ms:.0f} ms without renewing the "
                                  f"outputs' lease, limit {self.lease.valid_s * 1000:.0f} ms) and the DigOut keep-alive "
                                  "switched them off by itself. The browser was not at fault: switch on again")

    async def poll(self) -> None:
        """Serve the watchdog idle where the plant file says so; watch for silence; check the variant."""
        if (self.always_master and self.controller is None and not self._idle_serving and self.bus.state.connected
                and not self.foreign_master()):
            if self._listening_reconnects != self.bus.state.reconnects:
                self._listening_reconnects, self._listening_since = self.bus.state.reconnects, time.monotonic()
            if time.monotonic() - self._listening_since >= LISTEN_S:  # listened first
                self._start_idle_serving()
        now = time.time()
        if self.last_answer is None or now - self.last_answer > OFFLINE_AFTER_S:
            if self.last_answer is not None and self._gone_since is None:
                self._gone_since = self.last_answer
                if self.state.online is not False:
                    if self.controller is None and not self.foreign_master():
                        self.state.mark_offline("silent: the module answers only while a master serves its 2 s watchdog "
                                                "(7.1); take control to serve it")
                    else:
                        self.state.mark_offline(f"no DigIn/temperatures for {OFFLINE_AFTER_S} s: check 24 V, CAN wiring, SW1 0x{self.sw1:02X}")
            return
        if self._gone_since is not None:
            self.state.event("info", f"the module answers again after {self.last_answer - self._gone_since:.1f} s of silence")
            self._gone_since = None
            if self.ids.addressed:
                self._set_product(None)  # it may have been exchanged meanwhile: check its variant again
        if self.ids.addressed and self.product_code is None and now >= self._verify_after:
            await self._verify_variant()

    async def _verify_variant(self) -> None:
        try:
            answer = await self._request(codec.AREA_READ_CONFIG, codec.CONFIG_PRODUCT)
        except CommandError as exc:
            self._verify_after = time.time() + VERIFY_RETRY_S
            self.state.error(f"product code not read: {exc}", log=False)
            return
        self._set_product(codec.decode_u16(answer.payload))

    def _set_product(self, code: int | None) -> None:
        """Compare the module's product code with the plant file's variant (7.2.4.2.2)."""
        self.product_code = code
        check = codec.check_variant(self.variant, self.ids.addressed, code)
        changed = check != self.variant_check
        self.variant_check = check
        if check.state == "mismatch":
            if any(self.outputs.values()):
                self.all_off("the module is not the variant the plant file names")
            if changed:
                self.state.event("error", check.text)
        elif check.state == "ok" and changed:
            self.state.event("info", check.text)
            if any(self.outputs.values()):
                self._send_now()
        self._publish()

    # -- frames ------------------------------------------------------------------------------
    def _seen(self) -> None:
        self.last_answer = time.time()
        self.state.mark_seen(self.last_answer)
        if self.controller is None and not self._idle_serving and time.monotonic() > self._served_until:
            self._foreign_at = time.monotonic()  # the module answers although this tool does not serve it: another master does

    def on_dig_in(self, msg) -> None:
        try:
            self.inputs = codec.decode_dig_in(bytes(msg.data))
        except codec.CodecError as exc:
            self.state.counters.malformed += 1
            self.state.error(f"malformed DigIn: {exc}", log=False)
            return
        self.state.counters.responses += 1
        self._seen()
        raw = bytes(msg.data)[0]
        for name, on in self.inputs.items():
            self.state.publish(name, on, raw=raw, time=self.last_answer)

    def on_temps(self, msg) -> None:
        first = 1 if msg.arbitration_id == self.ids.temp14 else 5
        try:
            words = codec.decode_temps(bytes(msg.data), 4 if first == 1 else 2)
        except codec.CodecError as exc:
            self.state.counters.malformed += 1
            self.state.error(f"malformed temperature frame: {exc}", log=False)
            return
        self.state.counters.responses += 1
        self._seen()
        self.last_temps = self.last_answer
        for offset, word in enumerate(words):
            channel = first + offset
            self.temps[channel] = word
            monitor = self.channels[channel]
            monitor.update(word, self.channel_on(channel))
            if monitor.cleared:
                self.state.event("info", f"SSR{channel} fuse fault cleared: {monitor.cleared}")
            self._publish_channel(channel, word, self.last_answer)
        self._publish()
        if first == 5 or self.variant is Variant.HMR:
            sample = {}
            for channel in self.temp_channels():
                word = self.temps.get(channel)
                sample[self.temp_label(channel)] = word.celsius if word is not None and word.in_range else None
            self.state.add_history(sample)

    def on_mdata(self, msg) -> None:
        try:
            answer = codec.MData.decode(bytes(msg.data))
        except codec.CodecError as exc:
            self.state.counters.malformed += 1
            self.state.error(f"malformed MData: {exc}", log=False)
            return
        self._seen()
        future = self._mdata.get((answer.area, answer.index))
        if future is not None and not future.done():
            future.set_result(answer)

    def _publish_channel(self, channel: int, word: codec.TempWord, now: float) -> None:
        """Live points of one temperature word: TEMPx (not on HMR t2/t3, which carry TEMP1) and SSRx Last/Si/Triac (7.2.2, 7.2.3)."""
        publish, monitor = self.state.publish, self.channels[channel]
        if channel in self.temp_channels():
            publish(f"TEMP{channel}", word.celsius if word.in_range else None, "°C", raw=word.raw, text=word.text(), time=now)
        publish(f"SSR{channel} Last", word.load, raw=int(word.load), text=monitor.load, time=now)
        publish(f"SSR{channel} Si", monitor.fuse, raw=int(word.fuse), text=f"fuse {monitor.fuse}", time=now)
        publish(f"SSR{channel} Triac", monitor.triac, raw=int(word.triac), text=f"triac {monitor.triac}", time=now)

    def _publish(self) -> None:
        """Facts for tiles and the plant view, and the commanded state as live points."""
        faults = []
        if self.variant_check.state == "mismatch":
            faults.append(f"variant mismatch: {codec.product_name(self.product_code)} on the bus, {self.variant.value} in the plant file")
        for channel, monitor in self.channels.items():
            if monitor.fuse == "blown":
                faults.append(f"SSR{channel} fuse blown")
            if monitor.triac == "defective":
                faults.append(f"SSR{channel} triac defective")
        group = self.group_load_fault()
        if group:
            faults.append(group)
        self.state.info["faults"] = faults
        self.state.info["outputs_on"] = [name for name, on in self.outputs.items() if on]
        self.state.info["variant_check"] = {"state": self.variant_check.state, "text": self.variant_check.text}
        publish = self.state.publish  # what this tool commands does not age while the module is online
        for name, on in self.outputs.items():
            publish(name, on, periodic=False, text="on" if on else "off")
        publish("Watchdog", self.served, periodic=False,
                text=f"served: DigOut every {codec.DIGOUT_PERIOD_S * 1000:.0f} ms" if self.served
                else "not served by this tool: outputs are off in the module unless another master serves it")
        publish("Controlled by", self.controller.user if self.controller else None, periodic=False,
                text=None if self.controller else "nobody")
        publish("Variant check", self.variant_check.state, periodic=False, text=self.variant_check.text)
        if self.variant is Variant.HMR:
            publish("P2", self.two_phase, periodic=False, text="two-phase load" if self.two_phase else "three-phase load")
        publish("Faults", len(faults), periodic=False, text="; ".join(faults) or "none")
        rate, bus_rate = self.ids.bitrate, self.state.info.get("bus_bitrate")
        publish("Bit rate check", "mismatch" if self.state.info.get("bitrate_mismatch") else "ok", periodic=False,
                text=f"bit rate mismatch: module {rate // 1000} kbit/s, bus {(bus_rate or 0) // 1000} kbit/s"
                if self.state.info.get("bitrate_mismatch") else f"{rate // 1000} kbit/s")
        if self.variant is Variant.HMR:
            publish("SSR1-3 load check", "fault" if group else "ok", periodic=False, text=group or "ok")

    def group_load_fault(self) -> str | None:
        """HMR, SSR1-3 switched on: three phases must report a load, exactly two with P2 (4.3)."""
        if self.variant is not Variant.HMR or not self.outputs["SSR1-3"] or not all(i in self.temps for i in (1, 2, 3)):
            return None
        loaded = sum(self.temps[i].load for i in (1, 2, 3))
        expected = 2 if self.two_phase else 3
        if loaded == expected:
            return None
        return f"SSR1-3 load fault: {loaded} of 3 phases report a load, {'P2 (two-phase load)' if self.two_phase else 'a three-phase load'} needs {expected}"

    # -- what the page shows ------------------------------------------------------------------
    def temp_channels(self) -> list[int]:
        if self.variant is Variant.KM:
            return []
        return [1, 4, 5, 6] if self.variant is Variant.HMR else [1, 2, 3, 4, 5, 6]

    def temp_label(self, channel: int) -> str:
        return f"TEMP{channel} [°C]"

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
        if name not in self.outputs:
            raise CommandError(f"{self.variant.value} has no output {name}")
        if on:
            if self.controller is None:
                raise CommandError("take control of the module first: this tool serves its watchdog only while you control it")
            if self.controller.session != session:
                raise ControlBusy(f"{self.controller.user} controls the module")
            if not self.variant_check.may_switch:
                raise CommandError(self.variant_check.text)
        if on and not self.outputs[name]:
            self.owners[name] = session
        elif not on:
            self.owners.pop(name, None)
        self.outputs[name] = on
        self._send_now()
        self._publish()
        self.state.event("info", f"{name} {'on' if on else 'off'}")

    def all_off(self, reason: str = "all off") -> None:
        for name in self.outputs:
            self.outputs[name] = False
        self.owners.clear()
        self._send_now()
        self._publish()
        self.state.event("warning", f"every output switched off: {reason}")

    def holders(self) -> set[str]:
        """The page sessions that keep outputs on through this adapter (for the worker's dead-man rule)."""
        return {session for name, session in self.owners.items() if self.outputs[name]}

    def session_lost(self, session: str, reason: str) -> None:
        """``session`` is gone or stopped confirming it is alive: its outputs off at once, and its control released."""
        self.session_stop(session, reason)
        if self.controller is not None and self.controller.session == session:
            self._release(f"released: {reason}")

    def session_back(self, session: str) -> None:
        """The page of ``session`` confirms it is alive again after its connection dropped: its control is its own again."""
        if self.controller is not None and self.controller.session == session:
            self.controller.disconnected = None

    def session_stop(self, session: str, reason: str) -> None:
        """The page of ``session`` disconnected: its outputs off at once; its control (the watchdog with
        every output off) stays until the page is gone for good (:meth:`session_lost`)."""
        if self.controller is not None and self.controller.session == session:
            self.controller.disconnected = time.monotonic()  # another page may take control over
        names = [name for name, owner in self.owners.items() if owner == session and self.outputs[name]]
        for name in [name for name, owner in self.owners.items() if owner == session]:
            del self.owners[name]
        if names:
            for name in names:
                self.outputs[name] = False
            self._send_now()
            self._publish()
            self.state.event("warning", f"{', '.join(names)} off: {reason}")

    # -- SYNC cfg (7.2.4) ----------------------------------------------------------------------
    def set_two_phase(self, on: bool) -> None:
        if self.variant is not Variant.HMR:
            raise CommandError("P2 (two-phase load) exists on the HMR only")
        self.two_phase = on
        if self.controller is not None:
            self.bus.send(self.ids.sync, codec.encode_sync_cfg(on), False)
        self._start_cfg()
        self._publish()
        self.state.event("info", f"P2 {'on: three-phase output loaded on two phases' if on else 'off: three phases'}"
                         + ("" if self.controller is not None else " (sent once this tool controls the module)"))

    # -- addressed data (7.2.4.2) ---------------------------------------------------------------
    async def _request(self, area: int, index: int, payload: bytes = b"") -> codec.MData:
        if not self.ids.addressed:
            raise CommandError(f"addressed data needs SW1 switch 8 on (SW1 is 0x{self.sw1:02X})")
        async with self._lock:
            future = asyncio.get_running_loop().create_future()
            self._mdata[(area, index)] = future
            self.state.counters.requests += 1
            try:
                self.bus.send(self.ids.sync, codec.encode_sync_request(area, index, payload), False)
                return await asyncio.wait_for(future, MDATA_TIMEOUT_S)
            except asyncio.TimeoutError:
                self.state.counters.timeouts += 1
                raise CommandError(f"no MData for area {area} index {index} within {MDATA_TIMEOUT_S} s") from None
            finally:
                self._mdata.pop((area, index), None)

    async def read_identity(self) -> dict:
        serial = await self._request(codec.AREA_READ_CONFIG, codec.CONFIG_SERIAL)
        product = await self._request(codec.AREA_READ_CONFIG, codec.CONFIG_PRODUCT)
        version = await self._request(codec.AREA_READ_CONFIG, codec.CONFIG_VERSION)
        config = await self._request(codec.AREA_READ_CONFIG, codec.CONFIG_DYNAMIC)
        code = codec.decode_u16(product.payload)
        raw_version = codec.decode_u16(version.payload)
        info = {
            "serial": codec.decode_serial(serial.payload),
            "product_code": code,
            "product": codec.product_name(code),
            "version": f"{raw_version >> 8}.{raw_version & 0xFF}",
            "config": config.payload[0],
        }
        self.info.update(info)
        self.state.info["identity"] = info
        publish = self.state.publish  # read on demand: does not age while online
        publish("Serial number", info["serial"], raw=serial.payload.hex(" "), periodic=False)
        publish("Product code", code, raw=code, text=info["product"], periodic=False)
        publish("Software version", info["version"], raw=raw_version, periodic=False)
        publish("Configuration", info["config"], raw=info["config"], text=f"0x{info['config']:02X}", periodic=False)
        self._set_product(code)
        return info

    async def read_customer(self, index: int) -> bytes:
        if index not in codec.CUSTOMER_RECORDS:
            raise CommandError(f"customer record {index} is outside 1..15")
        answer = await self._request(codec.AREA_READ_CUSTOMER, index)
        self.state.info.setdefault("customer", {})[index] = answer.payload
        self._publish_customer(index, answer.payload)
        return answer.payload

    async def write_customer(self, index: int, payload: bytes) -> bytes:
        """Write and verify: the answer is what the module stored (7.2.4.2.4)."""
        if index not in codec.CUSTOMER_RECORDS:
            raise CommandError(f"customer record {index} is outside 1..15")
        if len(payload) > 6:
            raise CommandError(f"a customer record holds 6 bytes, got {len(payload)}")
        answer = await self._request(codec.AREA_WRITE_CUSTOMER, index, payload)
        self.state.info.setdefault("customer", {})[index] = answer.payload
        self._publish_customer(index, answer.payload)
        if answer.payload != codec.pad6(payload):
            self.state.counters.write_errors += 1
            raise CommandError(
                f"customer record {index}: the module stored {answer.payload.hex(' ')} instead of "
                f"{codec.pad6(payload).hex(' ')}: write it again"
            )
        self.state.event("info", f"customer record {index} = {answer.payload.hex(' ')} written and verified")
        return answer.payload

    async def read_load_data(self) -> dict[int, codec.TempWord]:
        result = {}
        for index in range(1, 7):
            answer = await self._request(codec.AREA_LOAD_DATA, index)
            result[index] = codec.TempWord(codec.decode_u16(answer.payload))
        self.state.info["load_data"] = result
        for index, word in result.items():  # area 5: actual load data of SSR 1-6 (7.2.4.2)
            self.state.publish(f"SSR{index} load data", word.load, raw=word.raw,
                               text=f"Last {int(word.load)}, Triac {int(word.triac)}, Si {int(word.fuse)}", periodic=False)
        return result

    def _publish_customer(self, index: int, payload: bytes) -> None:
        self.state.publish(f"Customer data {index}", payload.hex(" "), raw=list(payload), periodic=False)

    # -- backup and restore (app/backup.py) ------------------------------------------------------
    @property
    def backup_available(self) -> bool:
        """Only the addressed mode has stored data (customer records) to back up."""
        return self.ids.addressed

    async def backup_read(self, progress=None) -> list[dict]:
        """Identity (for reference) and the 15 customer-data records (writable)."""
        if not self.ids.addressed:
            raise CommandError(f"nothing to back up: customer data needs addressed mode (SW1 switch 8 on; SW1 is 0x{self.sw1:02X})")
        info = await self.read_identity()
        entries = [
            {"key": f"config:{k}", "name": name, "space": "config", "address": index, "raw": info[k], "value": info[k],
             "text": str(info[k]), "unit": "", "writable": False}
            for k, name, index in (("serial", "Serial number", 1), ("product_code", "Product code", 2),
                                   ("version", "Software version", 3), ("config", "Dynamic configuration", 15))
        ]
        for index in codec.CUSTOMER_RECORDS:
            payload = await self.read_customer(index)
            entries.append({"key": f"customer:{index}", "name": f"Customer data {index}", "space": "customer", "address": index,
                            "raw": payload.hex(" "), "value": payload.hex(" "), "text": payload.hex(" "), "unit": "", "writable": True})
            if progress:
                progress(index / 15)
        return entries

    def backup_identity(self) -> dict:
        identity = self.state.info.get("identity") or {}
        return {"serial": identity.get("serial"), "product": identity.get("product"), "version": identity.get("version"),
                "variant": self.variant.value, "sw1": self.sw1}

    async def restore_entry(self, key: str, raw: str) -> str:
        space, _, index = key.partition(":")
        if space != "customer":
            raise CommandError(f"{key} is not writable")
        try:
            payload = bytes.fromhex(str(raw))
        except ValueError:
            raise CommandError(f"{key}: {raw!r} is not hex bytes") from None
        return (await self.write_customer(int(index), payload)).hex(" ")

    async def save_step(self) -> None:
        return None  # every customer record is stored when written
