"""How the bus monitor words an SCU's RS232 line (devices/linewords.py): in the words of the SCU page.

``RC keep-alive``, ``RE F1 Move to position Out, ramp default``, ``RS F1``, ``RG 0x0011 Actual_Position Actuator 1``
and its answer ``Actual_Position Actuator 1 = 1200 counts``; a refusal by its code and meaning (section 4.2). The
data of an RC with a cyclic object follows the object's definition: the one the adapter sent (its ``cyclic``), or
an RT of the definition seen on the line. Filters: the command letters and the data ID (a group ID also finds its
members and the cyclic objects that carry them).
"""

from __future__ import annotations

from typing import Any

from devices import values as v
from devices.linewords import LineFilter, LineText, cached, from_hex
from devices.message import N_, Message, Word, joined
from devices.scu import adapter as scu_adapter
from devices.scu import codec as scu
from devices.scu import params as scu_params
from devices.scu.keepalive import CYCLIC_INDEX

COMMAND_WORDS = {"RO": "RO open remote mode", "RC": "RC keep-alive / cyclic object", "RG": "RG read data",
                 "RT": "RT write remote data", "RE": "RE start a function", "RS": "RS stop a function",
                 "RA": "RA end remote mode"}  # table 3, in the order of a session
MAX_VALUES = 8  # values named of one block; the rest are counted


def parse_data_id(text: str) -> str:
    """A data ID typed as hex (``0011``, ``0x0011``, ``11``) as the tag it matches (``"0x0011"``).

    :raises ValueError: not a hex number of 0 .. 0xFFFF
    """
    try:
        value = int(text.strip(), 16)
    except ValueError:
        raise ValueError("hex 0000 ... FFFF") from None
    if not 0 <= value <= 0xFFFF:
        raise ValueError("hex 0000 ... FFFF")
    return f"0x{value:04X}"


FILTERS = (
    LineFilter("command", "Command", choices=COMMAND_WORDS),
    LineFilter("data-id", "Data ID (hex)", placeholder="0011 or 0010", parse=parse_data_id,
               hint="A group ID (0x0010) also finds its members and the cyclic objects that carry them"),
)


def scu_id_tags(data_id: int) -> set[str]:
    """A data ID as filter tags: itself, its group, and the members of a group (0x0010 carries 0x0011..0x0016)."""
    tags = {f"0x{data_id:04X}"}
    item = scu_params.DIRECTORY.get(data_id)
    if item is not None:
        if item.group is not None:
            tags.add(f"0x{item.group:04X}")
        tags.update(f"0x{m:04X}" for m in item.members)
    return tags


# The words below are Messages (devices/message.py): the monitor words them in the page's language as the SCU page
# does (a group's name, the units with the catalog's context ``unit``: counts are Flanken); the English as before.


def _title(item: scu_params.DataItem) -> str:
    """An item as the SCU page names it: a group by its name in the reader's language, an item by the document's."""
    return Message(item.title) if item.is_group and not item.label else item.title


def scu_title(data_id: int) -> str:
    item = scu_params.DIRECTORY.get(data_id)
    if item is None:
        return Message(N_("0x{id:04X} (not in the data directory)"), id=data_id)
    return Message("0x{id:04X} {title}", id=data_id, title=_title(item))


def _member(data_id: int | str) -> str:
    """A member of a block: a data ID by its actuator or function (``A1``), a struct's field by its name
    (UserPositionData's ``Position_Memory_1[USER_1]``)."""
    if isinstance(data_id, str):
        return data_id
    item = scu_params.DIRECTORY.get(data_id)
    if item is None:
        return f"0x{data_id:04X}"
    return f"A{item.actuator}" if item.actuator else f"F{item.function}" if item.function else _title(item)


