"""A Bauer MO 64 barrier on a LogiTed line (``type = "mo64"`` on ``logited-tcp`` or ``logited-rs485``).

Document 003, chapters 2 to 5, with the readings of SPEC-NOTES "Bauer MO 64" (all in
:mod:`devices.mo64.codec`). The worker calls :meth:`Mo64Adapter.poll` every ``poll_period``:
gate state, barrier status and position every cycle (every :data:`MONITORED_POLL_EVERY`-th
cycle while change monitoring delivers them unsolicited), the counters in turn (one a cycle at
start, after a command and when the gate state changed, else one every :data:`COUNTER_EVERY`-th
cycle: they change only with the barrier's use), identity and settings once and after writes. Unsolicited telegrams (chapter 3: the barrier sends on change
once configured) arrive through ``line.listeners`` and are published at once with an event.

Commands (chapter 5.2.1): open / close / reverse as a pulse, or as a level (activate, which
stays in the barrier until deactivated). Settings (chapter 5.2.4-5.2.8): busy, syn then ack,
nak handled; every write is read back and counted per session (EEPROM wear, chapter 4).
"""

from __future__ import annotations

import asyncio
import time
from typing import Any

from devices.control import Report
from devices.decoding import decoded, malformed
from devices.live import DeviceState, session_tag
from devices.message import Message, N_, as_word, joined, message_of
from devices.mo64 import codec
from devices.mo64.control import DEAD_MAN_LEVELS, TOOL_STOPS, Mo64Control, Send
from devices.mo64.facts import (
    BUSY_TEXT,
    NAMES,
    P_CONFIRMED,
    P_CONNECTION,
    P_EEPROM,
    P_ERROR_LEVELS,
    P_LAST_REPLY,
    P_LATE,
    P_LEVELS,
    P_LEVELS_UNAVAILABLE,
    P_LINE,
    P_MONITORING,
    P_POLLING,
    P_QUERY_FORM,
    P_UNAVAILABLE,
    P_UNEXPECTED,
    P_VERIFIED,
    POLLING_SLOWER,
    QUERY_FORM_WORDS,
    CommandError,
    EepromWrites,
    ErrorMemoryLevel,
    HeldLevel,
    LineFacts,
    NeedsConfirmation,
    from_json,
    to_json,
    value_text,
)
from devices.mo64.params import PARAMS
from devices.mo64.settings import MONITOR_FLAGS, SYN_ACK_TIMEOUT_S, Mo64Settings
from devices.transport import SerialClosed, SerialLineError, SerialTimeout, TelegramLine, TelegramTcpLine

MONITORED_POLL_EVERY = 5  # gate state and position, while change monitoring delivers them, every 5th cycle
MONITOR_FRESH_S = 30.0  # change monitoring counts as delivering this long after its last telegram
LATE_WINDOW_S = 30.0  # a telegram of the type of a query that timed out this recently is its late answer
OPTIONAL_RETRY_S = (10.0, 30.0, 60.0, 300.0)  # a start-up read that was refused or unanswered is tried again
# the counters read in turn (service, maintenance, vehicle, loop-adjust, operating hours) change only when the barrier
# is used: once each was read (at start, after a command, after a change of the gate state: one a cycle) one of
# them is read every COUNTER_EVERY-th cycle, and each is stale after STALE_READINGS of its own period
COUNTER_EVERY = 4
STARTUP_READS_PER_CYCLE = 3  # start-up reads after the live queries, a few per cycle: live values come first
UNAVAILABLE = "not available on this unit"
# chapter 5.1.9 (SPEC-NOTES "Change monitoring"): the flag that makes the barrier send telegram type t
MONITOR_BITS = {0x07: 0, 0x0A: 1, 0x0B: 2, 0x0C: 3, 0x17: 4, 0x1C: 5, 0x1D: 6}
SAFETY_BITS = ("LS", "Baum ab", "F_ereignis")  # read every cycle, whatever change monitoring does
# A level that keeps the boom moving towards a person is released by the dead-man rule: the close and
# reverse levels. The open level is NOT released: deactivating it lets an unattended boom close
# (chapter 5.2.1, page 33: the level prevents closing until deactivated), the unsafe direction.
# the dead-man rule clears close and reverse levels of a lost session; an open level stays, since
# clearing it would let an unattended boom close (page 33: the level holds the barrier open)
HELD_LEVELS = DEAD_MAN_LEVELS  # devices/mo64/control.py holds the rule
COMMAND_NAMES = {codec.Command.OPEN: "open", codec.Command.CLOSE: "close", codec.Command.REVERSE: "reverse"}
LIVE_QUERIES = (codec.Q_GATE_STATE, codec.Q_BARRIER_STATUS, codec.Q_BARRIER_POSITION)
ROTATING_QUERIES = (codec.Q_SERVICE_COUNTER, codec.Q_MAINTENANCE_COUNTER, codec.Q_VEHICLE_COUNTER,
                    codec.Q_LOOP_ADJUST, codec.Q_OPERATING_HOURS)
