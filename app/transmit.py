"""The engineer's CAN transmit list of one bus: rows sent once or cyclically through the bus owner.

Rows are entered as bytes or built by name from the frames each device type declares
(``transmit_forms`` in its policy.py). Every send and every cyclic start/stop goes through
the worker's gate (:meth:`app.gate.CommandGate.run` / ``refused``): engineer role, audit row.
Frames that a device document forbids are refused by name before anything is sent
(:func:`forbidden_reason`). Cyclic rows belong to the browser session that started them and stop
under the worker's dead-man rule (``holders`` / ``session_lost``). The list is saved per bus as
JSON in the data folder, written in a thread.
"""

from __future__ import annotations

import asyncio
import json
import logging
import secrets
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from app import recording as rec
from app.backup import write_atomic
from app.can_stats import CanBusState
from app.i18n import N_
from app.message import Message, joined, message_of
from devices.commands import TxForm, transmit_forms
from devices.errors import CommissionError
from devices.sendpolicy import BusDevice, Verdict, check_can

log = logging.getLogger(__name__)

STD_ID_MAX = 0x7FF
EXT_ID_MAX = 0x1FFFFFFF
PERIOD_MIN_MS = 10
PERIOD_MAX_MS = 10_000
MAX_ROWS = 64  # rows per bus: the list, its file and the page stay small
FILE_PREFIX = "transmit-"


class TransmitError(CommissionError, ValueError):
    """An entry or a request that is refused (out of range, forbidden by a device document)."""


@dataclass
class TxRow:
    """One row: a frame, sent once (``period_ms`` None) or every ``period_ms``."""

    can_id: int
    extended: bool
    data: bytes
    period_ms: int | None = None
    label: str = ""  # how it was built, e.g. "M3IO heater DigOut: LED SSR1"
    key: str = field(default_factory=lambda: secrets.token_hex(4))

    @property
    def dlc(self) -> int:
        return len(self.data)

    def id_text(self) -> str:
        return f"0x{self.can_id:08X} ext" if self.extended else f"0x{self.can_id:03X}"

    def describe(self) -> str:
        data = self.data.hex(" ").upper() or "(no data)"
        text = f"{self.id_text()} [{self.dlc}] {data}"
        return f"{text} ({self.label})" if self.label else text

    def as_json(self) -> dict:
        d = asdict(self)
        d["data"] = self.data.hex()
        return d

    @classmethod
    def from_json(cls, d: dict) -> TxRow:
        return make_row(int(d["can_id"]), bool(d["extended"]), bytes.fromhex(d["data"]), d.get("period_ms"),
                        str(d.get("label", "")), key=str(d.get("key") or secrets.token_hex(4)))


def parse_bytes(text: str) -> bytes:
    """``"01 02 ff"``, ``"0102FF"`` or ``"01,02,FF"`` -> bytes (0..8)."""
    cleaned = text.replace(",", " ").replace("0x", " ").replace("0X", " ").split()
    if len(cleaned) == 1 and len(cleaned[0]) > 2:
        cleaned = [cleaned[0][i:i + 2] for i in range(0, len(cleaned[0]), 2)]
    try:
        data = bytes(int(b, 16) for b in cleaned)
    except ValueError:
        raise TransmitError(Message(N_("'{text}' is not a list of hex bytes (e.g. 01 02 FF)"), text=text)) from None
    if len(data) > 8:
        raise TransmitError(too_many_bytes(len(data)))
    return data


def too_many_bytes(n: int) -> Message:
    """``n`` data bytes, more than a classic CAN frame carries."""
    return Message(N_("{n} data bytes: a classic CAN frame carries 0..8"), n=n)


