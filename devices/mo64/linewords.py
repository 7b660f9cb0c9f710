"""How the bus monitor words a LogiTed line (devices/linewords.py): in the words of the MO 64 page.

``open pulse``, ``query gate state`` and ``Gate state = closed``; on a shared RS485 line the telegrams of another
master with a barrier are named as such, with the barrier's plant name. Filter: the telegram type.
"""

from __future__ import annotations

from typing import Any

from devices.linewords import LineFilter, LineText, cached, from_hex
from devices.message import N_, Message, Word
from devices.mo64 import adapter as mo64_adapter
from devices.mo64 import codec as mo64

KINDS = {"command": "operating commands", "query": "queries", "setting": "settings", "reply": "ack, nak, busy, syn",
              "answer": "answers", "unsolicited": "unsolicited (change monitoring)", "other master": "another master's",
              "token": "token"}
# the barrier's answer telegrams by type, named as the MO 64 page names their values
ANSWERS = {t: mo64_adapter.NAMES.get(t, name) for t, name in sorted(mo64.TELEGRAMS.items())}
FILTERS = (LineFilter("telegram", "Telegram", choices={
    **KINDS, **{f"0x{t:02X}": f"answer 0x{t:02X} {name}" for t, name in ANSWERS.items()}}),)


# the words below are Messages (devices/message.py) in the MO 64 page's words (the commands as devices/mo64/control.py
# words them, the telegrams by the codec's marked names, the points by their names); the English as before
COMMAND_WORDS = {mo64.Command.OPEN: N_("open"), mo64.Command.CLOSE: N_("close"), mo64.Command.REVERSE: N_("reverse")}
FUNCTION_WORDS = {mo64.Function.PULSE: N_("{command} pulse"), mo64.Function.ACTIVATE: N_("{command} activate"),
                  mo64.Function.DEACTIVATE: N_("{command} deactivate")}


def request_words(r: mo64.Request) -> tuple[str, str]:
    """A request to the barrier as the MO 64 page names it (``open pulse``, ``query gate state``) and its kind."""
    if r.kind is mo64.RequestType.COMMAND:
        command = mo64_adapter.COMMAND_NAMES[r.command]
        template = FUNCTION_WORDS.get(r.function)
        if template is None or COMMAND_WORDS.get(r.command) != command:
            return f"{command} {r.function.name.lower()}", "command"
        return Message(template, command=Message(command)), "command"
    if r.kind is mo64.RequestType.QUERY:
        name = mo64.TELEGRAMS.get(r.query + mo64.QUERY_ANSWER_OFFSET)
        telegram = Message(name) if name else f"0x{r.query:02X}"
        if r.level is not None and r.query == mo64.Q_ERROR_MEMORY:
            return Message(N_("query {telegram} level {level}"), telegram=telegram, level=r.level), "query"
        return Message(N_("query {telegram}"), telegram=telegram), "query"
    if r.kind is mo64.RequestType.SHORT_COMMAND:
        return Message(N_("short command 0x{code:02X}"), code=r.code), "setting"
    if r.setting is None:
        return Message(N_("setting 0x{kind:02X} selector 0x{selector:02X} = {value}"), kind=int(r.kind),
                       selector=r.selector, value=r.value.hex(" ")), "setting"
    return Message(N_("set {name} = {value}"), name=r.setting.name,
                   value=mo64_adapter.value_text(r.setting.query + mo64.QUERY_ANSWER_OFFSET, r.value)), "setting"


def answer_words(a: mo64.Answer) -> str:
    """A telegram of the barrier with the name its page gives the value (``Gate state = closed``)."""
    if a.reply is not None:
        return a.name + (f" ({a.error})" if a.error else "")
    if a.error:
        return Message(N_("{name}: {error} (raw {raw})"), name=Message(a.name), error=a.error, raw=a.payload.hex(" "))
    name, x = mo64_adapter.NAMES.get(a.type, a.name), a.value
    if a.type == 0x0C:  # the gate state's word as the point has it (context: the point's name)
        state = Word(x.name, name) if x.name else Message(N_("undefined state {n}"), n=int(x))
        return Message("{name} = {value}", name=Message(name), value=state)
    if a.type == 0x1D:
        return Message("{name} = {value}", name=Message(name),
                       value=Message(N_("unknown")) if int(x) == mo64.POSITION_UNKNOWN else f"{int(x)} %")
    if a.type == 0x17 and isinstance(x, dict) and "flags" in x:
        flags = mo64.error_flags_text(int(x["flags"]))
        if "index" in x:
            return Message(N_("Error memory level {level}: {flags} at {hours} h"), level=x["index"], flags=flags,
                           hours=int(x["timestamp_h"]))
        return Message(N_("Error memory {flags} at {hours} h"), flags=flags, hours=int(x["timestamp_h"]))
    return Message("{name} = {value}", name=Message(name), value=mo64_adapter.value_text(a.type, x))


