"""The MO 64's settings: written, read back and counted (EEPROM wear), through the parameter model.

A mixin of :class:`devices.mo64.adapter.Mo64Adapter` (it uses the adapter's ``query``, ``_transact``,
``state`` and counters). Chapter 5.2.4-5.2.8: a setting answers busy while the motor runs, else syn, the
EEPROM write, then ack (or nak); every write is read back. The parameter model
(:mod:`devices.mo64.params`) names each piece of a setting: :meth:`Mo64Settings.write_param` reads the
setting from the unit, replaces the piece, writes the whole value and reads it back; every answer that
carries settings is kept in the live store as the model's raw values (:meth:`Mo64Settings.publish_params`),
so drift, the project and restore compare them by name.
"""

from __future__ import annotations

import time
from typing import Any

from devices.adapter import BackupDefaults
from devices.message import Message, N_
from devices.mo64 import codec
from devices.mo64 import params as model
from devices.mo64.facts import (
    BUSY_TEXT,
    P_VERIFIED,
    CommandError,
    from_json,
    to_json,
    value_text,
)
from devices.params import Accepted, Param, ParamError, backup_entry
from devices.transport import SerialTimeout

SYN_ACK_TIMEOUT_S = 5.0  # after syn the EEPROM write ends with ack or nak (chapter 5.2.4); bound of the wait
MONITOR_FLAGS = ("barrier status", "gate state", "service counter", "maintenance counter", "vehicle counter",
                 "error memory", "barrier position")  # issue 13 item 6: what the tool switches on
# read with a backup beside the model, raw: query index 0x16 is answered by 0x1B tele_induktionsschleifenperioden
# ("Nicht verwenden!" in table 21 concerns the query indexes 0x1B-0x1E, not this telegram; SPEC-NOTES); its
# layout is not in the summary, and no setting telegram is named for it (chapter 5.2)
READ_ONLY_BACKUP = ((codec.Q_LOOP_PERIODS, "loop_periods", "induction-loop periods"),)
# the queries a backup reads, in the model's order; the vehicle counter is RAM only (chapter 5.2.5): not backed up
PARAM_QUERIES = tuple(dict.fromkeys(p.query for p in model.PARAMS
                                    if not p.setting_key or codec.SETTINGS[p.setting_key].backup))
READ_ATTEMPTS = 3  # a query of a backup or a read-modify-write, asked again when unanswered
WRITE_SESSION = "write parameter"  # the EEPROM writes of a restore, a batch or the API (no page session)


