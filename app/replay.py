"""Replay of a recorded file onto a CAN bus (issue 17 item 5).

The frames go through the bus owner's send path (:meth:`app.can_bus.CanBus.send`), so the bus
monitor shows them and a running recording records them as sent. A replay keeps the recorded
gaps (scaled by ``speed``), can be stopped at any time, is refused on a bus where a device is
under control (an adapter's ``holders()`` is not empty) and stops by itself when a device comes
under control meanwhile. It is under the dead-man rule: registered with ``worker.add_holder``, it
ends when the engineer's browser goes away. Starting is checked and audited through
``worker.gate.run``.

Error frames and remote frames of the file are not sent (the send path carries data frames);
they are counted in ``skipped``. Every other frame is judged by the one send policy
(:func:`devices.sendpolicy.check_send`, as every other path that sends bytes), and a replay never sends:

- a frame that a device sends (status, answers, internal traffic: the lock status under a lock's
  ID, Electrak 0x07, Electrak internal 0x600-0x6FF, an M3IO's inputs): the policy refuses it, and a
  frame on an ID that a device of the bus or a device type's fixed IDs declare as the device's own
  (``CanIdUse.sender == "device"``) is kept off as well: a replay never impersonates a device;
- a frame the policy forbids (firmware update, a factory reset, a register that is not writable) or
  would ask a confirmation for (motion: an Electrak control telegram with enable; mains: an M3IO
  DigOut with an SSR on; a risky value): nobody confirms frames of a file one by one.

Those frames are filtered, counted by reason, and shown before the replay starts (:func:`screen`).
Starting asks a confirmation that says how many frames go out onto which bus
(:class:`NeedsConfirmation`, then ``confirmed=True``).
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from app.can_bus import FrameRecord
from app.i18n import N_
from app.message import Message, joined
from devices.adapter import SessionHolder
from devices.errors import CommissionError
from devices.sendpolicy import CanMessage, check_send

log = logging.getLogger(__name__)

SPEED_MIN, SPEED_MAX = 0.01, 100.0  # replay speed factors offered (x recorded speed)
MAX_GAP_S = 60.0  # a recorded pause longer than this (after scaling) is shortened to it
BURST_FRAMES = 64  # frames sent in one go when late, before the loop runs anything else
CONTROL_CHECK_S = 0.2  # how often a running replay looks whether a device came under control
# a replay's summary by its state (ready, running, done, stopped, failed)
SUMMARIES = {"ready": N_("ready: {sent} of {total} frames sent"), "running": N_("running: {sent} of {total} frames sent"),
             "done": N_("done: {sent} of {total} frames sent"), "stopped": N_("stopped: {sent} of {total} frames sent"),
             "failed": N_("failed: {sent} of {total} frames sent")}
# what sending a frame does (devices.sendpolicy.KINDS), as a replay names a frame it keeps off for a confirmation (a
# read or a stop is never asked)
KIND_WORDS = {"write": N_("write"), "system": N_("system"), "mains": N_("mains"), "motion": N_("motion")}


class ReplayError(CommissionError):
    """A replay that cannot start; the message says why."""


class NeedsConfirmation(ReplayError):
    """The replay may start once the engineer confirmed the question: how many frames go out onto which bus."""

    def __init__(self, question: Message, frames: int):
        super().__init__(question)
        self.question = question
        self.frames = frames


STOPPED_BY_THE_ENGINEER = Message(N_("stopped by the engineer"))


def holder_name(bus: str) -> str:
    return f"replay {bus}"


def controlled_devices(worker: Any, bus: str) -> list[str]:
    """Devices on ``bus`` under control now (their adapter has holders)."""
    names = []
    for dev in worker.plant.devices_on(bus):
        adapter = worker.adapters.get(dev.name)
        if isinstance(adapter, SessionHolder) and adapter.holders():
            names.append(dev.name)
    return names


def refusal(worker: Any, bus: str) -> Message | None:
    """Why a replay cannot start on ``bus`` now, else None."""
    if bus not in worker.can_buses:
        return Message(N_("{bus} is not a CAN bus of this plant: only CAN recordings can be replayed"), bus=bus)
    controlled = controlled_devices(worker, bus)
    if controlled:
        template = (N_("{devices} on {bus} is under control: release the control first (a replay would interfere with it)")
                    if len(controlled) == 1 else
                    N_("{devices} on {bus} are under control: release the control first (a replay would interfere with it)"))
        return Message(template, devices=", ".join(controlled), bus=bus)
    running = worker.extra_holders.get(holder_name(bus))
    if isinstance(running, Replay) and running.running:
        return Message(N_("a replay of {name} runs on {bus} already"), name=running.name, bus=bus)
    return None


@dataclass
class Screening:
    """What the send policy lets through of a recording: the frames filtered, by reason."""

    blocked: frozenset[int] = frozenset()  # indexes of the frames not sent
    reasons: dict[str, int] = field(default_factory=dict)  # reason -> frames

    def text(self) -> str | Message:
        if not self.blocked:
            return ""
        counted = [Message("{n} x {reason}", n=n, reason=reason) for reason, n in sorted(self.reasons.items(), key=lambda i: -i[1])]
        return Message(N_("{n} frame(s) will not be sent: {reasons}"), n=len(self.blocked), reasons=joined(counted, "; "))

    def going_out(self, frames: Sequence[FrameRecord]) -> int:
        """How many of ``frames`` a replay sends: data frames the policy lets through."""
        return sum(1 for i, rec in enumerate(frames)
                   if not (rec.is_error_frame or rec.is_remote_frame) and i not in self.blocked)


def device_sent(bus_devices: Sequence[Any], can_id: int, extended: bool) -> str:
    """What a device sends on ``can_id`` on a bus with ``bus_devices`` (its declared use), or "" when no device
    declares it as its own: the devices of the bus and every CAN type's fixed IDs (devices/registry.py)."""
    from devices.registry import DEVICE_TYPES, fixed_can_id_uses

    for device_type, use in fixed_can_id_uses():
        if use.sender == "device" and use.covers(extended, can_id):
            return f"{use.use} ({device_type.title})"
    for dev in bus_devices:
        if dev.type not in DEVICE_TYPES:
            continue
        for use in DEVICE_TYPES[dev.type].can_ids(dev.options, "can"):
            if use.sender == "device" and use.covers(extended, can_id):
                return f"{use.use} ({dev.name})"
    return ""