class LogitedLineDecoder:
    """The telegrams of a LogiTed line (TCP or RS485) in the words of the MO 64 page; on a shared RS485 line the
    telegrams of another master with its barriers are named as such, with the barrier's plant name."""

    def __init__(self, devices: list, rs485: bool, bus_options: dict):
        self.rs485 = rs485
        self.framing = mo64.RS485 if rs485 else mo64.TCP
        self.master = int(bus_options.get("master_address", mo64.RS485_LAYOUT.master_address))
        self.names = {int(d.options["address"]): d.name for d in devices if "address" in d.options}
        self._cache: dict[tuple, LineText] = {}

    def refresh(self) -> None:
        """Nothing the line's adapters learn changes the words."""

    def who(self, address: int | None) -> str:
        if address is None:
            return ""
        return self.names.get(address, Message(N_("master 0x{address:02X}"), address=address) if address not in self.names else "")

    def text(self, t: Any) -> LineText:
        return cached(self._cache, (t.request, t.request_hex, t.response_hex, t.error),
                       lambda: self._make(t.request, from_hex(t.request_hex), from_hex(t.response_hex)))

    def _frame(self, raw: bytes) -> mo64.Frame | None:
        try:
            return mo64.decode_frame(raw, self.framing)
        except mo64.CodecError:
            return None

    def _make(self, own: str, request: bytes, answer: bytes) -> LineText:
        tags: set[str] = set()
        words = own
        if request:
            frame = self._frame(request)
            if frame is not None and frame.is_token:
                words = Message(N_("token to {who}"), who=self.who(frame.da))
                tags.add("token")
            elif frame is not None:
                try:
                    words, kind = request_words(mo64.decode_request(frame))
                    tags.add(kind)
                except mo64.CodecError as exc:
                    words = f"{own}: {exc}"
        if not answer:
            return LineText(words, "", frozenset(tags))
        frame = self._frame(answer)
        if frame is None:
            return LineText(words, Message(N_("not a LogiTed telegram: {data}"), data=answer.hex(" ").upper()), frozenset(tags))
        if frame.is_token:
            tags.add("token")
            return LineText(words, Message(N_("token {sender} -> {receiver}"), sender=self.who(frame.sa), receiver=self.who(frame.da)),
                            frozenset(tags))
        toward_barrier = self.rs485 and frame.da is not None and frame.da != self.master and frame.da in self.names
        other = self.rs485 and frame.da is not None and frame.da != self.master and frame.sa != self.master
        if other:
            tags.add("other master")
        if toward_barrier:  # another master's request to a barrier
            try:
                said, kind = request_words(mo64.decode_request(frame))
            except mo64.CodecError as exc:
                said, kind = Message(N_("telegram 0x{type:02X} ({error})"), type=frame.type, error=str(exc)), "setting"
            tags.add(kind)
            return LineText(Message("{sender} -> {receiver}: {said}", sender=self.who(frame.sa), receiver=self.who(frame.da),
                                    said=said), "", frozenset(tags))
        a = mo64.decode_answer(frame)
        tags.add("reply" if a.reply is not None else "answer")
        if a.reply is None:
            tags.add(f"0x{a.type:02X}")
        if own == "unsolicited":
            tags.add("unsolicited")
            words = Message(N_("unsolicited (change monitoring)"))
        elif other:
            words = Message(N_("{sender} -> {receiver}: answer"), sender=self.who(frame.sa), receiver=self.who(frame.da))
        return LineText(words, answer_words(a), frozenset(tags))




def decoder(devices: list, adapters: dict[str, Any], bus_type: str, bus_options: dict) -> LogitedLineDecoder:
    return LogitedLineDecoder(devices, bus_type.endswith("rs485"), bus_options)