def scu_value(data_id: int, value: Any) -> str:
    """A value of a data ID as the SCU page shows it, with its unit (``1200 counts``, ``1.2 A``); a block's members
    by actuator (``A1 1200 counts, A2 0 counts, ...``)."""
    item = scu_params.DIRECTORY.get(data_id)
    if isinstance(value, dict):
        parts = [Message("{member} {value}", member=_member(k), value=scu_value(k, x))
                 for k, x in list(value.items())[:MAX_VALUES]]
        if len(value) > MAX_VALUES:
            parts.append(Message(N_("... {n} more"), n=len(value) - MAX_VALUES))
        return joined(parts)
    text = scu_adapter.value_text(data_id, value)
    unit = item.unit if item is not None else ""
    if unit and isinstance(value, (int, float)) and not isinstance(value, bool) and not isinstance(value, v.FlagsValue):
        if isinstance(value, float) and text == f"{value:g}":  # a decimal number with the reader's decimal sign
            return Message("{value:g} {unit}", value=value, unit=Word(unit, "unit"))
        return Message("{value} {unit}", value=text, unit=Word(unit, "unit"))
    return text


def scu_values(values: dict[int, Any]) -> str:
    """Several data IDs' values (an RC's cyclic object), each named; a block as ``name: A1 .., A2 ..``."""
    parts = []
    for k, x in values.items():
        name = _title(scu_params.DIRECTORY[k]) if k in scu_params.DIRECTORY else f"0x{k:04X}"
        parts.append(Message("{name}: {value}" if isinstance(x, dict) else "{name} = {value}", name=name,
                             value=scu_value(k, x)))
    return joined(parts, "; ")


def scu_function(function: int) -> str:
    try:
        return scu.FUNCTIONS[scu.Function(function)].label
    except (ValueError, KeyError):
        return f"fnc_ID {function}"