def frame_reason(bus_devices: Sequence[Any], can_id: int, extended: bool, data: bytes) -> str | Message:
    """Why a replay keeps this frame off the bus ("" : it goes out): the send policy's verdict, the same as
    every other path's; a frame a device sends is never replayed."""
    verdict = check_send(bus_devices, CanMessage(can_id, extended, bytes(data)))
    if verdict.refused:
        return verdict.refused
    own = device_sent(bus_devices, can_id, extended)
    if own:
        return Message(N_("sent by a device: {use} (a replay never impersonates a device)"), use=own)
    if verdict.confirm:
        kind = Message(KIND_WORDS[verdict.kind]) if verdict.kind in KIND_WORDS else verdict.kind
        return Message(N_("{kind}: {name} (confirmed frame by frame only, never from a file)"), kind=kind,
                       name=verdict.name or Message(N_("needs a confirmation")))
    return ""


def screen(worker: Any, bus: str, frames: Sequence[FrameRecord]) -> Screening:
    """Ask the send policy about every frame (O(frames); run it in a thread for a long file).

    A frame the policy refuses, or would ask a confirmation for, and a frame a device sends, is filtered:
    its reason is counted.
    """
    devices = list(worker.plant.devices_on(bus))
    blocked, reasons, cache = set(), {}, {}
    for i, rec in enumerate(frames):
        if rec.is_error_frame or rec.is_remote_frame:
            continue
        key = (rec.arbitration_id, rec.is_extended_id, bytes(rec.data))
        reason = cache.get(key)
        if reason is None:
            reason = frame_reason(devices, *key)
            if len(cache) < 65536:
                cache[key] = reason
        if reason:
            blocked.add(i)
            reasons[reason] = reasons.get(reason, 0) + 1
    return Screening(frozenset(blocked), reasons)


