"""The SCU's requests and answers on its serial line (document 002, sections 3 and 4.2): one request and its answer,
a bad CRC sent again, a shifted answer resynchronised, error codes raised as :class:`codec.CommandRefused` (counted
and shown), silence counted towards offline, and the low-power wake-up."""

from __future__ import annotations

import functools
import time
from typing import TYPE_CHECKING

from devices.decoding import malformed
from devices.message import Message, N_
from devices.scu import codec
from devices.scu.facts import P_CRC_RETRIES, P_REFUSAL, P_RESYNCS, P_SKIPPED, Refusal, answer_length, describe_answer, header_offset
from devices.transport import SerialClosed, SerialLineError, SerialTimeout

if TYPE_CHECKING:
    from devices.scu.adapter import ScuAdapter

CRC_RETRIES = 2  # an answer with a bad CRC is counted and the request sent again


class ScuLink:
    """One SCU adapter's conversation on its line, with the counts of what went wrong on it."""

    def __init__(self, adapter: ScuAdapter):
        self.adapter = adapter
        self.state = adapter.state
        self.crc_retries = 0
        self.resyncs = 0
        self.skipped_bytes = 0
        self.last_answer: float | None = None
        self.silent_since: float | None = None

    async def request(self, frame: bytes, describe: str, *, keepalive: bool = True,
                       quiet: bool = False) -> codec.Answer:
        """One request and its answer; bad CRC retried; error codes raise CommandRefused (counted).

        :param quiet: a refusal is expected (a probe): not shown as the last error answer
        """
        if (keepalive and frame[:2] != codec.RC and self.adapter.session == "open" and not self.adapter.rc.threaded()
                and self.adapter.rc.due()):
            await self.adapter.send_rc()  # only RC feeds the unit's 500 ms watchdog (section 5): long operations interleave it
        expected = bytes(frame[:2])
        for attempt in range(CRC_RETRIES + 1):
            self.state.counters.requests += 1
            sent_at = time.monotonic()
            try:
                raw = await self.adapter.line.transact(frame, functools.partial(answer_length, expected=expected),
                                               describe=describe, decode=describe_answer)
            except SerialTimeout:
                self.state.counters.timeouts += 1
                self.no_answer()
                raise
            except SerialClosed:
                self.no_answer()
                raise
            start = header_offset(raw, expected) or 0
            if start:
                self.skipped_bytes += start  # a stray byte or an old answer's tail before this answer: skipped
                self.publish_counts()
                raw = raw[start:]
            try:
                answer = codec.decode_answer(raw, expected)
            except codec.FrameError as exc:
                if isinstance(exc, codec.ChecksumError):
                    self.state.counters.crc_errors += 1
                    self.crc_retries += 1
                    self.publish_counts()
                else:
                    malformed(self.state, f"{describe}: {exc}")
                # The reader may have lost its place in the byte stream (a stray byte, an answer split or
                # late): drop everything still arriving before the request is sent again (resynchronise).
                await self.resync()
                if attempt < CRC_RETRIES:
                    continue
                raise
            self.answered()
            if frame[:2] == codec.RC and answer.ok:
                self.adapter.rc.note(sent_at)
            if not answer.ok:
                await self.refused(describe, answer, quiet=quiet)
            self.state.counters.responses += 1
            return answer
        raise AssertionError("unreachable")

    async def resync(self) -> None:
        """Flush what the line still holds (the rest of a shifted answer) so the next answer starts clean."""
        try:
            dropped = await self.adapter.line.flush_input()
        except SerialLineError:
            return
        if dropped:
            self.resyncs += 1
            self.publish_counts()

    def answered(self) -> None:
        self.last_answer = time.monotonic()
        self.silent_since = None
        self.state.mark_seen()

    def no_answer(self) -> None:
        now = time.monotonic()
        if self.silent_since is None:
            self.silent_since = self.last_answer if self.last_answer is not None else now
        silent = now - self.silent_since
        if self.adapter.session == "open" and silent > codec.WATCHDOG_S:
            self.adapter.lost(Message(N_("no answer for more than 500 ms: the unit has dropped remote mode (watchdog)")))
        if silent >= codec.MAX_ANSWER_DELAY_S or self.last_answer is None and self.adapter.core.failures >= 1:
            self.state.mark_offline(self.offline_message())

    def offline_message(self) -> str:
        return Message(N_("no answer from the SCU within {seconds:g} s on {port}: check the RS232 cable (9-pin Sub-D, "
                          "RxD/TxD/GND), that DTR and RTS are on (they power the unit's RS232 converter; or a separate 5.5-15 V "
                          "supply on pin 4 or 7), and the baud rate ({baud}; standard units 38400, custom 9600 or 19200); a unit "
                          "on battery with Low Power enabled is woken by RxD at space for 100 ms (firmware V2B1), which is sent "
                          "before every reopening"), seconds=codec.MAX_ANSWER_DELAY_S, port=self.adapter.port,
                       baud=self.adapter.baudrate)

    async def refused(self, describe: str, answer: codec.Answer, *, quiet: bool = False) -> None:
        exc = codec.CommandRefused(answer.command, answer.status)
        self.state.counters.exceptions += 1
        info = exc.info
        if not quiet:
            refusal = Refusal(describe, info.name, info.title, info.meaning, info.remedy, time.time())
            self.state.fact(P_REFUSAL, refusal, text=Message(N_("{name} ({title}) to {what}: {meaning}. What to do: {remedy}"),
                                                             name=info.name, title=info.title, what=describe,
                                                             meaning=info.meaning, remedy=info.remedy))
            self.state.error(Message("{what}: {name} ({title}): {meaning}. {remedy}", what=describe, name=info.name,
                                     title=info.title, meaning=info.meaning, remedy=info.remedy))
        if answer.status == codec.Status.PE and self.adapter.session == "open":
            if answer.command == codec.RC:
                self.adapter.lost(Message(N_("PE (permission error) to {what}: the unit is no longer in remote mode"), what=describe))
            elif answer.command not in (codec.RO, codec.RA):
                # PE also means "not possible in the unit's current state" (an emergency stop, a locked
                # function): only an RC refused as well shows that remote mode is gone (section 4.2).
                try:
                    await self.request(codec.KEEP_ALIVE, "RC (is remote mode still open after a PE?)",
                                        keepalive=False, quiet=True)
                except (codec.CommandRefused, SerialLineError, codec.CodecError):
                    pass
        raise exc

    def publish_counts(self) -> None:
        self.state.fact(P_SKIPPED, self.skipped_bytes)
        self.state.fact(P_RESYNCS, self.resyncs)
        self.state.fact(P_CRC_RETRIES, self.crc_retries)

    async def wake(self) -> None:
        """Low-power wake-up (section 3, V2B1): RxD held at space for at least 100 ms."""
        try:
            await self.adapter.line.wake(0.15)
        except SerialLineError:
            pass