class ScuLineDecoder:
    """The telegrams of an SCU's RS232 line in the words of the SCU page.

    The data of an RC with a cyclic object follows the object's definition: the one its adapter sent (its
    ``cyclic``), or an RT of the definition seen on the line.
    """

    def __init__(self, devices: list, adapters: dict[str, Any]):
        self.devices = list(devices)
        self.adapters = adapters
        self.definitions: dict[int, scu_params.CyclicDefinition] = {}  # RC index 0..4 -> definition
        self._cache: dict[tuple, LineText] = {}
        self.refresh()

    def refresh(self) -> None:
        """The cyclic object definitions the line's adapters sent (a reopened session may change them)."""
        found = dict(self.definitions)
        for dev in self.devices:
            adapter = self.adapters.get(dev.name)
            if isinstance(adapter, scu_adapter.ScuAdapter) and adapter.cyclic is not None:
                found[CYCLIC_INDEX] = adapter.cyclic
        self._learn(found)

    def _learn(self, found: dict[int, scu_params.CyclicDefinition]) -> None:
        if found != self.definitions:
            self.definitions = found
            self._cache.clear()

    def text(self, t: Any) -> LineText:
        return cached(self._cache, (t.request, t.request_hex, t.response_hex, t.error),
                       lambda: self._make(t.request, from_hex(t.request_hex), from_hex(t.response_hex)))

    def _make(self, own: str, request: bytes, answer: bytes) -> LineText:
        tags: set[str] = set()
        if len(request) >= 2:
            tags.add(request[:2].decode("ascii", "replace"))
        try:
            r = scu.decode_request(request)
        except scu.CodecError as exc:
            return LineText(own or request[:2].decode("ascii", "replace"),
                            self._answer(None, answer) if answer else
                            Message(N_("request not decodable: {error}"), error=str(exc)), frozenset(tags))
        words = self._request(r, tags)
        return LineText(words, self._answer(r, answer) if answer else "", frozenset(tags))

    def _request(self, r: scu.Request, tags: set[str]) -> str:
        command = r.command
        if command == scu.RO:
            return f"RO Safety_ID {r.safety_id}" + (", para_ID[0] -1" if r.para else "")
        if command == scu.RA:
            return Message(N_("RA end remote mode"))
        if command == scu.RC:
            if r.index == -1:
                return Message(N_("RC keep-alive"))
            words = Message(N_("RC keep-alive with CyclicObj {n}"), n=r.index + 1)
            definition = self.definitions.get(r.index)
            if definition is not None:
                for data_id in definition.read_ids + definition.write_ids:
                    tags.update(scu_id_tags(data_id))
                if definition.write_ids and r.data:
                    words = Message(N_("RC keep-alive with CyclicObj {n}, writes {values}"), n=r.index + 1,
                                    values=scu_values(definition.decode_write(r.data)))
            return words
        if command == scu.RG:
            tags.update(scu_id_tags(r.data_id))
            return Message("RG {title}", title=scu_title(r.data_id))
        if command == scu.RT:
            tags.update(scu_id_tags(r.data_id))
            try:
                value = scu_params.decode_data(r.data_id, r.data)
            except (scu_params.UnknownDataId, v.ValueCodecError):
                return Message("RT {title} = {data}", title=scu_title(r.data_id), data=r.data.hex(" ").upper())
            if 0x3001 <= r.data_id <= 0x3005:  # a cyclic object's definition: what its RC carries from now on
                definition = scu_params.CyclicDefinition.decode(r.data)
                self._learn({**self.definitions, r.data_id - 0x3001: definition})
                reads = ", ".join(f"0x{i:04X}" for i in definition.read_ids) or Message(N_("nothing"))
                if definition.write_ids:
                    return Message(N_("RT {title} definition: reads {reads}, writes {writes}"), title=scu_title(r.data_id),
                                   reads=reads, writes=", ".join(f"0x{i:04X}" for i in definition.write_ids))
                return Message(N_("RT {title} definition: reads {reads}"), title=scu_title(r.data_id), reads=reads)
            return Message("RT {title} = {value}", title=scu_title(r.data_id), value=scu_value(r.data_id, value))
        label = scu_function(r.function)
        if command == scu.RE:
            function = scu.Function(r.function)
            if function in scu.MOTION_FUNCTIONS:
                motion = scu.MOTION_LABELS.get(scu.Motion(r.para[0]))  # table 7's motions as the SCU page words them
                motion = Message(motion) if motion else Message(N_("motion {n}"), n=r.para[0])
                ramp = Word(scu.Ramp(r.para[1]).name.lower(), "Ramp")
                return Message(N_("RE {function} {motion}, ramp {ramp}"), function=label, motion=motion, ramp=ramp)
            return Message("RE {function} {description}", function=label,
                           description=Message(scu.FUNCTIONS[function].description))
        if command == scu.RS:
            function = scu.Function(r.function)
            if function in scu.MOTION_FUNCTIONS:
                return f"RS {label}"
            return Message("RS {function} {description}", function=label,
                           description=Message(scu.FUNCTIONS[function].description))
        return command.decode("ascii", "replace")

    def _answer(self, r: scu.Request | None, raw: bytes) -> str:
        start = scu_adapter.header_offset(raw) or 0
        try:
            a = scu.decode_answer(raw[start:])
        except scu.CodecError as exc:
            return Message(N_("answer not decodable: {error}"), error=str(exc))

        def head(text: str) -> str:
            return Message(N_("(after {n} stray bytes) {text}"), n=start, text=text) if start else text

        if not a.ok:
            info = a.status_info  # table 4.4's name, title and meaning (devices/scu/codec.py STATUS_INFO)
            return head(Message("{name} ({title}): {meaning}", name=info.name, title=Message(info.title),
                                meaning=Message(info.meaning)) if info else
                        Message(N_("status 0x{status:02X}"), status=a.status))
        if r is None or not a.has_ctp:
            return head("ACK")
        if r.command == scu.RG:
            try:
                return head(scu_values({r.data_id: scu_params.decode_data(r.data_id, a.data)}))
            except (scu_params.UnknownDataId, v.ValueCodecError) as exc:
                return head(Message(N_("ACK, {n} data bytes ({error}): {data}"), n=len(a.data), error=str(exc),
                                    data=a.data.hex(" ").upper()))
        if r.command == scu.RC:
            definition = self.definitions.get(r.index) if r.index is not None else None
            if not a.data:
                return head("ACK")
            if definition is None:
                return head(Message(N_("ACK, {n} data bytes of CyclicObj {index} (its definition was not seen on the line)"),
                                    n=len(a.data), index=r.index + 1))
            try:
                return head(scu_values(definition.decode_read(a.data)))
            except v.ValueCodecError as exc:
                return head(Message(N_("ACK, {n} data bytes: not CyclicObj {index} as defined ({error})"), n=len(a.data),
                                    index=r.index + 1, error=str(exc)))
        return head("ACK")




def decoder(devices: list, adapters: dict[str, Any], bus_type: str, bus_options: dict) -> ScuLineDecoder:
    return ScuLineDecoder(devices, adapters)