class Mo64Settings(BackupDefaults):
    """Settings, the parameter model's writes, backup and restore of one MO 64 (mixed into the adapter)."""

    params = model.PARAMS
    eeprom_writes: dict[str, int]  # EEPROM writes of each session, kept by the adapter

    @property
    def eeprom_writes_total(self) -> int:
        """Every EEPROM write this tool made, whichever session asked."""
        return sum(self.eeprom_writes.values())

    async def write_setting(self, session: str, key: str, value: Any, selector_verified: bool = False) -> Any:
        """Write one setting, handle busy / syn / ack / nak, read it back; returns the read-back value.

        A setting whose selector is an assumption (codec ``Setting.assumed``) is refused unless the
        engineer confirms (``selector_verified``, kept for this unit) that the selector is verified on
        this unit: a wrong selector would write another EEPROM setting.
        """
        setting = codec.SETTINGS.get(key)
        if setting is None:
            raise CommandError(f"no setting {key!r}")
        if setting.assumed and not (selector_verified or key in self.verified_selectors):
            raise CommandError(f"{setting.name}: not written: the selector 0x{setting.telegram:02X} "
                               f"0x{setting.selector:02X} is an assumption ({setting.assumed}); write it only after "
                               "confirming that the selector is verified on this unit")
        try:
            telegram = codec.encode_setting(key, value)
        except codec.CodecError as exc:
            raise CommandError(str(exc)) from None
        if setting.assumed:
            self.verified_selectors.add(key)
            self.state.fact(P_VERIFIED, tuple(sorted(self.verified_selectors)))
        replies = {codec.Reply.ACK, codec.Reply.NAK, codec.Reply.BUSY, codec.Reply.SYN}
        syn: list[bool] = []

        def interim(raw: bytes) -> bool:  # syn, then ack or nak within the same exchange (chapter 5.2.4)
            frame = self._decode(raw)
            if frame is not None and frame.type == codec.Reply.SYN:
                syn.append(True)
                return True
            return False

        try:
            answer = await self._transact(telegram, replies, f"set {setting.name}", interim=interim,
                                          interim_timeout=SYN_ACK_TIMEOUT_S)
        except SerialTimeout:
            if not syn:
                raise
            raise CommandError(f"{setting.name}: syn, but no ack or nak in time") from None
        finally:
            if syn and setting.eeprom:
                self._count_write(session)
        result = answer.name
        self._reply(Message(N_("set {setting}"), setting=Message(setting.name)), result)
        if answer.reply is codec.Reply.BUSY:
            raise CommandError(f"{setting.name}: busy: {BUSY_TEXT}")
        if answer.reply is not codec.Reply.ACK:
            self.state.counters.write_errors += 1
            raise CommandError(f"{setting.name}: the barrier answered {result}")
        back_answer = await self._read(setting.query)
        back = codec.setting_value(key, back_answer)
        if to_json(back) != to_json(_normal(setting, value)):
            self.state.counters.write_errors += 1
            raise CommandError(f"{setting.name}: wrote {to_json(value)}, read back {to_json(back)}")
        self.state.event("info", Message(N_("set {setting} = {value} (read back)"), setting=Message(setting.name),
                                         value=value_text(back_answer.type, back_answer.value)))
        return back

    async def write_declared(self, session: str, key: str, numbers: list[int], selector_verified: bool = False) -> str:
        """A declared "set ..." command (devices/mo64/policy.py): the setting from its numbers
        (:func:`codec.setting_fields`), written and read back; the outcome with the value before, for
        the audit row."""
        setting = codec.SETTINGS[key]
        before = self.settings.get(key)
        answer_type = setting.query + codec.QUERY_ANSWER_OFFSET
        back = await self.write_setting(session, key, codec.setting_from_fields(key, numbers),
                                        selector_verified=selector_verified)
        was = "not read" if before is None else self.restore_text(key, before)
        return f"{setting.name}: {was} -> {value_text(answer_type, back)} (read back)"

    def _count_write(self, session: str) -> None:
        self.eeprom_writes[session] = self.eeprom_writes.get(session, 0) + 1
        self._publish_writes()

    async def set_change_monitoring(self, session: str, on: bool) -> str:
        """Switch the unsolicited telegrams of :data:`MONITOR_FLAGS` on, or all off (one EEPROM write)."""
        value = {name: int(bool(on)) for name in MONITOR_FLAGS}
        await self.write_setting(session, "change_monitoring", value)
        if not on:
            self._monitor_last = None
        return "on" if on else "off"

    # -- the parameter model (devices/mo64/params.py) ------------------------------------------------------
    async def _read(self, index: int) -> codec.Answer:
        """A query of a whole read (backup, read-modify-write), asked again when it went unanswered (at most
        :data:`READ_ATTEMPTS` times): on a shared RS485 line an answer may miss this tool's turn (chapter 2.6.1),
        which fails nothing yet."""
        for _ in range(READ_ATTEMPTS - 1):
            try:
                return await self.query(index)
            except SerialTimeout:
                continue
        return await self.query(index)

    def publish_params(self, answer: codec.Answer) -> None:
        """Keep the model's raw values of an answer that carries settings (one store change for all of them)."""
        pieces = model.of_query(answer.query) if answer.query is not None else []
        if not pieces or answer.error or answer.value is None:
            return
        number = model.value_int(answer.type, answer.value)
        registers = {}
        for param in pieces:
            for address, word in zip(param.addresses, param.split(model.extract(param, number))):
                registers[(param.space, address)] = word
        self.state.publish_telegram(time.time(), {}, registers)

    def _model_param(self, param: Param | str) -> model.Mo64Param:
        found = model.PARAMS.by_key.get(param if isinstance(param, str) else param.key)
        if found is None:
            raise CommandError(f"{param if isinstance(param, str) else param.name} is not a parameter of the MO 64")
        return found

    async def read_param(self, param: Param | str) -> int:
        """The raw value of ``param`` read from the unit now."""
        param = self._model_param(param)
        answer = await self._read(param.query)
        return model.extract(param, model.value_int(answer.type, answer.value))

    async def write_param(self, param: Param | str, value, *, confirmed: bool = False, session: str = WRITE_SESSION) -> int:
        """Write one piece of a setting: checked by the model (range, names, the confirmation a safety flag
        asks), the setting read from the unit, the piece replaced (the other bits as the unit holds them),
        written and read back. ``confirmed``: the engineer confirmed what the declared write asked, which for
        an assumed selector includes that it is verified on this unit. Returns the raw value read back."""
        param = self._settable(param)
        try:
            accepted = param.accept(value)
        except ParamError as exc:
            raise CommandError(str(exc)) from None
        return await self.write_accepted(accepted, confirmed=confirmed, session=session)

    def _settable(self, param: Param | str) -> Param:
        """The model's parameter of ``param``. :raises CommandError: no setting telegram writes it (read only)"""
        param = self._model_param(param)
        if not param.setting_key:
            raise CommandError(f"{param.name} is read only: no setting telegram is named for it (chapter 5.2)")
        return param

    async def write_accepted(self, accepted: Accepted, *, confirmed: bool = False, session: str = WRITE_SESSION) -> int:
        """:meth:`write_param` of a value the model accepted (its range, names and confirmation checked there)."""
        param = self._settable(accepted.param)
        try:
            raw = accepted.cleared(confirmed)
        except ParamError as exc:
            raise CommandError(str(exc)) from None
        key = param.setting_key
        setting = codec.SETTINGS[key]
        if setting.assumed and not (confirmed or key in self.verified_selectors):
            raise CommandError(f"{param.name}: not written: the selector 0x{setting.telegram:02X} "
                               f"0x{setting.selector:02X} is an assumption ({setting.assumed}); write it only after "
                               "confirming that the selector is verified on this unit")
        now = model.setting_int(key, codec.setting_value(key, await self._read(setting.query)))
        back = await self.write_setting(session, key, model.setting_value(key, model.replace(param, now, raw)),
                                        selector_verified=confirmed)
        back_raw = model.extract(param, model.setting_int(key, back))
        if back_raw != raw:
            self.state.counters.write_errors += 1
            raise CommandError(f"{param.name}: wrote {param.display(raw)}, read back {param.display(back_raw)}")
        return back_raw

    async def write_param_in(self, session: str, accepted: Accepted, confirmed: bool = False) -> str:
        """The declared "write parameter" (devices/mo64/policy.py) from a page's session, of the value the model
        accepted: the outcome for the audit row; the EEPROM write is counted for that session."""
        param = accepted.param
        before = self.state.raw(param)
        back = await self.write_accepted(accepted, confirmed=confirmed, session=session or WRITE_SESSION)
        was = "not read" if before is None else param.display(before)
        return f"{param.name}: {was} -> {param.display(back)} (read back)"

    # -- backup and restore --------------------------------------------------------------------------------
    async def backup_read(self, progress=None) -> list[dict]:
        """Every parameter of the model (settings and the read-only loop modes, direction logics and radio code),
        each by its key, and the loop periods raw (layout not in the summary)."""
        total = len(PARAM_QUERIES) + len(READ_ONLY_BACKUP)
        entries = []
        for n, index in enumerate(PARAM_QUERIES, 1):
            answer = await self._read(index)
            number = model.value_int(answer.type, answer.value)
            entries += [backup_entry(p, model.extract(p, number)) for p in model.of_query(index)]
            if progress:
                progress(n / total)
        for n, (index, key, name) in enumerate(READ_ONLY_BACKUP, len(PARAM_QUERIES) + 1):
            answer = await self._read(index)
            value = to_json(answer.value)
            entries.append({"key": key, "name": name, "value": value, "raw": value,
                            "text": value_text(answer.type, answer.value), "unit": "",
                            "writable": False})  # no setting telegram is named for them (chapter 5.2)
            if progress:
                progress(n / total)
        return entries

    def backup_identity(self) -> dict:
        def get(name: str) -> Any:
            point = self.state.points.get(name)
            return None if point is None else point.value

        return {"serial": get("Serial number"), "device code": get("Device code"),
                "program version": get("Program version"), "mac": get("MAC address"),
                "transport": self.transport, "address": self.address}

    def restore_text(self, key: str, value: Any) -> str:
        """A backed-up value in the words its table shows (relay modes and flags by name, times in s): a key of the
        parameter model (its value as the model decodes it), or a whole setting of an older backup file."""
        param = model.PARAMS.by_key.get(key)
        if param is not None:
            return param.display(param.encode(value))
        setting = codec.SETTINGS[key]
        answer_type = setting.query + codec.QUERY_ANSWER_OFFSET  # SPEC-NOTES "Replies": index n answered by type n + 5
        wire = codec.ANSWER_TYPES[answer_type]
        return value_text(answer_type, wire.decode(setting.vtype.encode(from_json(setting, value))))

    async def restore_entry(self, key: str, raw: Any, session: str = "restore") -> None:
        """Write one backed-up setting; one on an assumed selector only once an engineer confirmed on the
        device page that the selector is verified on this unit (else refused, nothing sent)."""
        setting = codec.SETTINGS.get(key)
        if setting is None or not setting.backup:
            raise CommandError(f"{key} is not restored (read-only, or RAM only like the vehicle counter)")
        await self.write_setting(session, key, from_json(setting, raw))

    async def save_step(self) -> str:
        return "no save step: the MO 64 stores every setting in its EEPROM as it is written (chapter 4)"


# -- the adapter methods the declared "set ..." commands run (devices/mo64/policy.py) -------------------------
def setting_method(key: str) -> str:
    """The adapter method of the declared "set ..." command of setting ``key``, e.g. ``write_t_open``."""
    return f"write_{key}"


def _setting(key: str):
    async def run(self: Mo64Settings, session: str, *numbers: int, selector_verified: bool = False) -> str:
        return await self.write_declared(session, key, list(numbers), selector_verified=selector_verified)

    run.__name__ = setting_method(key)
    run.__doc__ = f"set {codec.SETTINGS[key].name}, as the declared command of that name."
    return run


# "change monitoring" is declared as on/off (see set_change_monitoring)
SETTING_WRITES = {key: _setting(key) for key in codec.SETTINGS if key != "change_monitoring"}
"""The method of each declared "set ..." command, a member of :class:`Mo64Settings` under its name."""
for _run in SETTING_WRITES.values():
    assert _run.__name__ not in vars(Mo64Settings), _run.__name__
    setattr(Mo64Settings, _run.__name__, _run)


def _normal(setting: codec.Setting, value: Any) -> Any:
    """``value`` as the read-back decodes it (a mapping of bits becomes its number)."""
    return setting.vtype.decode(setting.vtype.encode(value))
