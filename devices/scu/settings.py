"""The SCU's settings on its line: the parameter model (devices/scu/model.py) read, written and backed up.

The adapter (devices/scu/adapter.py) owns the session and the line; this module asks it for reads (RG) and
writes (RT with RG read-back) and keeps the live store's words of every modelled value up to date, whoever
read it (a backup, the reads in turn of the poll, the page's own commands): :meth:`ScuSettings.note` is called
for every value the adapter publishes.

A write (restore, project, batch, the API) opens the remote session when it is closed (section 4.1: RT only in
remote mode), is refused while a function runs or a stop is owed (a remote speed changes a running motion,
section 4.6: "Die Geschwindigkeit kann während der Bewegung verändert werden"; a remote position moves the
target of a running RE 9), writes with RT and reads the value back with RG: the unit's answer is what the
store shows, a different one fails the write. Nothing is saved: remote data are volatile (table 7).
"""

from __future__ import annotations

import asyncio
import time
from typing import Any

from devices.message import Message, N_, message_of
from devices.params import Accepted, Param, ParamError, backup_entry
from devices.scu import codec
from devices.scu import params as p
from devices.scu.facts import CommandError, jsonable
from devices.scu.model import PARAMS, SAFETY_ID, VOLATILE, DataParam, params_for, params_of, raw_of
from devices.scu.opening import WATCH_RG

SESSION_WAIT_S = 3.0  # a read or write waits this long for a remote session that is being opened (or in its backoff)
# The data directory's record for the commissioning file, besides the model: identity, counters, error history
# (table 6). Read with the backup, never written.
RECORD_IDS = (0x0001, 0x0002, 0x0060, 0x0070, 0x0080, 0x0090, 0x00B0, 0x00C0, 0x00C1, 0x00D0)
# The groups that hold the model's values (one RG each; a unit that refuses a group is read member by member)
MODEL_GROUPS = (0x3010, 0x3020, 0x1010, 0x2000)
RESTORE_NOTE = Message(N_("each written setting is {volatile}"), volatile=Message(VOLATILE))


