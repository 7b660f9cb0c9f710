"""The CAN-M3IO's safety rules without I/O: who switched which output on, the DigOut keep-alive and its lease,
another master on the bus.

Sans-I/O on the shared control-session core (:mod:`devices.control`): events in (an operator takes or
releases control, switches an output, a page disconnects, comes back or is gone, the supervisor's beat, a
frame of the module or of another master, time), actions out (start, change or end the cyclic DigOut, grant,
renew or revoke its lease, report). Every method takes ``now``, monotonic seconds of the caller's clock.
The adapter (:mod:`devices.m3io.adapter`) carries the actions out on its CAN bus.

The rules (the M3IO document, sections 7 and 7.1):

- the module keeps its outputs on only while DigOut comes within 2 s (its watchdog); this tool serves it,
  every 100 ms, only while an engineer controls the module (or, with ``master = "always"``, with every
  output off while nobody does);
- an SSR switches mains voltage: it runs under the session's lease, and the cyclic sender carries the stop
  form (every SSR off, the LED as it is) by itself once the lease is not valid; a lapse latches;
- a page that disconnects switches its outputs off at once; a page gone for good releases control too;
- another master on the bus (a PLC's DigOut, or the module answering while this tool serves nothing and
  asked nothing) is never fought: control is refused while it was heard within 2 s, and this tool stops
  sending as soon as one appears. An answer to this tool's own request is no sign of another master.

No import of asyncio, threading, sockets or any bus library (tests/safety/test_control_layering.py).
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass

from devices.control import LEASE_S, ControlChanged, ControlSession, Decision, Holder, LeaseChange, Report, Stop
from devices.m3io import codec
from devices.m3io.codec import Variant
from devices.message import N_, Message

LISTEN_S = 0.6  # listened this long since the bus opened before taking control: longer than the 500 ms temperature period (7.2.2)
FOREIGN_WINDOW_S = codec.WATCHDOG_S  # a master must send DigOut within 2 s (7.1): one heard within this window is active
TEMP_SLACK_S = 0.6  # after the watchdog ran out, a temperature telegram already under way may still come
IDLE_DIGOUT_PERIOD_S = 0.5  # master = "always", nobody in control: every output off, the 2 s watchdog served with room
MDATA_TIMEOUT_S = 0.5  # an addressed request (7.2.4.2) waits this long for its MData
ANSWER_WINDOW_S = MDATA_TIMEOUT_S + 0.5  # an MData this long after this tool's own request answers it (a late one too)
FOREIGN_MASTER = Message(N_("a PLC or another master"))
RELEASED = Message(N_("released"))  # control released (the page's Release)
ALL_OFF = Message(N_("all off"))
TAKEN_OVER = Message(N_("taken over by another page: the page that held it had disconnected"))
ENGINEER = "engineer"
MODULE_FRAMES = ("DigIn", "Temp", "MData")


# -- actions ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class KeepAlive:
    """Start (or restart) the cyclic DigOut: ``data`` every ``period_s`` on the sender's own clock, and the
    Sync cfg with it. ``leased``: while the lease is not valid the sender carries :func:`stop_form` by itself."""

    data: bytes
    period_s: float
    leased: bool


@dataclass(frozen=True, slots=True)
class DigOut:
    """New contents of the running keep-alive, sent at once too."""

    data: bytes


@dataclass(frozen=True, slots=True)
class EndKeepAlive:
    """Stop the cyclic DigOut and the Sync cfg: the module's watchdog switches its outputs off within 2 s."""


def stop_form(data: bytes) -> bytes:
    """DigOut with every SSR off (bits 1-6 cleared); the LED (bit 0) is no mains output and stays."""
    return bytes([data[0] & 0x01]) + bytes(data[1:]) if data else bytes(data)


def mains_on(variant: Variant, data: bytes) -> list[str]:
    """The SSR outputs a DigOut byte switches on (mains voltage, 7.2.1)."""
    if not data:
        return []
    return [name for name, on in codec.decode_dig_out(variant, data).items() if on and name != "LED"]