def make_row(can_id: int, extended: bool, data: bytes, period_ms: int | None = None, label: str = "", *,
             dlc: int | None = None, key: str | None = None) -> TxRow:
    """A checked row: ID range by format, DLC 0..8 matching the data, period 10 ms .. 10 s."""
    limit = EXT_ID_MAX if extended else STD_ID_MAX
    if not 0 <= can_id <= limit:
        raise TransmitError(Message(N_("ID 0x{id:X} does not fit a {bits}-bit ID (0..0x{limit:X})"), id=can_id,
                                    bits=29 if extended else 11, limit=limit))
    if dlc is not None and dlc != len(data):
        raise TransmitError(Message(N_("DLC {dlc} but {n} data bytes"), dlc=dlc, n=len(data)))
    if len(data) > 8:
        raise TransmitError(too_many_bytes(len(data)))
    if period_ms is not None and not PERIOD_MIN_MS <= int(period_ms) <= PERIOD_MAX_MS:
        raise TransmitError(Message(N_("cycle time {period} ms is outside {low} ms .. {high} s"), period=period_ms,
                                    low=PERIOD_MIN_MS, high=PERIOD_MAX_MS // 1000))
    row = TxRow(can_id, extended, bytes(data), None if period_ms is None else int(period_ms), label)
    if key:
        row.key = key
    return row


# -- what the device policies say --------------------------------------------------------------------


class NeedsConfirmation(TransmitError):
    """The frame may be sent once the engineer confirmed the risks named in the message."""


def _bus_devices(bus_devices) -> list:
    """The devices of the bus as :class:`devices.sendpolicy.BusDevice` (``(type, options)`` pairs accepted)."""
    out = []
    for i, d in enumerate(bus_devices):
        if isinstance(d, tuple):
            out.append(BusDevice(f"{d[0]}-{i + 1}", d[0], dict(d[1])))
        else:
            out.append(d)
    return out


def verdict(row_or_id, extended: bool = False, data: bytes = b"", bus_devices=()) -> Verdict:
    """The device policies' verdict on a frame (:func:`devices.sendpolicy.check_can`)."""
    if isinstance(row_or_id, TxRow):
        return check_can(_bus_devices(bus_devices), row_or_id.can_id, row_or_id.extended, row_or_id.data)
    return check_can(_bus_devices(bus_devices), row_or_id, extended, data)


def forbidden_reason(can_id: int, extended: bool, data: bytes, bus_devices=()) -> str | None:
    """Why a frame is never sent by this tool, named after the document; None when it may be sent."""
    return verdict(can_id, extended, data, bus_devices).refused or None


# -- frames this tool sends itself ---------------------------------------------------------------------

OWN_CYCLIC_HEARD_S = 1.0  # a cyclic frame of this tool counts as running while its last one is this recent (and
# within three of its cycles)


def _cycle_text(cycle_s: float) -> Message:
    return Message("{ms:.0f} ms", ms=cycle_s * 1000) if cycle_s < 1.0 else Message("{s:.1f} s", s=cycle_s)


def overridden_by(worker, bus: str, can_id: int, extended: bool, *, now: float | None = None,
                  own_rows: tuple[int, ...] = ()) -> str | Message:
    """Why a frame sent now does not last, or "": this tool itself sends the same ID cyclically (a device's
    keep-alive it serves, such as an M3IO's DigOut), and its next frame replaces what was sent. Read from what the
    bus heard this tool send (its ID table), so any device's keep-alive is found by the same rule.

    :param own_rows: IDs of this list's own running cyclic rows (not the keep-alive of a device)
    """
    state = worker.store.buses.get(bus)
    stats = state.ids.get((extended, can_id)) if isinstance(state, CanBusState) else None
    if stats is None or stats.direction != "tx" or can_id in own_rows:
        return ""
    cycles = stats.cycles()
    if not cycles:
        return ""
    cycle_s = cycles[0][2]
    now = time.time() if now is None else now
    if now - stats.last_time > max(3 * cycle_s, OWN_CYCLIC_HEARD_S):
        return ""
    data = bytes(stats.data)
    owner = rec.device_of(rec.device_owners(worker, bus), can_id, extended, data)
    types = {d.type for d in worker.plant.devices_on(bus)}
    meaning = rec.FrameDecoder(worker.known_ids(bus), rec.describers(worker, bus, types))(can_id, extended, data)
    what = f" ({meaning})" if meaning != rec.UNKNOWN else ""
    cycle = _cycle_text(cycle_s)
    ident = f"0x{can_id:08X} ext" if extended else f"0x{can_id:03X}"
    if owner:
        return Message(N_("{owner} is served by this tool, which sends {ident} itself every {cycle}{what}: its next one, "
                          "within {cycle}, sets {owner} back to what its page shows. To change {owner}, use its page."),
                       owner=owner, ident=ident, cycle=cycle, what=what)
    return Message(N_("This tool sends {ident} itself every {cycle}{what}: its next one, within {cycle}, replaces what "
                      "you send."), ident=ident, cycle=cycle, what=what)


# -- rows built from device messages ----------------------------------------------------------------


def named_forms(type_name: str, options: dict) -> list[TxForm]:
    """The frames a device of the plant offers to build by name (declared in its type's policy.py)."""
    return transmit_forms(type_name, options)


def named_row(type_name: str, device: str, options: dict, form: str, values: dict) -> TxRow:
    """The row of the device frame ``form`` built from ``values`` (:raises TransmitError: no such frame, or
    values its codec refuses)."""
    found = next((f for f in named_forms(type_name, options) if f.title == form), None)
    if found is None:
        raise TransmitError(Message(N_("{device} offers no frame called {form!r}"), device=device, form=form))
    try:
        can_id, extended, data, label = found.build(device, options, values)
    except (KeyError, TypeError, ValueError) as exc:
        raise TransmitError(Message("{device} {form}: {error}", device=device, form=form, error=message_of(exc))) from None
    return make_row(can_id, extended, data, label=label)


# -- the list ------------------------------------------------------------------------------------


class TransmitList:
    """The transmit list of one CAN bus, registered with the worker as a dead-man holder."""

    def __init__(self, worker, bus: str, folder: Path | None):
        self.worker = worker
        self.bus = bus
        self.path = None if folder is None else Path(folder) / f"{FILE_PREFIX}{bus}.json"
        self.rows: list[TxRow] = []
        self.running: dict[str, tuple[str, str]] = {}  # row key -> (session, user) of a cyclic row
        self.sent: dict[str, int] = {}  # row key -> frames sent (once or cyclic)
        self.loaded = asyncio.Event()
        self.load_error = ""
        self.version = 0  # changes whenever rows or their state change (pages redraw on it)

    # -- dead-man rule -------------------------------------------------------------------
    def holders(self) -> set[str]:
        return {session for session, _user in self.running.values()}

    def session_lost(self, session: str, reason: str) -> None:
        """Stop at once every cyclic row the session started; audit afterwards (off the stop path)."""
        stopped = [key for key, (s, _u) in self.running.items() if s == session]
        for key in stopped:
            _s, user = self.running.pop(key)
            self._can().stop_cyclic(self._cyclic_key(key))
            row = self.row(key)
            if row is not None:
                asyncio.get_running_loop().create_task(self._audit_stop(row, user, reason))
        if stopped:
            self.version += 1

    async def _audit_stop(self, row: TxRow, user: str, reason: str) -> None:
        try:
            await self.worker.gate.run(self._nothing, device=self.bus, role="engineer", user=user, kind="stop",
                                       describe=f"transmit: cyclic {row.describe()} stopped: {reason}")
        except CommissionError as exc:  # stopped anyway; the audit state shows the failure
            log.error("audit: %s", exc)

    @staticmethod
    async def _nothing() -> None:
        return None

    # -- persistence -----------------------------------------------------------------------
    async def load(self) -> None:
        """Read the saved list (in a thread); a damaged file is reported and kept aside, not used."""
        try:
            if self.path is not None:
                rows = await asyncio.to_thread(self._read)
                self.rows = rows[:MAX_ROWS]
        except (OSError, ValueError) as exc:  # unreadable or damaged: shown on the page
            self.load_error = Message(N_("the saved list {path} could not be read: {error}"), path=self.path, error=message_of(exc))
            log.warning("%s", self.load_error)
        finally:
            self.version += 1
            self.loaded.set()

    def _read(self) -> list[TxRow]:
        if self.path is None or not self.path.exists():
            return []
        doc = json.loads(self.path.read_text(encoding="utf-8"))
        entries = doc.get("rows", []) if isinstance(doc, dict) else None
        if not isinstance(entries, list):
            raise ValueError(Message(N_("it holds no list of rows")))
        rows = []
        for entry in entries:
            try:
                rows.append(TxRow.from_json(entry))
            except (KeyError, ValueError, TypeError) as exc:
                log.warning("%s: a row of %s is skipped: %s", self.bus, self.path, exc)
        return rows

    async def save(self) -> None:
        if self.path is None:
            return
        text = json.dumps({"schema": "commission-transmit", "version": 1, "bus": self.bus,
                           "rows": [r.as_json() for r in self.rows]}, indent=1)
        await asyncio.to_thread(write_atomic, self.path, text)

    # -- helpers ---------------------------------------------------------------------------
    def _can(self):
        return self.worker.can_buses[self.bus]

    def _cyclic_key(self, key: str) -> str:
        return f"transmit {self.bus} {key}"

    def row(self, key: str) -> TxRow | None:
        return next((r for r in self.rows if r.key == key), None)

    def bus_devices(self) -> list:
        return list(self.worker.plant.devices_on(self.bus))

    def is_running(self, key: str) -> bool:
        return key in self.running and self._can().cyclic_running(self._cyclic_key(key))

    def overridden(self, row: TxRow) -> str:
        """Why ``row`` sent now does not last (:func:`overridden_by`), or ""."""
        own = tuple(r.can_id for r in self.rows if r.extended == row.extended and r.key != row.key and self.is_running(r.key))
        return overridden_by(self.worker, self.bus, row.can_id, row.extended, own_rows=own)

    async def _refuse_if_forbidden(self, row: TxRow, *, user: str, role: str, describe: str,
                                   confirmed: bool | None = None) -> Verdict:
        """Refuse (audited) what the device policies forbid; with ``confirmed`` False, ask for their risks first,
        and say so when a frame of this tool overrides the row (:meth:`overridden`)."""
        found = verdict(row, bus_devices=self.bus_devices())
        if found.refused:
            await self.worker.gate.refused(device=self.bus, user=user, role=role, describe=describe, reason=found.refused,
                                           parameter=found.name or row.id_text(), new=row.data.hex(" "))
            raise TransmitError(found.refused)
        if confirmed is False:
            note = self.overridden(row)
            if found.confirm or note:
                raise NeedsConfirmation(joined([t for t in (found.question, note) if t], " "))
        return found

    # -- edits (engineer only, audited) -------------------------------------------------------
    async def add(self, row: TxRow, *, user: str, role: str) -> TxRow:
        describe = f"transmit list {self.bus}: add {row.describe()}"
        await self._refuse_if_forbidden(row, user=user, role=role, describe=describe)
        if len(self.rows) >= MAX_ROWS:
            full = Message(N_("the list holds at most {n} rows"), n=MAX_ROWS)
            await self.worker.gate.refused(device=self.bus, user=user, role=role, describe=describe, reason=full)
            raise TransmitError(full)

        async def do() -> str:
            self.rows.append(row)
            self.version += 1
            await self.save()
            return ""

        await self.worker.gate.run(do, user=user, role=role, describe=describe, device=self.bus,
                                   parameter=row.id_text(), new=row.data.hex(" "), kind="write")
        return row

    async def remove(self, key: str, *, user: str, role: str, session: str = "") -> None:
        row = self.row(key)
        if row is None:
            raise TransmitError(Message(N_("no such row")))
        if key in self.running:
            await self.stop(key, user=user, role=role)

        async def do() -> str:
            self.rows = [r for r in self.rows if r.key != key]
            self.sent.pop(key, None)
            self.version += 1
            await self.save()
            return ""

        await self.worker.gate.run(do, user=user, role=role, describe=f"transmit list {self.bus}: remove {row.describe()}",
                                   device=self.bus, parameter=row.id_text(), kind="write")

    # -- sending ---------------------------------------------------------------------------------
    async def send_once(self, key: str, *, user: str, role: str, confirmed: bool = False) -> str:
        """Send a row once; returns why it does not last ("" when nothing of this tool overrides it).

        :raises NeedsConfirmation: its device policy names a risk, or a frame of this tool overrides it, and
            ``confirmed`` is False"""
        row = self.row(key)
        if row is None:
            raise TransmitError(Message(N_("no such row")))
        describe = f"transmit once on {self.bus}: {row.describe()}"
        found = await self._refuse_if_forbidden(row, user=user, role=role, describe=describe, confirmed=confirmed)

        async def do() -> str:
            if not self._can().send(row.can_id, row.data, row.extended):
                raise TransmitError(Message(N_("bus {bus} did not take the frame: {error}"), bus=self.bus,
                                            error=self._can().state.last_error or Message(N_("not open"))))
            self.sent[key] = self.sent.get(key, 0) + 1
            self.version += 1
            return ""

        note = self.overridden(row)  # before the send: the ID table then names this frame, not the keep-alive
        await self.worker.gate.run(do, user=user, role=role, describe=describe, device=self.bus,
                                   parameter=found.name or row.id_text(), new=row.data.hex(" "), kind="write")
        return note

    async def start(self, key: str, *, user: str, role: str, session: str, confirmed: bool = False) -> str:
        """Start a cyclic row for ``session`` (its browser keeps it alive under the dead-man rule); returns why its
        frames do not last ("" when nothing of this tool sends the same ID)."""
        row = self.row(key)
        if row is None:
            raise TransmitError(Message(N_("no such row")))
        if row.period_ms is None:
            raise TransmitError(Message(N_("this row is sent once: give it a cycle time to send it cyclically")))
        describe = f"transmit cyclic every {row.period_ms} ms on {self.bus}: start {row.describe()}"
        found = await self._refuse_if_forbidden(row, user=user, role=role, describe=describe, confirmed=confirmed)
        if not session:
            raise TransmitError(Message(N_("a cyclic row needs a browser session to keep it alive")))

        def make() -> tuple[int, bytes, bool]:
            self.sent[key] = self.sent.get(key, 0) + 1
            return row.can_id, row.data, row.extended

        async def do() -> str:
            self.running[key] = (session, user)
            self._can().start_cyclic(self._cyclic_key(key), row.period_ms / 1000, make)
            self.version += 1
            return ""

        note = self.overridden(row)
        await self.worker.gate.run(do, user=user, role=role, describe=describe, device=self.bus,
                                   parameter=found.name or row.id_text(), new=row.data.hex(" "), kind="write")
        return note

    async def stop(self, key: str, *, user: str, role: str) -> None:
        """Stop a cyclic row: never refused (any role), stopped first, audited after."""
        self.running.pop(key, None)
        self._can().stop_cyclic(self._cyclic_key(key))
        self.version += 1
        row = self.row(key)
        what = row.describe() if row else key
        await self.worker.gate.run(self._nothing, device=self.bus, role=role, user=user, kind="stop",
                                   describe=f"transmit cyclic on {self.bus}: stop {what}")

    def stop_all(self) -> None:
        for key in list(self.running):
            self.running.pop(key, None)
            self._can().stop_cyclic(self._cyclic_key(key))
        self.version += 1


def holder_name(bus: str) -> str:
    return f"transmit:{bus}"


def transmit_list(worker, bus: str, folder: Path | None) -> TransmitList:
    """The bus's list, created (and registered under the dead-man rule) on first use; load it with ``load()``."""
    name = holder_name(bus)
    existing = worker.extra_holders.get(name)
    if isinstance(existing, TransmitList):
        return existing
    if bus not in worker.can_buses:
        raise KeyError(f"{bus} is not a CAN bus")
    tl = TransmitList(worker, bus, folder)
    worker.add_holder(name, tl)
    return tl