@dataclass
class Replay:
    """One replay: its progress for the page, and the dead-man hooks for the worker."""

    worker: Any
    bus: str
    frames: Sequence[FrameRecord]
    name: str = "recording"
    speed: float = 1.0
    session: str = ""
    user: str = "local"
    sent: int = 0
    skipped: int = 0
    failed: int = 0
    screening: Screening = field(default_factory=Screening)
    filtered: int = 0  # frames the send policy kept off the bus
    state: str = "ready"  # ready, running, done, stopped, failed
    reason: str = ""  # why it ended (a Message where the replay words it)
    started: float = 0.0
    ended: float = 0.0
    send_times: list[float] = field(default_factory=list)  # loop time of each send, when measuring (bench)
    measure: bool = False
    _task: asyncio.Task | None = None
    _stop: asyncio.Event = field(default_factory=asyncio.Event)

    @property
    def running(self) -> bool:
        return self.state == "running"

    @property
    def total(self) -> int:
        return len(self.frames)

    @property
    def position(self) -> int:
        return self.sent + self.skipped + self.failed + self.filtered

    @property
    def fraction(self) -> float:
        return self.position / self.total if self.total else 1.0

    @property
    def duration_s(self) -> float:
        """Recorded duration at the chosen speed."""
        return (self.frames[-1].time - self.frames[0].time) / self.speed if len(self.frames) > 1 else 0.0

    def summary(self) -> Message:
        """How far it got: the frames sent, skipped, kept off and refused, and why it ended."""
        parts = [Message(SUMMARIES[self.state], sent=self.sent, total=self.total)]
        if self.skipped:
            parts.append(Message(N_(", {n} error/remote frames skipped"), n=self.skipped))
        if self.filtered:
            parts.append(Message(N_(", {n} kept off the bus by the device policies"), n=self.filtered))
        if self.failed:
            parts.append(Message(N_(", {n} refused by the bus"), n=self.failed))
        if self.reason:
            parts.append(Message(" ({reason})", reason=self.reason))
        return joined(parts, "")

    # -- dead-man hooks (worker.add_holder) --------------------------------------------------------------
    def holders(self) -> set[str]:
        return {self.session} if self.running and self.session else set()

    def session_lost(self, session: str, reason: str) -> None:
        if session == self.session and self.running:
            self.stop(reason)

    # -- control ---------------------------------------------------------------------------------------
    def stop(self, reason: str = STOPPED_BY_THE_ENGINEER) -> None:
        """Stop at once (no frame is sent after this returns)."""
        if self.running:
            self.state = "stopped"
            self.reason = reason
            self._stop.set()
            self._finish()

    def _finish(self) -> None:
        self.ended = time.time()
        if self.worker.extra_holders.get(holder_name(self.bus)) is self:
            self.worker.remove_holder(holder_name(self.bus))

    def start(self) -> None:
        self.state = "running"
        self.started = time.time()
        self.worker.add_holder(holder_name(self.bus), self)
        self._task = asyncio.get_running_loop().create_task(self._run(), name=holder_name(self.bus))

    async def wait(self) -> None:
        if self._task is not None:
            await asyncio.shield(self._task)

    async def _run(self) -> None:
        can_bus = self.worker.can_buses[self.bus]
        loop = asyncio.get_running_loop()
        start = loop.time()
        first = self.frames[0].time if self.frames else 0.0
        shift = 0.0  # time taken out of long pauses
        next_check = start + CONTROL_CHECK_S
        burst = 0
        try:
            blocked = self.screening.blocked
            for index, rec in enumerate(self.frames):
                due = start + (rec.time - first) / self.speed - shift
                now = loop.time()
                if due - now > MAX_GAP_S:
                    shift += due - now - MAX_GAP_S
                    due = now + MAX_GAP_S
                if due > now or burst >= BURST_FRAMES:
                    burst = 0
                    try:
                        await asyncio.wait_for(self._stop.wait(), max(0.0, due - loop.time()))
                    except TimeoutError:
                        pass
                else:
                    burst += 1
                if not self.running:
                    return
                if loop.time() >= next_check:
                    next_check = loop.time() + CONTROL_CHECK_S
                    controlled = controlled_devices(self.worker, self.bus)
                    if controlled:
                        self.stop(Message(N_("{devices} came under control"), devices=", ".join(controlled)))
                        return
                if rec.is_error_frame or rec.is_remote_frame:
                    self.skipped += 1
                    continue
                if index in blocked:
                    self.filtered += 1
                    continue
                if can_bus.send(rec.arbitration_id, rec.data, rec.is_extended_id):
                    self.sent += 1
                    if self.measure:
                        self.send_times.append(loop.time())
                else:
                    self.failed += 1
            if self.running:
                self.state = "done"
                self._finish()
        except Exception as exc:  # the replay's own task: whatever ends it is said on its page, with the traceback in the log
            log.exception("replay on %s failed", self.bus)
            if self.running:
                self.state = "failed"
                self.reason = str(exc) or exc.__class__.__name__
                self._finish()


