"""The running plant: state store, bus worker and (in simulation) the device twins."""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import tempfile
import time
from pathlib import Path
from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

from app import host, memory
from app.aio import end_tasks
from app.audit import AuditLog
from app.auth import AuthSessions, LoginThrottle
from app.backup import write_atomic
from app.can_bus import CanBus, CanBusState
from app.i18n import N_
from app.message import Message, message_of
from app.plant import Plant
from app.state import StateStore
from app.users import UserStore
from app.worker import Worker
from devices.registry import DEVICE_TYPES

log = logging.getLogger(__name__)


@runtime_checkable
class OptionsKeeper(Protocol):
    """An adapter that says what the plant file should hold for its device (e.g. a setting the device took)."""

    def plant_options(self) -> dict[str, Any]: ...


@runtime_checkable
class ControlledTwin(Protocol):
    """A twin that declares its simulation controls (``controls()`` in devices/<type>/sim.py)."""

    def controls(self) -> Any: ...


PROCESS_NICE = -5  # the GUI process ahead of a browser and other busy programs of the same machine (keep-alive threads: -10)


def raise_priority(nice: int = PROCESS_NICE) -> bool:
    """Ask for a higher scheduling priority (a lower nice value) for this thread and every thread it starts
    afterwards, where the system allows it (CAP_SYS_NICE, or a raised RLIMIT_NICE; on Windows the above-normal
    priority class, which any user may set: app/host.py); else nothing changes.

    The keep-alive threads ask for more (app/realtime.py), but they need the interpreter lock
    for every frame: a thread of the same process that holds it and is put aside for a browser's renderer
    keeps them waiting. bench/keepalive_jitter.py phase (c), 20 pages on two busy cores (load 15): worst
    Electrak control gap 572 ms with the process at 0, 266 ms at -10. Call it before threads are started.
    Returns whether the priority is now at least ``nice``."""
    host.raise_session_group(nice)  # Linux with autogroups; nothing elsewhere
    try:
        if host.get_nice(0) > nice:
            host.set_nice(0, nice)
        return host.get_nice(0) <= nice
    except host.Unsupported:  # Windows: no nice values; the above-normal priority class instead
        pass
    except (OSError, AttributeError):  # not permitted
        return False
    try:
        host.set_process_above_normal()
        return True
    except (OSError, AttributeError):
        return False


def freeze_startup_heap() -> int:
    """Once the program has started: collect what the start left behind, then move every object that is
    left (modules, pages' code, the plant, adapters: hundreds of thousands, alive for the whole run) out of
    the cyclic collector's sight (``gc.freeze``). A full collection then walks only what was made since,
    a fraction of the heap: it holds the interpreter lock for a few milliseconds instead of a hundred or
    more, during which no thread of the program (the keep-alive senders among them) could run.
    Returns the number of objects frozen. Only for a program's own process (the GUI, ``commission sim``),
    never in a test run that starts many runtimes in one process."""
    import gc

    gc.collect()
    gc.freeze()
    return gc.get_freeze_count()


