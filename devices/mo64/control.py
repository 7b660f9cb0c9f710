"""The MO 64's motion rule without I/O: which telegrams move the boom, what each needs, and the levels.

Sans-I/O in the manner of h11 (see :mod:`devices.control`): the core answers events (an operator's
request or raw telegram, the barrier's answer ack / nak / busy / none, the dead-man supervisor's beat,
time, a session lost) with actions (:class:`Send` this telegram, :class:`~devices.control.Report` this);
it never sends, sleeps or reads a clock. The adapter (:mod:`devices.mo64.adapter`) carries the actions out.

The rules (document 003, chapter 5.2.1; SPEC-NOTES "Operating commands"):

- every telegram that moves the boom (open, close, reverse; pulse or level) asks that the area is clear,
  every time: a confirmation is given with the one request it belongs to and is never remembered
  (not per session, not per page). Deactivating the open level is motion too (page 33: it lets the boom
  close); deactivating a close or reverse level is a stop and is never refused;
- a close or reverse level (``activate``) is held only under the dead-man lease of the operator who set it:
  when the lease is not renewed for ``lease_s`` or the operator's session is lost, the core sends its
  ``deactivate`` at once and again every ``retry_s`` until the barrier acknowledges it. The level counts
  as held from the moment its activate is sent (an activate whose answer was lost may have been carried
  out). The open level is not released by the dead-man rule: releasing it would let an unattended boom
  close (page 33), the unsafe direction;
- a raw telegram (transmit list, replay, a bus tool) is decoded into the declared command it amounts to
  and checked by the same rule; telegrams the barrier sends (ack, nak, busy, syn, the answers 0x05-0x1F)
  and short commands (0x03, layouts not named in the summary) are never sent;
- a session without the engineer role moves nothing and sets nothing: it may only stop (deactivate a
  close or reverse level), as the gate lets every role stop.

No import of asyncio, threading, sockets, clocks or bus libraries (tests/safety/test_control_layering.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from devices.control import LEASE_S, STOP_DEADLINE_S, LeaseState, Report, dead_man
from devices.message import Message, N_, joined
from devices.mo64 import codec
from devices.mo64 import params as model

AREA_CLEAR_RISK = Message(N_("The boom moves: check that nobody stands under it (the area is clear)."))
OPEN_LEVEL_RISK = Message(N_("Deactivating the open level lets the boom close (page 33): check that nobody stands under it "
                             "(the area is clear)."))
EEPROM_RISK = Message(N_("Every setting write wears the barrier's EEPROM (chapter 4: the number of writes is limited). "
                         "Write only what must change."))
# the levels released by the dead-man rule (close and reverse: they keep the boom moving towards a person)
DEAD_MAN_LEVELS = frozenset({codec.Command.CLOSE, codec.Command.REVERSE})
COMMAND_NAMES = {codec.Command.OPEN: N_("open"), codec.Command.CLOSE: N_("close"), codec.Command.REVERSE: N_("reverse")}
# an operating command in words ("open pulse", "close deactivate"): a Message the page words in its language
FUNCTION_WORDS = {codec.Function.PULSE: N_("{command} pulse"), codec.Function.ACTIVATE: N_("{command} activate"),
                  codec.Function.DEACTIVATE: N_("{command} deactivate")}
TOOL_STOPS = Message(N_("the tool stops"))  # why the close and reverse levels are deactivated as the tool ends
RETRY_S = 0.2  # a dead-man deactivation the barrier did not acknowledge is sent again this often
WRITE_ROLES = frozenset({"engineer"})
__all__ = ["LEASE_S", "STOP_DEADLINE_S", "Report"]


# -- what a telegram amounts to -------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Meaning:
    """What a telegram to the barrier does: ``kind`` read / stop / write / motion; ``risk`` the question it
    asks each time ("" none); ``refused`` why it is never sent ("" it may be)."""

    name: str
    kind: str = "read"
    risk: str = ""
    refused: str = ""
    command: codec.Command | None = None
    function: codec.Function | None = None

    @property
    def motion(self) -> bool:
        return self.kind == "motion"


def command_words(cmd: codec.Command, fn: codec.Function) -> Message:
    """An operating command in words (``open pulse``), worded by its reader (:mod:`devices.message`)."""
    return Message(FUNCTION_WORDS[fn], command=Message(COMMAND_NAMES[cmd]))


def operation(cmd: codec.Command, fn: codec.Function) -> Meaning:
    """An operating command (chapter 5.2.1): every one moves the boom but the release of a close or reverse level."""
    name = command_words(cmd, fn)
    if fn is codec.Function.DEACTIVATE and cmd in DEAD_MAN_LEVELS:
        return Meaning(name, "stop", command=cmd, function=fn)
    risk = OPEN_LEVEL_RISK if fn is codec.Function.DEACTIVATE else AREA_CLEAR_RISK
    return Meaning(name, "motion", risk, command=cmd, function=fn)


def meaning(telegram: bytes) -> Meaning:
    """A raw telegram (``type`` and payload, without SD, LE, addresses and checksum) as the command it amounts to."""
    telegram = bytes(telegram)
    if not telegram:
        return Meaning("empty telegram", "write", refused="an empty telegram has no type: nothing to send")
    frame = codec.Frame(telegram[0], telegram[1:])
    try:
        request = codec.decode_request(frame)
    except codec.CodecError as exc:
        if telegram[0] in codec.REPLY_TYPES or telegram[0] in codec.ANSWER_TYPES:
            return Meaning(f"telegram 0x{telegram[0]:02X}", "write",
                           refused=f"telegram type 0x{telegram[0]:02X} of this length is one the barrier sends "
                                   "(an answer or a reply): this tool never sends it")
        return Meaning(f"telegram 0x{telegram[0]:02X}", "write", refused=f"not a telegram the barrier takes: {exc}")
    if request.kind is codec.RequestType.COMMAND:
        return operation(request.command, request.function)
    if request.kind is codec.RequestType.QUERY:
        return Meaning(f"query 0x{request.query:02X}", "read")
    if request.kind is codec.RequestType.SHORT_COMMAND:
        return Meaning(f"short command 0x{request.code:02X}", "write",
                       refused="short commands (0x03) are not named in the manual's summary: nothing can check what "
                               "they do, so they are never sent")
    if request.setting is None:
        return Meaning(f"setting 0x{request.kind:02X} 0x{request.selector:02X}", "write",
                       refused=f"setting selector 0x{request.kind:02X} 0x{request.selector:02X} is not known: a wrong "
                               "selector writes another EEPROM setting")
    # a flag the value switches off (force monitoring, light-barrier test, ...) is named first (devices/mo64/params.py)
    questions = model.safety_questions(request.setting.key, model.setting_int(request.setting.key, request.value))
    return Meaning(Message(N_("set {setting}"), setting=Message(request.setting.name)), "write",
                   joined(questions + ([EEPROM_RISK] if request.setting.eeprom else []), " "))


# -- actions and answers -----------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Send:
    """Send ``telegram`` (unframed) and report its answer with :meth:`Mo64Control.answered` and ``ref``."""

    telegram: bytes
    words: str
    session: str
    ref: int
    kind: str = "motion"
    why: str = ""  # "dead-man: ..." for the core's own deactivations


@dataclass(frozen=True, slots=True)
class Decision:
    """The answer to a request: ``refused`` why not; ``question`` the risk to confirm first (nothing sent)."""

    refused: str = ""
    question: str = ""
    actions: tuple = ()

    @property
    def ok(self) -> bool:
        return not self.refused and not self.question

    @property
    def send(self) -> Send | None:
        return next((a for a in self.actions if isinstance(a, Send)), None)


ANSWERS = ("ack", "nak", "busy", "lost")


@dataclass
class Level:
    """A level this tool activated: the barrier keeps it until it is deactivated."""

    command: codec.Command
    session: str
    lease: LeaseState
    state: str = "activating"  # activating (sent), active (ack), deactivating (deactivate sent, no ack yet)
    gone_at: float | None = None  # when its operator was gone (lease lapsed, session lost)
    next_try: float | None = None  # when a deactivation not acknowledged is sent again

    @property
    def dead_man(self) -> bool:
        return self.command in DEAD_MAN_LEVELS


@dataclass
class _Pending:
    command: codec.Command | None
    function: codec.Function | None
    session: str
    words: str


@dataclass
class Mo64Control:
    """The motion rule of one MO 64 (see the module's text)."""

    lease_s: float = LEASE_S
    retry_s: float = RETRY_S
    levels: dict = field(default_factory=dict)  # codec.Command -> Level
    pending: dict = field(default_factory=dict)  # ref -> _Pending
    _ref: int = 0

    # -- queries ---------------------------------------------------------------------------------
    def holders(self) -> set[str]:
        """Sessions whose close or reverse level is held (the dead-man supervisor watches them)."""
        return {lv.session for lv in self.levels.values() if lv.dead_man and lv.state != "deactivating"}

    def held(self) -> dict:
        """Levels held in the barrier by this tool: command -> session."""
        return {cmd: lv.session for cmd, lv in self.levels.items()}

    # -- operator events -------------------------------------------------------------------------
    def request(self, session: str, cmd: codec.Command | int, fn: codec.Function | int, *, confirmed: bool = False,
                role: str = "engineer", now: float) -> Decision:
        """An operating command; ``confirmed``: the operator confirmed its risk for this very request."""
        return self._run(session, operation(codec.Command(cmd), codec.Function(fn)), confirmed, role, now)

    def raw(self, session: str, telegram: bytes, *, confirmed: bool = False, role: str = "engineer",
            now: float) -> Decision:
        """A raw telegram (unframed) from a bus tool: the same rule as the command it amounts to."""
        what = meaning(telegram)
        if what.refused:
            return Decision(refused=f"{what.name}: {what.refused}")
        if what.command is not None:
            return self._run(session, what, confirmed, role, now)
        if what.kind != "read" and role not in WRITE_ROLES:
            return Decision(refused=f"the {role or 'anonymous'} role may not send {what.name}")
        if what.risk and not confirmed:
            return Decision(question=what.risk)
        return Decision(actions=(self._send(bytes(telegram), what.name, session, None, None, what.kind),))

    def _run(self, session: str, what: Meaning, confirmed: bool, role: str, now: float) -> Decision:
        cmd, fn = what.command, what.function
        if what.kind != "stop" and role not in WRITE_ROLES:
            return Decision(refused=f"the {role or 'anonymous'} role may not move the boom ({what.name})")
        if what.risk and not confirmed:
            return Decision(question=what.risk)
        if fn is codec.Function.ACTIVATE:
            lease = LeaseState(self.lease_s)
            lease.grant(now)  # pressed just now: its operator is alive
            self.levels[cmd] = Level(cmd, session, lease)  # held before sending: a lost answer may have set it
        elif fn is codec.Function.DEACTIVATE and cmd in self.levels:
            self.levels[cmd].state = "deactivating"
        return Decision(actions=(self._send(codec.encode_command(cmd, fn), what.name, session, cmd, fn, what.kind),))

    def _send(self, telegram: bytes, words: str, session: str, cmd, fn, kind: str, why: str = "") -> Send:
        self._ref += 1
        self.pending[self._ref] = _Pending(cmd, fn, session, words)
        return Send(telegram, words, session, self._ref, kind, why)

    def answered(self, ref: int, answer: str, now: float) -> list:
        """The barrier's answer to the telegram ``ref``: "ack", "nak", "busy" or "lost" (none, or the line failed)."""
        pending = self.pending.pop(ref, None)
        if pending is None or pending.command is None:
            return []
        cmd, fn = pending.command, pending.function
        level = self.levels.get(cmd)
        if fn is codec.Function.ACTIVATE and level is not None and level.session == pending.session:
            if answer == "ack" and level.state == "activating":
                level.state = "active"
            elif answer in ("nak", "busy") and level.state == "activating":
                del self.levels[cmd]  # refused: the barrier holds no level
            return []
        if fn is codec.Function.DEACTIVATE and level is not None and level.state == "deactivating":
            if answer == "ack":
                del self.levels[cmd]
                return []
            if level.gone_at is not None:  # the dead-man rule's release: again until acknowledged
                level.next_try = now + self.retry_s
                return [Report("error", Message(N_("{command}: {answer}: the {level} level is still active in the barrier; "
                                                   "sent again every {seconds:g} s until it is acknowledged"),
                                                command=pending.words, answer=answer, level=Message(COMMAND_NAMES[cmd]),
                                                seconds=self.retry_s))]
            level.state = "active" if answer in ("nak", "busy") else level.state  # the operator's own: still held
            if answer == "lost":
                level.next_try = now + self.retry_s
            return []
        return []

    def session_lost(self, session: str, reason: str, now: float) -> list:
        """The operator of ``session`` is gone: release its close and reverse levels now."""
        actions: list = []
        for level in list(self.levels.values()):
            if level.session != session or not level.dead_man:
                continue
            if level.state != "deactivating":
                actions += self._release(level, dead_man(reason), now)
            elif level.gone_at is None:  # a stop is on its way: should it be refused, it is sent again
                level.gone_at = now
        return actions

    def beat(self, alive: set[str], now: float) -> list:
        """The dead-man supervisor: ``alive`` confirmed they are alive; their leases are renewed."""
        for level in self.levels.values():
            if level.dead_man and level.state != "deactivating" and level.session in alive:
                level.lease.renew(now)
        return self.tick(now)

    def tick(self, now: float) -> list:
        """Time passes: a lapsed lease releases its level; a release not acknowledged is sent again."""
        actions: list = []
        for level in list(self.levels.values()):
            if not level.dead_man:
                continue
            if level.state != "deactivating":
                if not level.lease.valid(now):
                    actions += self._release(level, Message(N_("dead-man: the lease lapsed (the operator stopped "
                                                               "confirming it is alive, or this program stalled)")), now)
            elif level.next_try is not None and now >= level.next_try:
                level.next_try = None
                cmd = level.command
                actions.append(self._send(codec.encode_command(cmd, codec.Function.DEACTIVATE),
                                          command_words(cmd, codec.Function.DEACTIVATE), level.session, cmd,
                                          codec.Function.DEACTIVATE, "stop", Message(N_("dead-man: sent again"))))
        return actions

    def _release(self, level: Level, why: str, now: float) -> list:
        level.state, level.gone_at, level.next_try = "deactivating", now, None
        cmd = level.command
        return [Report("warning", Message(N_("{why}; deactivating {level}"), why=why, level=Message(COMMAND_NAMES[cmd]))),
                self._send(codec.encode_command(cmd, codec.Function.DEACTIVATE),
                           command_words(cmd, codec.Function.DEACTIVATE),
                           level.session, cmd, codec.Function.DEACTIVATE, "stop", why)]

    def closing(self) -> list[Send]:
        """The tool stops: the deactivations of every close and reverse level (sent as the line closes)."""
        sends = []
        for level in list(self.levels.values()):
            if level.dead_man:
                cmd = level.command
                sends.append(self._send(codec.encode_command(cmd, codec.Function.DEACTIVATE),
                                        command_words(cmd, codec.Function.DEACTIVATE), level.session, cmd,
                                        codec.Function.DEACTIVATE, "stop", TOOL_STOPS))
                del self.levels[cmd]
        return sends

    def forget(self, cmd: codec.Command) -> None:
        """A level the barrier no longer holds (acknowledged by another path)."""
        self.levels.pop(cmd, None)