def question(worker: Any, bus: str, frames: Sequence[FrameRecord], screening: Screening, *, name: str,
             speed: float) -> Message:
    """The confirmation a replay asks: how many frames go out onto which bus, what is kept off and why."""
    going = screening.going_out(frames)
    config = worker.plant.buses.get(bus)
    kind = (Message(N_("a simulated bus")) if config is not None and config.simulated
            else Message(N_("a live bus: real devices receive them")))
    duration = (frames[-1].time - frames[0].time) / speed if len(frames) > 1 else 0.0
    text = Message(N_("Replay {n} recorded frame(s) of {name} onto {bus} ({kind}) over {duration:.1f} s at {speed:g} x. "
                      "Every device on the bus acts on them as if this tool sent each one now."),
                   n=going, name=name, bus=bus, kind=kind, duration=duration, speed=speed)
    if screening.blocked:
        return joined([text, Message(" {kept_off}.", kept_off=screening.text())], "")
    return text


async def start_replay(
    worker: Any, bus: str, frames: Sequence[FrameRecord], *, name: str = "recording", speed: float = 1.0,
    session: str = "", user: str = "local", role: str = "engineer", confirmed: bool = False,
) -> Replay:
    """Check, audit and start a replay of ``frames`` onto CAN bus ``bus``.

    :param speed: factor on the recorded speed (:data:`SPEED_MIN` .. :data:`SPEED_MAX`)
    :param session: the browser session that runs it (dead-man rule)
    :param confirmed: the engineer confirmed the question (:func:`question`: how many frames go out)
    :raises PermissionDenied: not an engineer; :raises ReplayError: refused (see :func:`refusal`),
        no frames, none that may go out, or a speed out of range; :raises NeedsConfirmation: not confirmed yet
    """
    from app.gate import WRITE_ROLES

    screening = await asyncio.to_thread(screen, worker, bus, frames)
    if not confirmed and worker.gate.role_now(user, role) in WRITE_ROLES:  # another role is refused and audited below
        _check(worker, bus, frames, screening, name, speed)
        raise NeedsConfirmation(question(worker, bus, frames, screening, name=name, speed=speed),
                                screening.going_out(frames))

    async def action() -> str:
        _check(worker, bus, frames, screening, name, speed)
        replay = Replay(worker, bus, frames, name=name, speed=speed, session=session, user=user, screening=screening)
        replay.start()
        holder.append(replay)
        kept_off = f"; {screening.text()}" if screening.blocked else ""
        return (f"{screening.going_out(frames)} of {len(frames)} frames, {replay.duration_s:.1f} s at {speed:g} x, "
                f"confirmed{kept_off}")

    holder: list[Replay] = []
    await worker.gate.run(action, user=user, role=role, device=bus,
                          describe=f"replay {name} onto {bus} at {speed:g} x", kind="write")
    return holder[0]


def _check(worker: Any, bus: str, frames: Sequence[FrameRecord], screening: Screening, name: str, speed: float) -> None:
    if not SPEED_MIN <= speed <= SPEED_MAX:
        raise ReplayError(Message(N_("speed {speed:g} is outside {low:g}..{high:g} x"), speed=speed, low=SPEED_MIN,
                                  high=SPEED_MAX))
    if not frames:
        raise ReplayError(Message(N_("{name} has no frames to replay"), name=name))
    if not screening.going_out(frames):
        raise ReplayError(Message(N_("nothing of {name} may go out onto {bus}: {reason}"), name=name, bus=bus,
                                  reason=screening.text() or Message(N_("no data frames"))))
    problem = refusal(worker, bus)
    if problem:
        raise ReplayError(problem)


def running_replay(worker: Any, bus: str) -> Replay | None:
    replay = worker.extra_holders.get(holder_name(bus))
    return replay if isinstance(replay, Replay) else None