class FullCollections:
    """Full collections of the cyclic garbage collector at moments of the program's choosing.

    A full collection walks every object the pages and buffers hold (with 20 pages open a hundred
    milliseconds of CPU and more) without giving up the interpreter lock: no keep-alive thread can send
    meanwhile, and an Electrak flags a message timeout after 250 ms. CPython starts them whenever its
    counts say so; here the young generations stay automatic, the full collection is checked once a
    second and runs when CPython's own count (ten collections of the middle generation) says it is due
    and at least ``min_gap_s`` after the last one (cyclic garbage of closed pages waits that long), but
    not while ``busy()`` (default: a motion or mains output runs under a lease, or a CAN keep-alive is
    sent for a device under control), for at most ``longest_defer_s`` (then it runs anyway: memory
    stays bounded). For the program's own process (the GUI), not for tests that share one interpreter.
    """

    def __init__(self, min_gap_s: float = 120.0, longest_defer_s: float = 600.0, check_s: float = 1.0,
                 busy: Callable[[], bool] | None = None):
        self.min_gap_s, self.longest_defer_s, self.check_s = min_gap_s, longest_defer_s, check_s
        self.busy = busy if busy is not None else _keepalives_busy
        self.runs = 0
        self.deferred = 0  # checks at which it was due but a lease held it back
        self.last_ms: float | None = None  # CPU time of the last full collection
        self._task: asyncio.Task | None = None
        self._thresholds: tuple[int, int, int] | None = None

    def start(self) -> None:
        import gc

        self._thresholds = gc.get_threshold()
        young, middle, _full = self._thresholds
        gc.set_threshold(young, middle, 1 << 30)  # the full generation: only from here
        self._task = asyncio.get_running_loop().create_task(self._run(), name="full collections")

    async def stop(self) -> None:
        import gc

        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None
        if self._thresholds is not None:
            gc.set_threshold(*self._thresholds)
            self._thresholds = None

    def due(self, now: float, last: float, due_since: float | None, busy: bool) -> bool:
        """Whether to collect now: due by count and gap, and nothing running under a lease (or put off too long)."""
        if not self._counted_due(now, last):
            return False
        return not busy or (due_since is not None and now - due_since >= self.longest_defer_s)

    def _counted_due(self, now: float, last: float) -> bool:
        import gc

        every = self._thresholds[2] if self._thresholds is not None else gc.get_threshold()[2]
        return gc.get_count()[2] > every and now - last >= self.min_gap_s

    async def _run(self) -> None:
        import gc

        last = time.monotonic()
        due_since: float | None = None
        while True:
            await asyncio.sleep(self.check_s)
            now = time.monotonic()
            busy = self.busy()
            if self.due(now, last, due_since, busy):
                started = time.process_time()
                gc.collect()
                self.last_ms = (time.process_time() - started) * 1000
                self.runs += 1
                last, due_since = time.monotonic(), None
            elif busy and self._counted_due(now, last):
                self.deferred += 1
                if due_since is None:
                    due_since = now


def _keepalives_busy() -> bool:
    """A motion or mains output runs under a lease, or a CAN keep-alive is being sent (a device under control)."""
    from app.can_bus import keepalives_running
    from devices.lease import any_granted

    return any_granted() or keepalives_running()


def _open_can(name: str, options: dict[str, Any]) -> CanBus:
    return CanBus(name, options, CanBusState(name, "can", ""))


class SimulatedPlant:
    """The twins of every simulated bus of a plant, on the buses' own endpoints."""

    def __init__(self, plant: Plant, only_flagged: bool = True):
        self.plant = plant
        self.servers: list[Any] = []
        self.twins: dict[str, Any] = {}
        for bus in plant.buses.values():
            if only_flagged and not bus.simulated:
                continue
            by_type: dict[str, list] = {}
            extra = [d for d in plant.sim_devices.values() if d.bus == bus.name]
            for dev in plant.devices_on(bus.name) + extra:
                by_type.setdefault(dev.type, []).append(dev)
            for type_name, devs in by_type.items():
                sim_class = DEVICE_TYPES[type_name].sim_class(bus.type)
                if sim_class is None:
                    continue
                # the twins of a CAN bus get their own bus object of the kind the worker uses (passed in:
                # devices/ imports nothing of app/)
                server = sim_class(bus, devs, open_can=_open_can) if bus.type == "can" else sim_class(bus, devs)
                self.servers.append(server)
                self.twins.update(server.twins)

    async def start(self) -> list[str]:
        """Start every twin server; returns the errors of those that could not start."""
        errors = []
        for server in self.servers:
            try:
                await server.start()
            except OSError as exc:
                errors.append(str(exc))
        return errors

    async def stop(self) -> None:
        for server in self.servers:
            await server.stop()


STALE_PART_S = 60.0  # a temporary file older than this at start-up belongs to an interrupted write
UNSAVED_FILE = "unsaved.json"


def secure_data_dir(path: Path) -> None:
    """The data folder holds accounts, the audit log, sessions and backups: owner only (POSIX mode 0700;
    on Windows the user profile's ACL, see :func:`app.host.protect_folder`)."""
    host.protect_folder(path)


def remove_stale_parts(folder: Path, older_than_s: float = STALE_PART_S) -> list[Path]:
    """Delete the hidden ``.*.part`` files that interrupted atomic writes left behind."""
    removed = []
    if not folder.is_dir():
        return removed
    limit = time.time() - older_than_s
    for path in folder.rglob(".*.part"):
        try:
            if path.is_file() and path.stat().st_mtime < limit:
                path.unlink()
                removed.append(path)
        except OSError as exc:
            log.warning("cannot remove the stale temporary file %s: %s", path, exc)
    for path in removed:
        log.info("removed %s, left by an interrupted write", path)
    return removed