IDENTITY_QUERIES = (codec.Q_DEVICE, codec.Q_PROGRAM_VERSION, codec.Q_SERIAL_NUMBER, codec.Q_MAC,
                    codec.Q_OPERATING_HOURS)
SETTING_QUERIES = tuple(dict.fromkeys([s.query for s in codec.SETTINGS.values()]
                                      + [codec.Q_INDUCTION_LOOPS, codec.Q_DIRECTION_LOGICS, codec.Q_COUNTING,
                                         codec.Q_DEC_BT, codec.Q_LOOP_PERIODS]))


class Mo64Adapter(Mo64Settings):
    """One MO 64 barrier on a LogiTed TCP or RS485 line."""

    params = PARAMS
    backup_available = True

    def __init__(self, config, state: DeviceState, line: TelegramLine | TelegramTcpLine):
        self.config = config
        self.state = state
        self.line = line
        line_options = line.options
        self.rs485 = "address" in config.options or "master_address" in line_options or "baudrate" in line_options
        self.framing = codec.RS485 if self.rs485 else codec.TCP
        self.transport = "logited-rs485" if self.rs485 else "logited-tcp"
        self.address = config.options.get("address")
        self.master = int(line_options.get("master_address", codec.RS485_LAYOUT.master_address))
        self.masters = {self.master, int(line_options.get("next_master", self.master + 1))}  # the masters of a shared line
        self.core = Mo64Control()  # the motion rule: what asks, the levels and their dead-man (sans-I/O)
        # each setting write wears the barrier's EEPROM (document: "EEPROM"): restore says how many
        self.restore_wear = Message(N_("each written setting wears the barrier's EEPROM"))
        self.eeprom_writes: dict[str, int] = {}  # EEPROM writes of each session (eeprom_writes_total: all of them)
        self.last_reply = ""
        self.error_memory: list[dict] = []
        self.settings: dict[str, Any] = {}
        # start-up reads (identity, settings, modes, error memory levels): each optional, retried with backoff
        self._reads: dict[tuple, dict] = {}
        for index in IDENTITY_QUERIES + SETTING_QUERIES:
            self._reads.setdefault(("query", index), {"state": "pending", "failures": 0, "next": 0.0})
        for level in range(codec.ERROR_MEMORY_LEVELS):
            self._reads[("error memory", level)] = {"state": "pending", "failures": 0, "next": 0.0}
        self._optional_live: dict[int, dict] = {}  # rotating counters the unit refused: index -> backoff
        self.query_form: str | None = None  # "document" or "short", once the unit answered one (SPEC-NOTES)
        self.verified_selectors: set[str] = set()  # assumed selectors an engineer confirmed for this unit
        self.late_answers = 0
        self.unexpected_telegrams = 0
        self._timed_out: dict[int, float] = {}  # answer type -> when its query timed out
        self._cycle = 0
        self._rotate = 0
        self._counters_due: list[int] = list(ROTATING_QUERIES)  # read one a cycle until none is left
        self._monitor_last: float | None = None
        self._stop_tasks: set[asyncio.Task] = set()
        self.poll_period = float(line_options.get("poll_period", 0.5) or 0.5)
        state.stale_after = 5.0
        state.params = PARAMS  # settings by name: project, drift, restore (devices/mo64/params.py)
        state.registers_periodic = False  # settings are read at start and after writes: they do not age
        fact = state.fact
        fact(P_LINE, LineFacts(self.transport, self.rs485, self.address, self.master),
             text=f"RS485 bus address {self.address}, this tool is master {self.master}" if self.rs485 else "TCP")
        fact(P_CONNECTION, "not connected")
        fact(P_POLLING, "every cycle")
        fact(P_QUERY_FORM, None, text=QUERY_FORM_WORDS[None])
        fact(P_LATE, 0)
        fact(P_UNEXPECTED, 0)
        fact(P_UNAVAILABLE, ())
        fact(P_LEVELS_UNAVAILABLE, ())
        fact(P_LAST_REPLY, "", text="-")
        fact(P_ERROR_LEVELS, ())
        fact(P_MONITORING, "unknown")
        self._publish_levels()
        self._publish_writes()
        fact(P_VERIFIED, ())
        fact(P_CONFIRMED, ())
        line.listeners.append(self._unsolicited)
        line.closing.append(self.closing_frames)
        line.describe = self.describe_telegram

    # -- the line -----------------------------------------------------------------------------------
    def _frame(self, telegram: bytes) -> bytes:
        if self.rs485:
            return codec.encode_frame(telegram, codec.RS485, da=self.address, sa=self.master)
        return codec.encode_frame(telegram, codec.TCP)

    def _decode(self, telegram: bytes) -> codec.Frame | None:
        try:
            frame = codec.decode_frame(telegram, self.framing)
        except codec.CodecError:
            return None
        if self.rs485 and (frame.is_token or frame.da != self.master or frame.sa != self.address):
            return None
        return frame

    def describe_telegram(self, telegram: bytes) -> str:
        """The bus monitor's decoding of a telegram on the line (undecodable ones say why): on a shared
        RS485 line a telegram to a barrier (not to a master) is another master's request."""
        try:
            frame = codec.decode_frame(telegram, self.framing)
            to_device = self.rs485 and frame.da is not None and frame.da not in self.masters
            return codec.describe(frame, to_device)
        except codec.CodecError as exc:
            return f"cannot decode: {exc}"

    def _matcher(self, types: set[int]):
        def answers(telegram: bytes) -> bool:
            frame = self._decode(telegram)
            return frame is not None and frame.type in types
        return answers

    async def _transact(self, telegram: bytes, types: set[int], describe: str, **options) -> codec.Answer:
        self.state.counters.requests += 1
        try:
            raw = await self.line.transact(self._frame(telegram), self._matcher(types), describe=describe, **options)
        except SerialTimeout:
            self.state.counters.timeouts += 1
            raise
        except SerialClosed as exc:
            self.state.mark_offline(str(exc))
            raise
        frame = self._decode(raw)
        answer = codec.decode_answer(frame)
        self.state.counters.responses += 1
        self.state.mark_seen()
        if answer.error and answer.reply is None:
            malformed(self.state)
        return answer

    async def query(self, index: int, level: int | None = None) -> codec.Answer:
        """One query (table 21) and its answer telegram, published; nak raises :class:`CommandError`.

        Until the unit has answered one, the document's form ``02 Auswahl index`` (page 33) is tried
        first and the short form ``02 Auswahl`` after a nak or no answer; the form the unit took is
        kept (``query_form``, shown on the page). SPEC-NOTES "Query form".
        """
        answer_type = index + codec.QUERY_ANSWER_OFFSET
        what = telegram_words(answer_type, level)
        forms = [self.query_form] if self.query_form else list(codec.QUERY_FORMS)
        telegrams = list(dict.fromkeys(codec.encode_query(index, level, form) for form in forms))
        answer = None
        for n, telegram in enumerate(telegrams):
            last = n == len(telegrams) - 1
            try:
                answer = await self._transact(telegram, {answer_type, codec.Reply.NAK}, f"query {what}")
            except SerialTimeout:
                self._timed_out[answer_type] = time.monotonic()
                if last:
                    raise
                continue
            if answer.reply is not codec.Reply.NAK:
                if self.query_form is None and len(telegrams) > 1:
                    self.query_form = forms[n]
                    self.state.fact(P_QUERY_FORM, self.query_form, text=QUERY_FORM_WORDS[self.query_form])
                    self.state.event("info", Message(N_("queries: the unit takes the document's form 02 Auswahl index (page 33)"))
                                     if forms[n] == "document" else Message(N_("queries: the unit takes the short form 02 "
                                                                                "Auswahl (the document's form was refused)")))
                break
        if answer.reply is codec.Reply.NAK:
            self._reply(Message(N_("query {telegram}"), telegram=what), "nak")
            raise CommandError(f"the barrier answered the query for {what} with nak")
        self._publish(answer)
        return answer

    def _reply(self, what: str, result: str) -> None:
        """The barrier's last answer: what was sent and what came back (``open pulse: ack``), a Message its page
        words (a reply word, the document's ``tele_ack``, as it is; a telegram by its name)."""
        text = Message("{what}: {result}", what=what, result=Message(result))
        self.last_reply = text
        self.state.fact(P_LAST_REPLY, text, text=text or "-")

    # -- unsolicited telegrams (chapter 3, change monitoring) ------------------------------------------
    def armed(self, answer_type: int) -> bool:
        """Whether the barrier was told to send telegram ``answer_type`` on change (chapter 5.1.9): its flag
        in the change monitoring read from the unit, and for the barrier status a status mask that is
        not 0 (page 18: factory mask 0 watches nothing). Over TCP only (chapter 3)."""
        if self.rs485 or answer_type not in MONITOR_BITS:
            return False
        flags = self.settings.get("change_monitoring")
        if not isinstance(flags, int) or not flags >> MONITOR_BITS[answer_type] & 1:
            return False
        if answer_type == 0x07:
            mask = self.settings.get("status_mask")
            return isinstance(mask, int) and mask != 0
        return True

    def _unsolicited(self, telegram: bytes) -> None:
        frame = self._decode(telegram)
        if frame is None:
            if not self.rs485:
                malformed(self.state)
            return
        answer = decoded(self.state, codec.decode_answer, frame, None)
        if answer is None:
            return
        now = time.monotonic()
        if answer.reply is not None:
            self._count_late(Message(N_("{telegram} that answers no request"), telegram=Message(answer.name)))
            return
        asked = self._timed_out.pop(answer.type, None)
        if asked is not None and now - asked < LATE_WINDOW_S:
            self._count_late(Message(N_("{telegram} after its query timed out"),  # not change monitoring
                                     telegram=Message(answer.name)))
        elif self.armed(answer.type):
            self._monitor_last = now
        else:
            self.unexpected_telegrams += 1
            self.state.fact(P_UNEXPECTED, self.unexpected_telegrams)
        self.state.mark_seen()
        before = self.state.points.get(NAMES.get(answer.type, ""))
        self._publish(answer)
        after = self.state.points.get(NAMES.get(answer.type, ""))
        text = as_word(after.text, answer.name) if after is not None and after.text is not None else Message(answer.name)
        if answer.error:
            self.state.event("warning", Message(N_("change reported: {telegram}: {error}"), telegram=Message(answer.name), error=answer.error))
        elif before is None or before.raw != after.raw:
            self.state.event("info", Message(N_("change reported: {telegram} = {value}"), telegram=Message(answer.name), value=text))

    # -- publishing -------------------------------------------------------------------------------------
    def _publish(self, answer: codec.Answer) -> None:
        pub = self.state.publish
        now = time.time()
        t, x = answer.type, answer.value
        name = NAMES.get(t, answer.name)
        if answer.error:
            pub(name, None, raw=answer.payload.hex(" "), text=f"raw {answer.payload.hex(' ')} ({answer.error})", time=now)
            return
        if t == 0x0C:
            before = self.state.points.get("Gate state")
            pub("Gate state", int(x), raw=int(x), text=x.name or f"undefined state {int(x)}", time=now)
            if before is not None and before.raw != int(x):
                self.counters_next()  # the boom moved or stopped: the counters may have counted
        elif t == 0x1D:
            pos = int(x)
            pub("Position", None if pos == codec.POSITION_UNKNOWN else pos, "%", raw=pos,
                text="unknown" if pos == codec.POSITION_UNKNOWN else f"{pos} %", time=now)
        elif t == 0x07:
            bits = x["status"]
            pub("Barrier status", int(bits), raw=int(bits), text=value_text(t, x), time=now)
            for key, bit in bits.fields.items():
                pub(key, bool(bit), raw=int(bool(bit)), time=now)
        elif t == 0x1F:
            for loop, count in zip("ABC", x):
                pub(f"Loop-adjust counter {loop}", int(count), raw=int(count), time=now, every=self._rotation_s)
        elif t == 0x17:
            self._error_entry(x)
        elif t == 0x1C:
            pub("Vehicle counter", int(x), raw=int(x), text=Message(N_("{count} (RAM only: 0 after power-up)"), count=int(x)),
                time=now, every=self._rotation_s)
        elif t in (0x0A, 0x0B, 0x16):  # counters read in turn: stale after a few of their own rounds
            pub(name, int(x), "h" if t == 0x16 else "", raw=int(x), time=now, every=self._rotation_s)
        elif t in (0x14, 0x06, 0x1A):
            pub(name, int(x), raw=int(x), time=now, periodic=False)
        else:  # identity, settings and modes: read at start-up and after writes, they do not age
            pub(name, to_json(x), raw=to_json(x), text=value_text(t, x), time=now, periodic=False)
        setting = next((s for s in codec.SETTINGS.values() if s.query + codec.QUERY_ANSWER_OFFSET == t), None)
        if setting is not None:
            self.settings[setting.key] = to_json(x)
        self.publish_params(answer)  # the parameter model's raw values (devices/mo64/settings.py)
        if t == 0x09:
            self.state.fact(P_MONITORING, "on" if int(x) else "off")

    @property
    def _rotation_s(self) -> float:
        """How often one counter read in turn comes round (one every COUNTER_EVERY-th cycle)."""
        return len(ROTATING_QUERIES) * self.poll_period * COUNTER_EVERY

    def counters_next(self) -> None:
        """Read every counter in turn from the next cycle on, one a cycle (after a command, a change of the gate state)."""
        self._counters_due = list(ROTATING_QUERIES)

    def _counter_now(self) -> int | None:
        """The counter this cycle reads, if any."""
        if self._counters_due:
            return self._counters_due.pop(0)
        if self._cycle % COUNTER_EVERY:
            return None
        index = ROTATING_QUERIES[self._rotate % len(ROTATING_QUERIES)]
        self._rotate += 1
        return index

    def _error_entry(self, x: Any) -> None:
        if isinstance(x, (list, tuple)):
            entries = [{"level": n, "flags": int(e["flags"]), "timestamp_h": int(e["timestamp_h"])} for n, e in enumerate(x)]
        else:
            entries = [e for e in self.error_memory if e["level"] != int(x["index"])]
            entries.append({"level": int(x["index"]), "flags": int(x["flags"]), "timestamp_h": int(x["timestamp_h"])})
        entries.sort(key=lambda e: e["level"])  # level 0 holds the newest (chapter 5.1.23)
        self.error_memory = entries
        self.state.fact(P_ERROR_LEVELS, tuple(ErrorMemoryLevel(e["level"], e["flags"], e["timestamp_h"]) for e in entries))
        newest = entries[0] if entries else None
        older = next((e["flags"] for e in entries if newest is not None and e["level"] == newest["level"] + 1), None)
        # the newest level in the words of the page's error memory table (codec.error_level_meaning)
        self.state.publish("Error memory", None if newest is None else newest["flags"],
                           raw=None if newest is None else newest["flags"], periodic=False,
                           text="empty" if newest is None else
                           f"newest ({newest['timestamp_h']} h): "
                           f"{codec.error_level_meaning(newest['flags'], newest['timestamp_h'], older)}")

    # -- polling -----------------------------------------------------------------------------------------
    def _count_late(self, what: str) -> None:
        self.late_answers += 1
        self.state.fact(P_LATE, self.late_answers)
        self.state.event("warning", Message(N_("late answer: {what}"), what=what))

    @property
    def monitoring_active(self) -> bool:
        return self._monitor_last is not None and time.monotonic() - self._monitor_last < MONITOR_FRESH_S

    def _slowed(self, index: int) -> bool:
        """Gate state and position are asked only every few cycles while the barrier reports their changes;
        the barrier status never is (its safety bits show within one poll period)."""
        if index == codec.Q_BARRIER_STATUS or not self.monitoring_active:
            return False
        return self.armed(index + codec.QUERY_ANSWER_OFFSET) and self._cycle % MONITORED_POLL_EVERY != 0

    async def poll(self) -> None:
        """One cycle: the live queries first, each on its own (a nak or no answer of one never holds up
        the others), a counter in turn when one is due (:meth:`_counter_now`), then a few of the start-up reads
        that are still due. Faults are named in the state, never raised."""
        if isinstance(self.line, TelegramTcpLine) and self.line.released:
            self.state.fact(P_CONNECTION, "released")
            return
        problems: list[str] = []
        try:
            for index in LIVE_QUERIES:
                if self._slowed(index):
                    continue
                try:
                    await self.query(index)
                except (CommandError, SerialTimeout, codec.CodecError) as exc:
                    problems.append(message_of(exc))
            index = self._counter_now()
            if index is not None:
                await self._optional(self._optional_live.setdefault(index, {"state": "pending", "failures": 0, "next": 0.0}),
                                     index, NAMES.get(index + codec.QUERY_ANSWER_OFFSET))
            due = [key for key, read in self._reads.items() if read["state"] != "done" and read["next"] <= time.monotonic()]
            for kind, n in due[:STARTUP_READS_PER_CYCLE]:
                if kind == "query":
                    await self._optional(self._reads[(kind, n)], n, NAMES.get(n + codec.QUERY_ANSWER_OFFSET))
                else:
                    await self._optional(self._reads[(kind, n)], codec.Q_ERROR_MEMORY, None, level=n)
            if problems:
                self.state.error(Message(N_("poll: {problems}"), problems=joined(problems, "; ")), log=False)
        except (SerialLineError, codec.CodecError) as exc:
            self.state.error(f"poll: {exc}", log=False)
        finally:
            self._act(self.core.tick(time.monotonic()))  # a lapsed lease, a release to send again
            self._cycle += 1
            self._show_reads()
            self.state.fact(P_CONNECTION, "not connected" if isinstance(self.line, TelegramTcpLine) and not self.line.connected else "connected")
            self.state.fact(P_POLLING, POLLING_SLOWER if self.monitoring_active else "every cycle")

    async def _optional(self, read: dict, index: int, point: str | None, level: int | None = None) -> bool:
        """One optional read: a nak marks it not available on this unit, no answer as not answered; either is
        tried again later with backoff (:data:`OPTIONAL_RETRY_S`). A closed line ends the cycle (raised)."""
        try:
            await self.query(index, level)
        except (CommandError, SerialTimeout) as exc:
            read["failures"] += 1
            read["state"] = UNAVAILABLE if isinstance(exc, CommandError) else "no answer"
            read["next"] = time.monotonic() + OPTIONAL_RETRY_S[min(read["failures"], len(OPTIONAL_RETRY_S)) - 1]
            if point is not None and isinstance(exc, CommandError):
                entry = self.state.points.get(point)
                if entry is None or entry.value is None:
                    self.state.publish(point, None, text=UNAVAILABLE, periodic=False)
            return False
        read["state"] = "done"
        read["failures"] = 0
        return True

    def _show_reads(self) -> None:
        names = [NAMES.get(key[1] + codec.QUERY_ANSWER_OFFSET, f"query 0x{key[1]:02X}")
                 for key, read in [*self._reads.items(), *((("query", i), r) for i, r in self._optional_live.items())]
                 if key[0] == "query" and read["state"] == UNAVAILABLE]
        self.state.fact(P_UNAVAILABLE, tuple(sorted(set(names))))
        self.state.fact(P_LEVELS_UNAVAILABLE, tuple(
            level for (kind, level), read in self._reads.items() if kind == "error memory" and read["state"] == UNAVAILABLE))

    async def read_settings(self) -> dict[str, Any]:
        for index in SETTING_QUERIES:
            await self._optional(self._reads[("query", index)], index, NAMES.get(index + codec.QUERY_ANSWER_OFFSET))
        self._show_reads()
        return dict(self.settings)

    async def read_error_memory(self) -> list[dict]:
        """The 10 levels (chapter 5.1.23), newest first; the level byte of the query is an assumption. A level
        the unit refuses is shown as not available; the others are read."""
        for level in range(codec.ERROR_MEMORY_LEVELS):
            await self._optional(self._reads[("error memory", level)], codec.Q_ERROR_MEMORY, None, level=level)
        self._show_reads()
        return list(self.error_memory)

    # -- commands (chapter 5.2.1), carried out as devices/mo64/control.py says ---------------------------------
    @property
    def levels(self) -> dict[codec.Command, str]:
        """The levels this tool activated and the barrier holds until deactivated: command -> session."""
        return self.core.held()

    @property
    def motion_confirmed(self) -> frozenset[str]:
        """Sessions remembered as having confirmed motion: none, ever (each motion asks again)."""
        return frozenset()

    def _decided(self, decision) -> Send:
        if decision.question:
            raise NeedsConfirmation(Message(N_("{question} Confirm it for this command (each motion asks again)."),
                                            question=decision.question))
        if decision.refused:
            raise CommandError(decision.refused)
        self._act([a for a in decision.actions if not isinstance(a, Send)])
        return decision.send

    async def command(self, session: str, command: int, function: int = codec.Function.PULSE,
                      confirmed: bool = False, role: str = "engineer") -> str:
        """Open, close or reverse as a pulse or a level; the answer ack or nak is returned and shown.

        ``confirmed``: the operator confirmed that the area is clear for this very command (a motion
        asks each time; releasing a close or reverse level is a stop and asks nothing)."""
        cmd, fn = codec.Command(command), codec.Function(function)
        send = self._decided(self.core.request(session, cmd, fn, confirmed=confirmed, role=role, now=time.monotonic()))
        self._publish_levels()
        answer = await self._carry(send, {codec.Reply.ACK, codec.Reply.NAK, codec.Reply.BUSY})
        result = answer.reply.name.lower() if answer.reply is not None else answer.name
        self._reply(send.words, result)
        if answer.reply is not codec.Reply.ACK:
            self.state.event("warning", Message("{what}: {result}", what=send.words, result=Message(result)))
            raise CommandError(f"{send.words}: the barrier answered {result}"
                               + (f" ({BUSY_TEXT})" if answer.reply is codec.Reply.BUSY else ""))
        self.counters_next()
        self.state.event("info", Message("{what}: ack", what=send.words))
        return "ack"

    async def send_raw(self, session: str, telegram: bytes, confirmed: bool = False, role: str = "engineer") -> str:
        """A raw telegram (type and payload, unframed) from a bus tool: decoded into the command it amounts to
        and checked by the same rule (a motion asks that the area is clear; a telegram the barrier sends, a
        short command or an unknown setting selector is refused); returns the barrier's answer in words."""
        send = self._decided(self.core.raw(session, bytes(telegram), confirmed=confirmed, role=role,
                                           now=time.monotonic()))
        self._publish_levels()
        answer = await self._carry(send, set(codec.REPLY_TYPES) | set(codec.ANSWER_TYPES))
        result = answer.reply.name.lower() if answer.reply is not None else answer.name
        self._reply(send.words, result)
        if answer.reply is None:
            self._publish(answer)
        return result

    async def _carry(self, send: Send, types: set[int], describe: str = "") -> codec.Answer:
        """Send ``send`` and tell the core its answer (ack, nak, busy, or lost when none came)."""
        try:
            answer = await self._transact(send.telegram, types, describe or send.words)
        except (SerialLineError, codec.CodecError):
            self._after(send, "lost")
            raise
        word = {codec.Reply.ACK: "ack", codec.Reply.NAK: "nak", codec.Reply.BUSY: "busy"}.get(answer.reply, "ack")
        self._after(send, word)
        return answer

    def _after(self, send: Send, word: str) -> None:
        self._act(self.core.answered(send.ref, word, time.monotonic()))
        self._publish_levels()

    def _act(self, actions: list) -> None:
        """Carry out the core's own actions: its reports, and its deactivations each in a task of its own."""
        for action in actions:
            if isinstance(action, Report):
                self.state.event(action.level, action.text)
            elif isinstance(action, Send):
                task = asyncio.get_running_loop().create_task(self._release(action))
                self._stop_tasks.add(task)
                task.add_done_callback(self._stop_tasks.discard)
        self._publish_levels()

    async def _release(self, send: Send) -> bool:
        words = Message("{words} ({why})", words=send.words, why=send.why) if send.why else send.words
        try:
            answer = await self._carry(send, {codec.Reply.ACK, codec.Reply.NAK, codec.Reply.BUSY}, words)
        except (SerialLineError, codec.CodecError) as exc:
            self.state.error(Message(N_("{command} not answered: {error}"), command=words, error=message_of(exc)))
            return False
        self._reply(words, answer.name)
        if answer.reply is not codec.Reply.ACK:
            self.state.event("warning", Message("{what}: {result}", what=words, result=Message(answer.name)))
            return False
        return True

    def renew_leases(self, alive: set[str]) -> None:
        """The dead-man supervisor's beat (devices/adapter.py LeaseRenewer): the levels of ``alive`` stay,
        a level whose lease lapsed is released, a release not acknowledged is sent again."""
        self._act(self.core.beat(alive, time.monotonic()))

    def _publish_levels(self) -> None:
        self.state.fact(P_LEVELS, tuple(sorted((HeldLevel(COMMAND_NAMES[c], c in HELD_LEVELS) for c in self.levels),
                                               key=lambda level: level.command)))

    def _publish_confirmed(self) -> None:
        self.state.fact(P_CONFIRMED, ())

    def _publish_writes(self) -> None:
        self.state.fact(P_EEPROM, EepromWrites(self.eeprom_writes_total, tuple(sorted(
            (session_tag(s), n) for s, n in self.eeprom_writes.items()))), text=f"{self.eeprom_writes_total}")

    async def clear_levels(self, session: str | None = None, confirmed: bool = False) -> list[str]:
        """Deactivate the levels this tool set (and only those: a level set by another master or at the
        barrier is not touched). An engineer command (the worker checks the role); it asks first
        (``confirmed``), since deactivating an open level lets the boom close (page 33)."""
        if not confirmed:
            raise NeedsConfirmation(Message(N_("clearing the levels may move the boom (an open level released lets it "
                                               "close): check that nobody stands under it, then confirm")))
        cleared, failed = [], []
        for cmd in list(self.levels):
            if await self._deactivate(cmd, Message(N_("clear levels"))):
                cleared.append(COMMAND_NAMES[cmd])
            else:
                failed.append(COMMAND_NAMES[cmd])
        if failed:
            raise CommandError(f"not deactivated (still active in the barrier): {', '.join(failed)}"
                               + (f"; deactivated: {', '.join(cleared)}" if cleared else ""))
        return cleared

    async def clear_levels_asked(self, session: str | None = None) -> str:
        """The declared command "clear levels" (devices/mo64/policy.py): the gate has asked its risk
        (:data:`CLEAR_LEVELS_RISK`) before it runs this, so it is not asked again."""
        cleared = await self.clear_levels(session, confirmed=True)
        return "deactivated: " + (", ".join(cleared) if cleared else "none (no level of this tool was active)")

    async def shutdown(self) -> list[str]:
        """The tool stops: deactivate the close and reverse levels this tool set, each awaited to its ack
        (on RS485 in this tool's turn, the token taken like for any request). The worker awaits this,
        bounded, before it closes the lines; a level not acknowledged by then is sent once more,
        unacknowledged, as the line closes (:meth:`closing_frames`). Returns the levels acknowledged."""
        await self.stopped()  # dead-man deactivations already on their way
        done = []
        for cmd in [c for c in self.levels if c in HELD_LEVELS]:
            if await self._deactivate(cmd, TOOL_STOPS):
                done.append(COMMAND_NAMES[cmd])
                self.state.event("info", Message(N_("the tool stops: {level} deactivated (ack)"), level=Message(COMMAND_NAMES[cmd])))
        return done

    def closing_frames(self) -> list[bytes]:
        """The deactivations of the close and reverse levels this tool set, sent by the line as it closes
        (the tool stops): a level the dead-man rule would release is not left behind in the barrier."""
        frames = []
        for send in self.core.closing():
            frames.append(self._frame(send.telegram))
            self.state.event("warning", Message(N_("the tool stops: {command} sent"), command=send.words))
        self._publish_levels()
        return frames

    async def _deactivate(self, cmd: codec.Command, why: str) -> bool:
        """Deactivate a level this tool set (the caller confirmed what it needs: clear levels asks first)."""
        session = self.levels.get(cmd, "")
        send = self._decided(self.core.request(session, cmd, codec.Function.DEACTIVATE, confirmed=True,
                                               now=time.monotonic()))
        send = Send(send.telegram, send.words, send.session, send.ref, send.kind, why)
        return await self._release(send)

    def holders(self) -> set[str]:
        """Sessions whose close or reverse level is still active in the barrier (see HELD_LEVELS)."""
        return self.core.holders()

    def session_lost(self, session: str, reason: str) -> None:
        """Deactivate at once the close and reverse levels ``session`` set (devices/mo64/control.py)."""
        self._act(self.core.session_lost(session, reason, time.monotonic()))

    async def stopped(self) -> None:
        """Wait for the deactivations :meth:`session_lost` has sent off (tests, shutdown)."""
        while self._stop_tasks:
            await asyncio.gather(*list(self._stop_tasks), return_exceptions=True)

    # -- the TCP connection --------------------------------------------------------------------------------
    def release(self, session: str | None = None) -> str:
        if self.rs485:
            raise CommandError("an RS485 line is not released: the token passing shares it")
        self.line.release()
        self.state.event("info", Message(N_("connection released: another client may connect to the barrier")))
        self.state.fact(P_CONNECTION, "released")
        return "released"

    def resume(self, session: str | None = None) -> str:
        if self.rs485:
            return "connected"
        self.line.resume()
        self.state.event("info", Message(N_("connection taken back")))
        self.state.fact(P_CONNECTION, "reconnecting")
        return "reconnecting"