class M3ioControl:
    """One module's outputs, their owners, the keep-alive and its lease, and another master on the bus.

    :param variant: the plant file's variant (which outputs exist)
    :param dig_out_id: the module's DigOut CAN ID (named in what the core reports)
    :param always_master: ``master = "always"`` in the plant file: serve the watchdog with every output off
        while nobody controls the module and no other master is heard
    """

    def __init__(self, variant: Variant, dig_out_id: int = 0, always_master: bool = False, lease_s: float = LEASE_S):
        self.variant = variant
        self.dig_out_id = dig_out_id
        self.always_master = always_master
        self.session = ControlSession(lease_s)
        self.outputs = {name: False for name in codec.OUTPUT_BITS[variant]}
        self.owners: dict[str, str] = {}  # output that is on -> page session that switched it on
        self.may_switch = True  # the variant check lets outputs switch on
        self.may_switch_text = ""  # why not, in words
        self.serving = ""  # "" nothing sent, "control" for the engineer in control, "idle" every output off (always master)
        self.foreign_at: float | None = None  # last sign of another master
        self.served_until = -math.inf  # the module may still answer this tool's last DigOut until then
        self.requests: dict[tuple[int, int], float] = {}  # this tool's own addressed requests -> answered until
        self._link: object = None  # the bus's (re)open this core listened since
        self._listening_since = 0.0

    # -- queries ---------------------------------------------------------------------------------------
    @property
    def holder(self) -> Holder | None:
        return self.session.holder

    @property
    def served(self) -> bool:
        return bool(self.serving)

    def controls(self, session: str) -> bool:
        return self.session.controls(session)

    def holders(self) -> set[str]:
        """The sessions that keep outputs on (the dead-man supervisor watches them)."""
        return {session for name, session in self.owners.items() if self.outputs.get(name)}

    def foreign_master(self, now: float) -> bool:
        """Was another master heard within the last 2 s?"""
        return self.foreign_at is not None and now - self.foreign_at <= FOREIGN_WINDOW_S

    def listen_left(self, now: float, link: object = None) -> float:
        """Seconds still to listen for another master before control may be taken; ``link`` names the bus's
        current opening (its reconnect count): a bus opened anew is listened to from now on."""
        if link != self._link:
            self._link, self._listening_since = link, now
        return max(0.0, LISTEN_S - (now - self._listening_since))

    def dig_out_data(self) -> bytes:
        """The DigOut byte of the outputs as set (nothing on before the variant check lets it)."""
        return codec.encode_dig_out(self.variant, self.outputs if self.may_switch else {})

    def telegram(self, now: float) -> bytes | None:
        """What the cyclic sender carries at ``now`` (None: it sends nothing), as python-can's task sends it."""
        if not self.serving:
            return None
        if self.serving == "idle":
            return codec.encode_dig_out(self.variant, {})
        data = self.dig_out_data()
        return data if self.session.lease.valid(now) else stop_form(data)

    # -- operator events -------------------------------------------------------------------------------
    def take(self, session: str, user: str, now: float, wall: float, link: object = None,
             role: str = ENGINEER) -> Decision:
        """``session`` asks for control: granted once this tool listened LISTEN_S and heard no other master."""
        if role != ENGINEER:
            return Decision(f"a {role} watches the module: taking control needs the engineer role")
        holder = self.holder
        if holder is not None and holder.session == session:
            return Decision()
        if holder is not None and holder.disconnected is None:
            return self.session.take(session, user, now, wall)  # refused: busy
        left = self.listen_left(now, link)
        if left > 0:
            return Decision(Message(N_("still listening for another master on the bus ({seconds:.1f} s): try again"),
                                    seconds=round(left, 1)))
        if self.foreign_master(now):
            return Decision(Message(N_("another master serves this module ({who}: DigOut 0x{id:03X} or the module's answers "
                                       "heard within {seconds:g} s): taking control would fight it. Stop that master and "
                                       "try again."), who=FOREIGN_MASTER, id=self.dig_out_id, seconds=FOREIGN_WINDOW_S))
        actions: list = []
        if holder is not None:  # its page had disconnected: taken over
            actions += self._release(TAKEN_OVER, now)
        decision = self.session.take(session, user, now, wall)
        if not decision.ok:
            return decision
        self._clear_outputs()
        self.session.idle()
        self.serving = "control"
        actions += [ControlChanged(self.holder), LeaseChange("revoke"),
                    KeepAlive(self.dig_out_data(), codec.DIGOUT_PERIOD_S, leased=True),
                    Report("info", Message(N_("{user} took control (no other master heard): DigOut 0x{id:03X} every "
                                              "{ms:.0f} ms serves the 2 s watchdog"),
                                           user=user, id=self.dig_out_id, ms=codec.DIGOUT_PERIOD_S * 1000))]
        return Decision(actions=tuple(actions))

    def release(self, session: str, now: float, reason: str = RELEASED) -> list:
        """The holder gives control back (``session`` "": whoever holds it): every output off, DigOut stops."""
        if self.holder is None or (session and self.holder.session != session):
            return []
        return self._release(reason, now)

    def set_output(self, session: str, name: str, on: bool, now: float, role: str = ENGINEER) -> Decision:
        """Switch ``name`` for ``session``, which must control the module to switch on and then owns the output
        until it is off or the session is lost. Switching off is never refused."""
        if name not in self.outputs:
            return Decision(f"{self.variant.value} has no output {name}")
        lapsed = self.tick(now)  # a lease that lapsed meanwhile stays lapsed: no press of another output renews it
        if on:
            if role != ENGINEER:
                return Decision(f"a {role} watches the module: switching on needs the engineer role")
            if self.holder is None:
                return Decision("take control of the module first: this tool serves its watchdog only while you control it")
            if self.holder.session != session:
                return Decision(f"{self.holder.user} controls the module", busy=True)
            if self.holder.disconnected is not None:
                return Decision("this page's connection dropped: reload it and take control again")
            if not self.may_switch:
                return Decision(self.may_switch_text or "the variant check does not let outputs switch on")
            if not self.outputs[name]:
                self.owners[name] = session
        else:
            self.owners.pop(name, None)
        self.outputs[name] = on
        said = Message(N_("{output} on"), output=name) if on else Message(N_("{output} off"), output=name)
        actions = lapsed + self._leased(now) + self._resend() + [Report("info", said)]
        return Decision(actions=tuple(actions))

    def all_off(self, now: float, reason: str = ALL_OFF) -> list:
        """Every output off (a stop: never refused)."""
        lapsed = self.tick(now)
        self._clear_outputs()
        return lapsed + self._leased(now) + self._resend() + [Report(
            "warning", Message(N_("every output switched off: {reason}"), reason=reason))]

    def disconnected(self, session: str, reason: str, now: float) -> list:
        """The page of ``session`` disconnected: its outputs off at once; its control (the watchdog with every
        output off) stays until the page is gone for good (:meth:`lost`), and another page may take it over."""
        lapsed = self.tick(now)
        self.session.disconnected(session, reason, now)  # what runs is the outputs: switched off below
        names = [name for name, owner in self.owners.items() if owner == session and self.outputs[name]]
        for name in [name for name, owner in self.owners.items() if owner == session]:
            del self.owners[name]
        if not names:
            return lapsed
        for name in names:
            self.outputs[name] = False
        return lapsed + self._leased(now) + self._resend() + [Report(
            "warning", Message(N_("{outputs} off: {reason}"), outputs=", ".join(names), reason=reason))]

    def back(self, session: str) -> list:
        """The page of ``session`` is alive again: its control is its own again (nothing switches on)."""
        return self.session.back(session)

    def lost(self, session: str, reason: str, now: float) -> list:
        """``session`` is gone or stopped confirming it is alive: its outputs off, its control released."""
        actions = self.disconnected(session, reason, now)
        if self.controls(session):
            actions += self._release(Message(N_("released: {reason}"), reason=reason), now)
        return actions

    # -- the lease -------------------------------------------------------------------------------------
    def beat(self, alive: Collection[str] | Mapping[str, float], now: float) -> list:
        """The dead-man supervisor: ``alive`` confirmed they are alive (a mapping: each with the time of its
        page's last beat). Renews the lease of the mains outputs, counted from the page's last beat where it is
        told: a page that froze just before this program stalled keeps nothing on past that beat + the lease."""
        holder = self.holder
        if not self.session.running or holder is None:
            return []
        lease = self.session.lease
        if holder.session in alive and holder.disconnected is None and lease.valid(now):
            seen = alive.get(holder.session, now) if isinstance(alive, Mapping) else now
            at = min(now, seen if isinstance(seen, int | float) else now)
            lease.renew(at)
            return [LeaseChange("renew", at)]
        return self._lapse(self.session.tick(now), now)

    def tick(self, now: float) -> list:
        """Time passes: a lease past its time lapses (the SSRs off); old requests are forgotten; idle serving
        of an always-master starts once nobody controls the module and no other master was heard."""
        for key in [k for k, until in self.requests.items() if now > until]:
            del self.requests[key]
        return self._lapse(self.session.tick(now), now)

    def sender_lapsed(self, now: float) -> list:
        """The sender found the lease lapsed (its own clock ran past it before a renewal reached it)."""
        if not self.session.running:
            return []
        lease = self.session.lease
        if lease.lapsed_at is None:
            lease.lapsed_at = now
        return self._lapse(self.session.tick(now), now)

    # -- the bus ---------------------------------------------------------------------------------------
    def serve_idle(self, now: float, connected: bool, link: object = None) -> list:
        """``master = "always"``: start serving the watchdog with every output off once this tool listened and
        heard no other master, while nobody controls the module."""
        if (not self.always_master or self.holder is not None or self.serving or not connected
                or self.foreign_master(now)):
            return []
        if self.listen_left(now, link) > 0:
            return []
        self.serving = "idle"
        return [KeepAlive(codec.encode_dig_out(self.variant, {}), IDLE_DIGOUT_PERIOD_S, leased=False),
                Report("info", Message(N_("serving the watchdog with every output off (master = \"always\" in the plant "
                                          "file): DigOut 0x{id:03X} every {ms:.0f} ms"),
                                       id=self.dig_out_id, ms=IDLE_DIGOUT_PERIOD_S * 1000))]

    def foreign_dig_out(self, now: float) -> list:
        """A DigOut from another node: a PLC serves the module. Never fight it: stop sending, without a last frame."""
        self.foreign_at = now
        if self.holder is not None:
            return self._release(Message(N_("lost: another master sends DigOut 0x{id:03X} ({who}); this tool stopped "
                                            "sending so as not to fight it"), id=self.dig_out_id, who=FOREIGN_MASTER),
                                 now, level="error", last=False)
        if self.serving == "idle":
            return self._end_serving(now) + [Report(
                "warning", Message(N_("stopped serving the watchdog: another master sends DigOut 0x{id:03X} ({who}): "
                                      "this tool only listens now"), id=self.dig_out_id, who=FOREIGN_MASTER))]
        return []

    def request_sent(self, area: int, index: int, now: float) -> None:
        """This tool sent an addressed request (Sync, 7.2.4.2): its MData answer is no sign of another master."""
        self.requests[(area, index)] = now + ANSWER_WINDOW_S

    def module_frame(self, kind: str, now: float, key: tuple[int, int] | None = None) -> list:
        """A frame the module sent (``kind`` DigIn, Temp or MData with its ``(area, index)``). The module talks
        only while a master serves it (7): while this tool serves nothing, did not just stop, and did not ask
        for it, another master does."""
        if self.serving or now <= self.served_until:
            return []
        if kind == "MData" and key is not None and now <= self.requests.get(key, -math.inf):
            return []  # the answer to this tool's own request
        self.foreign_at = now
        return []

    def variant_checked(self, may_switch: bool, text: str, now: float) -> list:
        """The variant check's verdict: a module that is not the plant file's variant gets every output off."""
        was = self.may_switch
        self.may_switch, self.may_switch_text = may_switch, text
        if not may_switch and any(self.outputs.values()):
            return self.all_off(now, Message(N_("the module is not the variant the plant file names")))
        if may_switch and not was and any(self.outputs.values()):
            return self._resend()
        return []

    # -- inside ----------------------------------------------------------------------------------------
    def _clear_outputs(self) -> None:
        for name in self.outputs:
            self.outputs[name] = False
        self.owners.clear()

    def _leased(self, now: float) -> list:
        """A mains output on runs under a lease granted now (the press of its page: it is alive); none, no lease."""
        if any(on for name, on in self.outputs.items() if name != "LED"):
            self.session.started(now)
            return [LeaseChange("grant")]
        self.session.idle()
        return [LeaseChange("revoke")]

    def _resend(self) -> list:
        return [DigOut(self.dig_out_data())] if self.serving == "control" else []

    def _lapse(self, actions: list, now: float) -> list:
        """The shared core's lapse (a :class:`~devices.control.Stop`): every SSR off, the LED as it is; its
        report names the outputs."""
        if not any(isinstance(a, Stop) for a in actions):
            return list(actions)
        names = [name for name, on in self.outputs.items() if on and name != "LED"]
        for name in names:
            self.outputs[name] = False
            self.owners.pop(name, None)
        self.session.idle()
        out: list = [LeaseChange("revoke"), *self._resend()]
        if names:
            out += [Report(a.level, Message(N_("{outputs} off, by the DigOut keep-alive itself: {reason}"),
                                            outputs=", ".join(names), reason=a.text))
                    for a in actions if isinstance(a, Report)]
        return out

    def _end_serving(self, now: float) -> list:
        self.serving = ""
        self.served_until = now + codec.WATCHDOG_S + TEMP_SLACK_S
        return [EndKeepAlive()]

    def _release(self, reason: str, now: float, level: str = "warning", last: bool = True) -> list:
        """Every output off (sent at once unless another master took over), then the keep-alive stops."""
        user = self.holder.user if self.holder is not None else "nobody"
        on = [name for name, value in self.outputs.items() if value]
        self._clear_outputs()
        self.session.idle()
        actions: list = [LeaseChange("revoke")]
        if last and self.serving == "control":
            actions.append(DigOut(self.dig_out_data()))
        self.session.release("", reason)
        actions += [ControlChanged(None)]
        if self.serving:
            actions += self._end_serving(now)
        actions.append(Report(level, Message(N_("control {reason} ({user}): {outputs} off; DigOut stopped"), reason=reason,
                                             user=user, outputs=", ".join(on)) if on
                              else Message(N_("control {reason} ({user}); DigOut stopped"), reason=reason, user=user)))
        return actions