class Runtime:
    """Everything one ``commission`` process runs for one plant.

    :param data_dir: accounts, the audit database and backups (default: a temporary
        folder, so tests and throw-away runs leave nothing behind; the CLI passes the
        user's data folder)
    :param auth_required: sessions must log in (the GUI listens beyond the loopback address)
    """

    def __init__(self, plant: Plant, simulate: bool = True, data_dir: str | Path | None = None, auth_required: bool = False):
        self.plant = plant
        if data_dir is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="commission-")
            data_dir = self._tmp.name
        self.data_dir = Path(data_dir)
        secure_data_dir(self.data_dir)
        remove_stale_parts(self.data_dir)
        self.audit = AuditLog(self.data_dir / "audit.sqlite")
        self.users = UserStore(self.data_dir / "users.toml")
        self.sessions = AuthSessions()
        self.login_throttle = LoginThrottle()
        self.backups_dir = self.data_dir / "backups"
        self.auth_required = auth_required
        self.store = StateStore()
        self.sim = SimulatedPlant(plant) if simulate else None
        # the gate asks the account store at every action; reminders and kept options are durable before a write
        # is reported done
        self.worker = Worker(plant, self.store, audit=self.audit, role_of=self.role_of, after_change=self.after_change)
        self._unsaved_path = self.data_dir / UNSAVED_FILE
        self._unsaved_lock = asyncio.Lock()
        self._unsaved_written = self._load_unsaved()
        self._tasks: list[asyncio.Task] = []
        from app.open_reads import OpenReads
        from app.record import RecordService

        self.record = RecordService(self)  # approved sets, snapshots, checkouts, sign-offs (record.sqlite)
        self.open_reads = OpenReads(self)  # what a device page reads by itself on opening (DeviceType.open_reads)
        from app.replace import ReplacementWatch

        self.replacements = ReplacementWatch(self)  # "replaced?": each device's identity against its known one
        self.mqtt = None  # the broker publisher, when the plant file has an [mqtt] table (docs/mqtt.md)
        if plant.mqtt is not None:
            from app.mqtt import MqttPublisher

            self.mqtt = MqttPublisher(plant.mqtt, self.store, plant.name, audit=self.audit)
        self.opcua = None  # the read-only OPC UA server, when the plant file has an [opcua] table
        if plant.opcua is not None:
            from app.opcua_server import OpcuaServer

            self.opcua = OpcuaServer(plant.opcua, self.store, plant, worker=self.worker, users=self.users, audit=self.audit,
                                     throttle=self.login_throttle)

    def session_user(self, token: str | None):
        """The account a session token stands for, as the account store says now (or None)."""
        name = self.sessions.user_of(token)
        return None if name is None else self.users.users.get(name)

    def role_of(self, user: str) -> str | None:
        """The role of ``user`` now: None on loopback without accounts (the caller's role stands, every
        browser is the local engineer), else the account's role, "" for an account that is gone."""
        if not self.auth_required:
            return None
        account = self.users.users.get(user)
        return "" if account is None else account.role

    @property
    def twins(self) -> dict[str, Any]:
        return self.sim.twins if self.sim else {}

    def sim_controls(self, device: str):
        """The declared simulation controls of ``device``'s twin (``controls()`` in devices/<type>/sim.py,
        a devices.simcontrols.SimControls), or None: not simulated here, or a twin that declares none yet."""
        twin = self.twins.get(device)
        return twin.controls() if isinstance(twin, ControlledTwin) else None

    # -- unsaved changes survive a restart (volatile device settings) -----------------------
    def _unsaved_now(self) -> dict[str, list[str]]:
        return {name: sorted(state.unsaved) for name, state in self.store.devices.items() if state.unsaved}

    def _load_unsaved(self) -> dict[str, list[str]]:
        try:
            data = json.loads(self._unsaved_path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            return {}
        except (OSError, ValueError) as exc:
            log.warning("%s cannot be read (%s): unsaved-change reminders of the last run are lost", self._unsaved_path, exc)
            return {}
        plant_data = data.get(self.plant.name, {}) if isinstance(data, dict) else {}
        for name, keys in plant_data.items():
            state = self.store.devices.get(name)
            if state is not None and isinstance(keys, list):
                state.unsaved.update(str(k) for k in keys)
                state.event("warning", Message(N_("{count} parameter(s) written in an earlier session are not saved in the "
                                                  "device yet"), count=len(keys)))
        return self._unsaved_now()

    async def after_change(self) -> None:
        """After every change the worker ran: the unsaved-change reminders and the device options an adapter keeps
        in the plant file (an M3IO's P2, ``plant_options()``) onto disk."""
        await self.keep_unsaved_now()
        await self.keep_plant_options()

    async def keep_plant_options(self) -> None:
        """What an adapter says the plant file should hold (``plant_options()``), kept there (app.plant_options.keep_device_options)."""
        from app.plant import PlantError
        from app.plant_options import keep_device_options, options_to_keep

        for name, adapter in list(self.worker.adapters.items()):
            if not isinstance(adapter, OptionsKeeper) or not options_to_keep(self.plant, name, adapter.plant_options()):
                continue  # nothing to keep, or the plant holds it already (no thread for it)
            state = self.store.devices.get(name)
            try:
                done = await asyncio.to_thread(keep_device_options, self.plant, name, adapter.plant_options())
            except (OSError, PlantError) as exc:
                done = ""
                if state is not None:
                    state.event("error", Message(N_("the plant file could not keep {options}: {error}"),
                                                 options=str(adapter.plant_options()), error=message_of(exc)))
            if done and state is not None:
                state.event("info", done)

    async def keep_unsaved_now(self) -> None:
        """The unsaved-change reminders on disk now, if they changed (in a thread): the worker awaits this
        after every change it ran, so a write is reported done only once its reminder survives a crash."""
        async with self._unsaved_lock:  # one writer at a time: the newest reminders are the ones on disk
            now = self._unsaved_now()
            if now == self._unsaved_written:
                return
            try:
                await asyncio.to_thread(self._write_unsaved, now)
                self._unsaved_written = now
            except OSError as exc:
                log.error("cannot keep the unsaved-change reminders in %s: %s", self._unsaved_path, exc)

    async def _keep_unsaved(self) -> None:
        """Write the unsaved-change reminders to the data folder whenever they change (in a thread); a
        change the worker ran is written at once (:meth:`keep_unsaved_now`), this catches the rest."""
        while True:
            await asyncio.sleep(1.0)
            await self.keep_unsaved_now()

    def _write_unsaved(self, now: dict[str, list[str]]) -> None:
        try:
            data = json.loads(self._unsaved_path.read_text(encoding="utf-8"))
            if not isinstance(data, dict):
                data = {}
        except (OSError, ValueError):
            data = {}
        data[self.plant.name] = now  # other plants' reminders in the same data folder stay
        write_atomic(self._unsaved_path, json.dumps(data, indent=1))

    async def _watch_accounts(self) -> None:
        """Removed accounts and changed roles take effect at once, not at the next restart."""
        while True:
            await asyncio.sleep(1.0)
            try:
                await asyncio.to_thread(self.users.reload_if_changed)
            except Exception as exc:  # noqa: BLE001 - a task that must not end: a broken file keeps the last good accounts
                log.error("accounts: %s", exc)

    async def start(self) -> None:
        started = time.time()  # the record acts on every audit row from now on (app/record.py)
        problem = await asyncio.to_thread(self.audit.check_writable)
        if problem:
            log.error("the audit log cannot be written (%s): every write will be refused until it can", problem)
        if self.sim:
            for error in await self.sim.start():
                log.error("%s", error)
                for bus in self.store.buses.values():
                    if bus.name in error:
                        bus.last_error = error
        if self.opcua is not None:
            await self.opcua.start()  # before the buses: building its address space takes the loop for a moment
        await self.worker.start()
        await self.record.start(since=started)
        await self.replacements.start()
        self._tasks = [asyncio.create_task(self._keep_unsaved(), name="unsaved reminders"),
                       asyncio.create_task(self._watch_accounts(), name="accounts"),
                       asyncio.create_task(memory.keep_trimmed(), name="heap trim")]
        if self.mqtt is not None:
            await self.mqtt.start()  # its own tasks: a broker that is away never holds up the buses

    async def stop(self) -> None:
        if self.opcua is not None:
            await self.opcua.stop()
        if self.mqtt is not None:
            await self.mqtt.stop()  # bounded; says "offline, stopped" to the broker while the store still holds the devices
        await end_tasks(self._tasks, "runtime")
        self._tasks = []
        now = self._unsaved_now()
        if now != self._unsaved_written:
            try:
                await asyncio.to_thread(self._write_unsaved, now)
            except OSError as exc:
                log.error("cannot keep the unsaved-change reminders: %s", exc)
        await self.replacements.stop()
        await self.record.stop()
        await self.worker.stop()
        if self.sim:
            await self.sim.stop()


_current: Runtime | None = None


def current() -> Runtime:
    if _current is None:
        raise RuntimeError("no plant is running")
    return _current


def set_current(runtime: Runtime | None) -> None:
    global _current
    _current = runtime