# -- the adapter methods the declared commands run (devices/mo64/policy.py) --------------------------------
def telegram_words(answer_type: int, level: int | None = None) -> Message:
    """An answer telegram by its name (``gate state``, ``error memory level 3``), worded by its reader."""
    name = Message(codec.TELEGRAMS[answer_type])
    return name if level is None else Message(N_("{telegram} level {level}"), telegram=name, level=level)


def operation_method(cmd: codec.Command, fn: codec.Function) -> str:
    """The adapter method of operating command ``cmd`` with function ``fn``, e.g. ``open_pulse``."""
    return f"{COMMAND_NAMES[cmd]}_{fn.name.lower()}"

def _operation(cmd: codec.Command, fn: codec.Function):
    async def run(self: Mo64Adapter, session: str) -> str:
        # reached through the gate only after the declared risk ("the area is clear") was confirmed
        return await self.command(session, cmd, fn, confirmed=True)

    run.__name__ = operation_method(cmd, fn)
    run.__doc__ = f"{COMMAND_NAMES[cmd]} {fn.name.lower()} (chapter 5.2.1), as the declared command of that name."
    return run


OPERATIONS = {(_cmd, _fn): _operation(_cmd, _fn) for _cmd in codec.Command for _fn in codec.Function}
"""The method of each operating command with each function, a member of :class:`Mo64Adapter` under its name."""
for _run in OPERATIONS.values():
    assert _run.__name__ not in vars(Mo64Adapter), _run.__name__
    setattr(Mo64Adapter, _run.__name__, _run)


__all__ = [
    "BUSY_TEXT", "COMMAND_NAMES", "CommandError", "EepromWrites", "ErrorMemoryLevel", "HeldLevel", "LineFacts",
    "MONITOR_FLAGS", "Mo64Adapter", "NAMES", "OPERATIONS", "NeedsConfirmation", "P_CONFIRMED", "P_CONNECTION", "P_EEPROM",
    "P_ERROR_LEVELS", "P_LAST_REPLY", "P_LATE", "P_LEVELS", "P_LEVELS_UNAVAILABLE", "P_LINE", "P_MONITORING",
    "P_POLLING", "P_QUERY_FORM", "P_UNAVAILABLE", "P_UNEXPECTED", "P_VERIFIED", "POLLING_SLOWER", "QUERY_FORM_WORDS",
    "SYN_ACK_TIMEOUT_S", "UNAVAILABLE", "from_json", "operation_method", "to_json", "value_text",
]