class ScuSettings:
    """The parameter model of one SCU on its adapter's line."""

    def __init__(self, adapter):
        self.adapter = adapter
        self.state = adapter.state
        self.params = params_for(len(adapter.scales))
        self.keys = {q.key for q in self.params}
        self.refused: dict[str, str] = {}  # parameter key -> why the unit refused its data ID (a refused selector)
        self.writing = 0  # writes under way: the session stays open for them (a unit watched with RG alone)

    # -- the live store ---------------------------------------------------------------------------
    def note(self, data_id: int, value: Any, now: float | None = None) -> None:
        """A value of ``data_id`` the adapter read (or read back): the words of the parameters it carries."""
        found = params_of(data_id)
        if not found:
            return
        words: dict[tuple[str, int], int] = {}
        for q in found:
            if q.key not in self.keys:
                continue
            try:
                raw = raw_of(q, value)
            except (KeyError, TypeError, ValueError, OverflowError):
                continue
            for address, word in zip(q.addresses, q.split(raw)):
                words[(q.space, address)] = word
            self.refused.pop(q.key, None)
        if words:
            self.state.publish_telegram(time.time() if now is None else now, {}, words)

    def _note_safety_id(self) -> None:
        sid = int(self.adapter.safety_id)
        self.state.publish_telegram(time.time(), {}, {(SAFETY_ID.space, SAFETY_ID.address): sid})

    # -- reads ------------------------------------------------------------------------------------
    async def _session(self, needed: bool) -> None:
        """Wait (at most :data:`SESSION_WAIT_S`) for the remote session where the unit needs one: a compare or a write
        asked just as the unit came online finds the session still being opened (section 4.1: RG and RT only in
        remote mode, unless the unit answers RG without one)."""
        adapter = self.adapter
        if not needed or adapter.session in ("open", "released"):
            return
        deadline = time.monotonic() + SESSION_WAIT_S
        while adapter.session != "open" and time.monotonic() < deadline:
            await adapter.ensure_open()
            if adapter.session != "open":
                await asyncio.sleep(0.1)

    def _needs_session_to_read(self) -> bool:
        return self.adapter.watch != WATCH_RG

    async def _read(self, data_id: int) -> dict[int, Any]:
        """RG of ``data_id`` (a group: its members, one by one when the unit refuses the group): ``{data ID: value}``
        of what the unit answered; a member it refuses is left out and remembered."""
        try:
            result = await self.adapter.read_data(data_id)
        except codec.CommandRefused as exc:
            if exc.code in (codec.Status.PE, codec.Status.CSE):
                raise
            entry = p.item(data_id)
            if not entry.is_group:
                for q in params_of(data_id):
                    self.refused[q.key] = f"{exc.info.name}: the unit refuses RG 0x{data_id:04X}"
                return {}
            out: dict[int, Any] = {}
            for member in entry.members:
                if any(q.key in self.keys for q in params_of(member)):
                    out.update(await self._read(member))
            return out
        value = result["value"]
        if result["error"]:
            raise CommandError(f"RG 0x{data_id:04X}: {result['error']}")
        return dict(value) if p.item(data_id).is_group else {data_id: value}  # a struct's value is a dict too

    async def read_all(self) -> dict[str, int]:
        """Every modelled value of this unit, fresh: ``{key: raw}`` (a value the unit refuses is left out)."""
        values: dict[int, Any] = {}
        await self._session(self._needs_session_to_read())
        for group in MODEL_GROUPS:
            values.update(await self._read(group))
        self._note_safety_id()
        out = {}
        for q in self.params:
            if q.space == SAFETY_ID.space:
                out[q.key] = int(self.adapter.safety_id)
            elif q.address in values:
                out[q.key] = raw_of(q, values[q.address])
        return out

    async def read_param(self, param: Param) -> int:
        """One modelled value, fresh from the unit."""
        q = self._own(param)
        if q.space == SAFETY_ID.space:
            self._note_safety_id()
            return int(self.adapter.safety_id)
        await self._session(self._needs_session_to_read())
        values = await self._read(q.address)
        if q.address not in values:
            raise CommandError(f"{q.name}: {self.refused.get(q.key, 'no answer')}")
        return raw_of(q, values[q.address])

    def _own(self, param: Param) -> DataParam:
        q = PARAMS.by_key.get(param.key)
        if q is None or q.key not in self.keys:
            raise CommandError(f"{param.name} is not a parameter of this SCU ({len(self.adapter.scales)} actuator(s) "
                               "configured)")
        return q

    # -- writes -----------------------------------------------------------------------------------
    def refusal(self, param: DataParam, raw: int) -> str:
        """Why ``raw`` must not be written to ``param`` now, beyond the model's range, or ``""``."""
        adapter = self.adapter
        if param.data_id in range(0x3011, 0x3011 + p.FUNCTIONS) and raw > adapter.speed_max:
            return (f"{param.name}: {raw} is above {adapter.speed_max} {adapter.speed_unit}: the unit's speed select is "
                    f"{adapter.speed_select} (table 7; the plant file's speed_select)")
        running = sorted(adapter.running) + sorted(set(adapter.rs_pending) - set(adapter.running))
        if running:
            names = ", ".join(codec.FUNCTIONS[codec.Function(fn)].label for fn in running)
            return (f"{param.name} is not written while {names} runs or its stop is owed: a remote speed or position "
                    "changes a running motion (section 4.6); stop first")
        return ""

    async def write(self, param: Param, value, *, confirmed: bool = False) -> int:
        """An entry for ``param``, checked by the model, written by :meth:`write_accepted`."""
        try:
            accepted = self._own(param).accept(value)
        except ParamError as exc:
            raise CommandError(message_of(exc)) from None
        return await self.write_accepted(accepted, confirmed=confirmed)

    async def write_accepted(self, accepted: Accepted, *, confirmed: bool = False) -> int:
        """RT and RG read-back (table 3, section 4.6) of a value the model accepted; returns the raw value written
        and read back."""
        q = self._own(accepted.param)
        try:
            raw = accepted.cleared(confirmed)
        except ParamError as exc:
            raise CommandError(message_of(exc)) from None
        reason = self.refusal(q, raw)
        if reason:
            raise CommandError(reason)
        adapter = self.adapter
        number = q.decode(raw)
        self.writing += 1
        try:
            for attempt in (1, 2):  # a PE: the session ended under the write (section 4.2), opened once more
                await self._session(True)
                await adapter.ensure_open()
                adapter.check_open()
                reason = self.refusal(q, raw)  # the session's opening may have sent RE 19 and owed RS: look again
                if reason:
                    raise CommandError(reason)
                try:
                    await adapter.write_read_back(q.data_id, number, q.name)
                    break
                except codec.CommandRefused as exc:
                    if exc.code == codec.Status.PE and attempt == 1:
                        continue
                    self.state.counters.write_errors += 1
                    raise CommandError(f"{q.name} = {q.display(raw)}: the unit answered {exc.info.name} "
                                       f"({exc.info.title})") from None
        finally:
            self.writing -= 1
        self.state.event("info", Message(N_("{name} = {value} written (RT) and read back (RG); {volatile}"), name=q.name,
                                         value=q.display(raw), volatile=Message(VOLATILE)))
        return raw

    # -- backup ------------------------------------------------------------------------------------
    async def backup_read(self, progress=None) -> list[dict]:
        """The model's values (settings and read-only ones, each with name, unit and text), then the record
        entries of table 6 (identity, counters, error history) as the unit answers them."""
        ids = list(RECORD_IDS)
        steps = len(ids) + 1
        raws = await self.read_all()
        entries = [backup_entry(q, raws[q.key]) for q in self.params if q.key in raws]
        if progress:
            progress(1 / steps)
        for k, data_id in enumerate(ids, 2):
            try:
                result = await self.adapter.read_data(data_id)
            except codec.CommandRefused as exc:
                if exc.code == codec.Status.PE:
                    raise
                entries.append({"key": f"0x{data_id:04X}", "name": p.item(data_id).name, "value": None,
                                "text": f"not available on this unit ({exc.info.name})", "unit": p.item(data_id).unit,
                                "raw": "", "writable": False})
                continue
            entries.append({"key": result["key"], "name": result["name"], "value": jsonable(result["value"]),
                            "text": result["text"], "unit": result["unit"], "raw": result["raw"], "writable": False})
            if progress:
                progress(k / steps)
        return entries

    def identity(self) -> dict:
        """What names the unit: the plant file's serial number (section 4.3 has no data ID for one), else the unit's
        configuration info (name, version and checksum of its parametrisation, 0x0002); firmware info (0x0001)."""
        adapter = self.adapter
        firmware, configuration = (None if point is None else point.value for point in
                                   (self.state.points.get("Firmware info"), self.state.points.get("Configuration info")))
        serial = adapter.config.options.get("serial")
        return {"serial": str(serial) if serial not in (None, "") else configuration, "firmware": firmware,
                "configuration": configuration, "actuators": len(adapter.scales), "port": adapter.port,
                "baudrate": adapter.baudrate}


__all__ = ["ScuSettings", "RECORD_IDS", "MODEL_GROUPS", "RESTORE_NOTE"]
