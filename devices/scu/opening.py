"""Opening the SCU's remote session (document 002, sections 4.1 and 5): RO with the Safety_ID and RC, the emergency
stop and every owed RS again (the core's actions), then the cyclic object (RT of 0x3001; RG reads where the unit
refuses it) and the end positions; the probe that tells how the unit is watched outside a session, and RA."""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

from devices import values as v
from devices.message import Message, N_, message_of
from devices.scu import codec
from devices.scu import params as p
from devices.scu.facts import ActuatorScale
from devices.scu.keepalive import CYCLIC_INDEX
from devices.transport import SerialLineError

if TYPE_CHECKING:
    from devices.scu.adapter import ScuAdapter

WATCH_RG = "rg"  # RG outside a remote session: no RO/RC until someone takes control
WATCH_SESSION = "session"  # the unit refuses RG outside remote mode: the session is open for reading only
PROBE_ID = 0x0011  # a single data ID every unit answers (section 5 example reads it)
# Live data the cyclic object brings with every RC (at most 6 read IDs, table 7); the rest is read
# with one RG per poll in turn.
CYCLIC_READ_IDS = (0x0010, 0x0170, 0x00E0, 0x00A0, 0x00D1, 0x0100)


class ScuOpening:
    """The remote session of one SCU adapter: opened, probed, ended."""

    def __init__(self, adapter: ScuAdapter):
        self.adapter = adapter

    async def send_rc(self) -> codec.Answer:
        if self.adapter.cyclic is not None:
            try:
                answer = await self.adapter.link.request(codec.encode_rc(CYCLIC_INDEX), "RC keep-alive with CyclicObj 1",
                                             keepalive=False)
            except codec.CommandRefused as exc:
                if exc.code in (codec.Status.PE, codec.Status.CSE):
                    raise  # remote mode gone, or line noise (sent again with the next RC): nothing to remember
                # The definition was taken but RC with it is refused: RC without data from now on, RG for the rest.
                self.adapter.cyclic = None
                self.adapter.cyclic_refused = True
                self.adapter.cyclic_note = Message(N_("the unit refused RC with the cyclic object ({name}: {title}); RC "
                                                      "without data keeps the session, live data is read with RG"),
                                                   name=exc.info.name, title=exc.info.title)
                self.adapter.publish_cyclic()
                self.adapter.state.event("warning", self.adapter.cyclic_note)
                return await self.adapter.link.request(codec.KEEP_ALIVE, "RC keep-alive", keepalive=False)
            if answer.has_ctp:
                try:
                    self.adapter.live.publish_ids(self.adapter.cyclic.decode_read(answer.data))
                except (v.DecodeError, ValueError) as exc:
                    self.adapter.state.error(f"RC cyclic data: {exc}", log=False)
            return answer
        return await self.adapter.link.request(codec.KEEP_ALIVE, "RC keep-alive", keepalive=False)

    async def probe(self) -> None:
        """Does the unit answer RG outside remote mode? Decides how it is watched (remembered for this unit)."""
        if self.adapter.link.last_answer is None:
            await self.adapter.link.wake()  # a unit on battery may be asleep from the start (section 3, Low Power, V2B1)
        try:
            answer = await self.adapter.link.request(codec.encode_rg(PROBE_ID), "RG 0x0011 outside a session (probe)",
                                         keepalive=False, quiet=True)
        except codec.CommandRefused:
            self.adapter.watch = WATCH_SESSION
        else:
            self.adapter.watch = WATCH_RG
            self.adapter.live.publish_ids({PROBE_ID: p.rg_value(PROBE_ID, answer)})
        self.adapter.state.event("info", self.adapter.watch_text())
        self.adapter.publish_session()

    def ro_frame(self) -> bytes:
        """RO with the Safety_ID alone (section 5 example), or with para_ID[0] as table 3 lists it once the unit
        answered PCE to the short form."""
        if self.adapter.core.ro_two_bytes:
            return codec.encode_frame(codec.RO, bytes([int(self.adapter.safety_id), codec.UNUSED]))
        return codec.encode_ro(self.adapter.safety_id)

    async def open(self, forced: bool = False) -> None:
        """RO with the Safety_ID, RC; before anything else F20 again when it is on and the RS owed (the core's
        actions, whatever follows); then the cyclic object definition (or the RG fallback) and the end positions.

        :param forced: for the emergency stop: whatever the backoff or an earlier RA (never while RC is withheld)
        """
        why_not = self.adapter.core.may_open(time.monotonic(), forced)
        if why_not:
            if forced and self.adapter.core.phase != "open":
                self.adapter.state.event("error", Message(N_("emergency stop: the session is not opened now ({reason}); F20 "
                                                             "is switched on in the unit as soon as it is"), reason=why_not))
            return
        answered_before = self.adapter.link.last_answer is not None
        self.adapter.core.opening()
        self.adapter.sync_phase()
        self.adapter.cyclic = None
        with self.adapter.rc.guard:
            self.adapter.rc.times.clear()
        if self.adapter.core.failures or not answered_before:
            await self.adapter.link.wake()
        sid = int(self.adapter.safety_id)
        try:
            try:
                await self.adapter.link.request(self.ro_frame(), f"RO Safety_ID {sid}", keepalive=False)
            except codec.CommandRefused as exc:
                if not self.adapter.core.ro_refused(self.adapter.outcome(exc)):
                    raise
                self.adapter.state.event("warning", Message(N_("the unit answered PCE to RO with the Safety_ID alone: it takes "
                                                               "RO with Safety_ID and para_ID[0] as table 3 lists it; that "
                                                               "form from now on")))
                await self.adapter.link.request(self.ro_frame(), f"RO Safety_ID {sid}, para_ID[0] -1", keepalive=False)
            await self.adapter.link.request(codec.KEEP_ALIVE, "RC keep-alive", keepalive=False)  # section 5: RC before any other command
        except (SerialLineError, codec.CodecError) as exc:
            self.adapter.core.open_failed(message_of(exc), time.monotonic(),
                                          answered_before=self.adapter.link.last_answer is not None)
            self.adapter.sync_phase()
            if forced:
                for action in self.adapter.core.estop_unreachable(message_of(exc), time.monotonic()):
                    self.adapter.apply(action)
            return
        actions = self.adapter.core.opened(time.monotonic())
        self.adapter.sync_phase()
        # the emergency stop again (released only by the person who asks for it) and the RS of every RE still owed
        # (section 4.6), before the cyclic object is defined: whatever becomes of that, these have gone out
        await self.adapter.carry_out(actions)
        self.adapter.publish_estop()
        if self.adapter.core.phase != "open":
            return  # an RS was not acknowledged: RC is withheld until the unit's watchdog has stopped every drive
        if self.adapter.cyclic_refused:
            self.adapter.cyclic_note = Message(N_("RC without data (the unit refused the cyclic object); live data is read "
                                                  "with RG"))
        else:
            definition = p.CyclicDefinition(read_ids=self.cyclic_ids())
            try:
                await self.adapter.link.request(codec.encode_rt(0x3001, definition.encode()), "RT CyclicObj 1 definition")
                self.adapter.cyclic = definition
                self.adapter.cyclic_note = Message(N_("cyclic object 0x3001: positions, status 1 and 2, currents, error "
                                                      "code, mains/battery with every RC"))
            except codec.CommandRefused as exc:
                if exc.code == codec.Status.PE:
                    return
                if exc.code == codec.Status.CSE:
                    self.adapter.cyclic_note = Message(N_("the cyclic object's definition arrived damaged (CSE, line noise): "
                                                          "live data is read with RG until the next opening defines it again"))
                else:
                    self.adapter.cyclic_refused = True
                    self.adapter.cyclic_note = Message(N_("the unit refused the cyclic object definition ({name}: {title}); "
                                                          "live data is read with RG requests instead"),
                                                       name=exc.info.name, title=exc.info.title)
                    self.adapter.state.event("warning", self.adapter.cyclic_note)
            except (SerialLineError, codec.CodecError):
                return
        self.adapter.publish_cyclic()
        self.adapter.state.event("info", Message(N_("remote session open (Safety_ID {safety_id}); {note}"),
                                                 safety_id=int(self.adapter.safety_id), note=self.adapter.cyclic_note))
        try:
            await self.read_end_positions()
        except (SerialLineError, codec.CodecError, v.DecodeError):
            pass

    def cyclic_ids(self) -> tuple[int, ...]:
        """The cyclic object's read IDs: the groups, or for a unit that refuses groups its single IDs (at most 6)."""
        if not self.adapter.single_ids:
            return CYCLIC_READ_IDS
        ids: list[int] = []
        for group in CYCLIC_READ_IDS:
            ids.extend(self.ids_of(group))
        return tuple(ids[:6])

    def ids_of(self, group: int) -> list[int]:
        """What to read for ``group``: the group ID, or its members for the configured actuators once refused."""
        entry = p.DIRECTORY.get(group)
        if group not in self.adapter.single_ids or entry is None or not entry.is_group:
            return [group]
        return [m for m in entry.members
                if p.DIRECTORY[m].actuator is None or p.DIRECTORY[m].actuator <= len(self.adapter.scales)]

    async def read_end_positions(self) -> None:
        """Position_Virtual_Limit_In/Out of UserPositionData (section 7) as the end positions of the bars and mm;
        the conversion factors 0x1011.. (counts per mm) where the plant file gives no scale."""
        for i, scale in enumerate(self.adapter.scales):
            try:
                answer = await self.adapter.link.request(codec.encode_rg(0x2000 + scale.number), f"RG 0x{0x2000 + scale.number:04X}")
                value = p.rg_value(0x2000 + scale.number, answer)
            except codec.CommandRefused:
                value = None
            if value is not None:
                self.adapter.settings.note(0x2000 + scale.number, value)
                lo, hi = value["Position_Virtual_Limit_In"], value["Position_Virtual_Limit_Out"]
                self.adapter.scales[i] = scale.with_ends(lo, hi)
                self.adapter.publish_scales()
            s = self.adapter.scales[i]
            self.adapter.state.publish(f"A{s.number} in end", s.in_counts, "counts", periodic=False)
            self.adapter.state.publish(f"A{s.number} out end", s.out_counts, "counts", periodic=False)
            if not s.has_mm:
                try:
                    factor = p.rg_value(0x1010 + s.number, await self.adapter.link.request(
                        codec.encode_rg(0x1010 + s.number), f"RG 0x{0x1010 + s.number:04X} conversion factor"))
                except codec.CommandRefused:
                    continue
                self.adapter.settings.note(0x1010 + s.number, factor)
                self.adapter.state.publish(f"A{s.number} conversion factor", factor, "counts/mm", periodic=False)
                if isinstance(factor, float) and math.isfinite(factor) and factor > 0:
                    self.adapter.scales[i] = ActuatorScale(s.number, factor, None, s.in_counts, s.out_counts)
                    self.adapter.publish_scales()

    async def end(self, reason: str) -> None:
        try:
            await self.adapter.link.request(codec.encode_ra(), "RA (nobody in control)", keepalive=False)
        except (SerialLineError, codec.CodecError):
            pass
        self.adapter.cyclic = None
        self.adapter.set_session("closed", reason)
