"""The bus worker: owns every transport, polls every device, runs commands from pages.

Pages never touch a transport. They read :class:`~app.state.StateStore` and call
:meth:`Worker.invoke`, which hands the declared command to the gate (:mod:`app.gate`); it
checks the role, runs the adapter method on the bus task's transport and returns the result
or a clear error.

:class:`Worker` is a composition of one part per job, each a module of this package:

- :mod:`.transports` opens and owns the buses and lines of the plant file;
- :mod:`.adoption` gives each device its record in the store and its adapter on its transport,
  and takes a discovered device into the running plant;
- :mod:`.polling` runs one polling task per bus;
- :mod:`.discovery` lists devices heard on a CAN bus and scans Modbus lines;
- :mod:`.deadman` keeps the browser sessions' beats and stops what a silent one keeps running; it asks
  the page of a session that holds something to beat (through :meth:`Worker.on_beat_ask`: pages beat
  only while they hold something or just after a user interaction);
- :mod:`.loophealth` measures how late the event loop runs the 50 ms supervision tick (slower while
  no page is connected and nothing is held);
- :mod:`.commands` hands commands to the gate and audits them.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable
from typing import Any

from app import gate
from app.audit import AuditLog
from app.can_bus import CanBus
from app.gate import WRITE_ROLES  # noqa: F401 - named here for callers
from app.gate import AuditUnavailable, PermissionDenied  # noqa: F401 - raised by the gate; named here for callers
from app.modbus_line import ModbusLine
from app.plant import DeviceConfig, Plant
from app.state import StateStore
from app.worker import commands, loophealth
from app.worker.adoption import Devices
from app.worker.deadman import (  # noqa: F401 - the dead-man rule's figures, named here for pages and tests
    BEAT_PERIOD_S,
    BEAT_RELEASE_S,
    BEAT_WINDOW_S,
    DEADMAN_BOUND_S,
    DEADMAN_TIMEOUT_S,
    LIVE_CREDIT_S,
    SILENCE_LIMIT_S,
    DeadmanSupervisor,
)
from app.worker.discovery import (  # noqa: F401 - discovery's bounds, named here for tests
    CANDIDATE_STALE_PERIODS,
    FLOOD_NEW_IDS_PER_S,
    FLOOD_QUIET_S,
    MAX_CANDIDATES,
    MAX_DISCOVERED,
    CanDiscovery,
    scan_line,
)
from app.worker.loophealth import IDLE_PERIOD_S, LAG_WINDOW, STALL_S, SUPERVISE_PERIOD_S, LoopHealth  # noqa: F401
from app.worker.polling import Polling
from app.worker.transports import Line, Transports

log = logging.getLogger(__name__)
STOP_S = 5.0  # the bus tasks' end, at most this long


class Worker:
    """Every adapter is reached through it; one polling task per bus, one supervision tick."""

    def __init__(self, plant: Plant, store: StateStore | None = None, audit: AuditLog | None = None):
        self.plant = plant
        self.audit = audit
        self.store = store or StateStore()
        self.transports = Transports(plant, self.store)
        self.devices = Devices(plant, self.store, self.transports)
        self.polling = Polling(plant, self.store, self.devices.adapters, self.transports.can_buses)
        self.extra_holders: dict[str, Any] = {}  # transmit lists, replays: under the dead-man rule like adapters
        self.deadman = DeadmanSupervisor(self._holder_items)
        self.loop_health = LoopHealth()
        self.hurry = loophealth.Hurry()  # a page connecting or a command coming ends the idle tick's wait
        # the flood bound is the module's, passed in, so that a test may choose its own
        self.discovery = CanDiscovery(plant, self.transports.can_buses, flood_ids_per_s=FLOOD_NEW_IDS_PER_S)
        for name, can_bus in self.transports.can_buses.items():
            can_bus.listeners.append(lambda msg, bus=name: self.discovery.frame(bus, msg))
        self.tasks: list[asyncio.Task] = []

    # -- what the parts hold, by the names pages, tools and tests use -----------------------------------
    @property
    def adapters(self) -> dict[str, Any]:
        """Device name -> its adapter."""
        return self.devices.adapters

    @property
    def can_buses(self) -> dict[str, CanBus]:
        return self.transports.can_buses

    @property
    def lines(self) -> dict[str, Line]:
        """Bus name -> its line (every bus that is not CAN)."""
        return self.transports.lines

    @property
    def discovered(self) -> dict[str, dict[tuple[bool, int], dict]]:
        """CAN bus name -> the devices listed on it: (extended, ID) -> what was heard."""
        return self.discovery.discovered

    @property
    def paused(self) -> set[str]:
        """Buses whose polling is held (a line scan runs)."""
        return self.polling.paused

    @property
    def sessions(self) -> dict[str, str]:
        """Connected browser sessions -> role."""
        return self.deadman.sessions

    @property
    def beats(self) -> dict[str, float]:
        """Session -> monotonic time of its last sign of life."""
        return self.deadman.beats

    # -- running ---------------------------------------------------------------------------------------
    async def start(self) -> None:
        await self.transports.open()
        for name in self.plant.buses:
            self.tasks.append(asyncio.create_task(self.polling.run(name), name=f"bus {name}"))
        self.deadman.start_clock()
        self.tasks.append(asyncio.create_task(loophealth.tick(self.loop_health, self.deadman.tick,
                                                              idle_period_s=IDLE_PERIOD_S, hurry=self.hurry),
                                              name="supervisor"))
        self.store.ensure_running()  # the one producer that pushes changes to pages and publishers

    async def stop(self) -> None:
        # A cancellation can be swallowed when pymodbus's wait_for gets its answer in the same
        # loop iteration: cancel again until every task has really ended (bounded).
        pending = set(self.tasks)
        loop = asyncio.get_running_loop()
        end = loop.time() + STOP_S
        while pending and loop.time() < end:
            for task in pending:
                task.cancel()
            _done, pending = await asyncio.wait(pending, timeout=0.2)
        for task in pending:
            log.error("bus task %s did not end", task.get_name())
        self.tasks.clear()
        await self.devices.shutdown()  # on the still open lines
        await self.transports.close()
        await self.store.stop()

    # -- devices ---------------------------------------------------------------------------------------
    def adopt(self, dev: DeviceConfig) -> None:
        """Take a discovered device into the running plant (the plant file is the caller's business).

        :raises ValueError: the name exists, or the device would share a CAN ID with a device of the bus
        """
        self.devices.adopt(dev, self.discovery)

    def known_ids(self, bus: str) -> set[tuple[bool, int]]:
        """IDs of devices on a CAN bus (in the plant or discovered): for decoding in the monitor."""
        can_bus = self.can_buses.get(bus)
        if can_bus is None:
            return set()
        return set(can_bus.handlers) | set(self.discovered.get(bus, {}))

    def discovery_summary(self, bus: str) -> dict:
        """What the overview shows under the discovered devices of a CAN bus."""
        return self.discovery.summary(bus)

    def _discover_frame(self, bus: str, msg) -> None:
        """A frame whose ID no adapter owns (:meth:`CanDiscovery.frame`)."""
        self.discovery.frame(bus, msg)

    async def discover(self, bus: str, first: int, last: int, progress=None) -> list[dict]:
        """Find devices on a Modbus line (broadcast, then a scan), with polling held meanwhile."""
        line = self.lines.get(bus)
        if not isinstance(line, ModbusLine):
            raise KeyError(f"{bus} is not a Modbus RTU line")
        with self.polling.held(bus):
            return await scan_line(self.plant, bus, line, first, last, progress)

    # -- browser sessions and the dead-man rule (:mod:`.deadman`) ----------------------------------------
    def session_opened(self, session: str, role: str = "engineer") -> None:
        self.deadman.session_opened(session, role)
        self.hurry.now()

    def session_connected(self, session: str) -> None:
        """A page's connection is up (again): one that had dropped is asked to beat (:meth:`DeadmanSupervisor.session_connected`)."""
        self.deadman.session_connected(session)

    def on_beat_ask(self, ask: Callable[[str, bool], None]) -> None:
        """``ask(session, on)`` asks the page of ``session`` to beat (True) or to stop beating (False): the web
        layer's way to reach a page (:attr:`DeadmanSupervisor.ask_beat`)."""
        self.deadman.ask_beat = ask

    def session_closed(self, session: str) -> None:
        """A page's connection dropped: stop at once what it keeps running (:meth:`DeadmanSupervisor.session_closed`)."""
        self.deadman.session_closed(session)

    def session_deleted(self, session: str) -> None:
        """A page is gone for good (it did not reconnect): release everything it controlled."""
        self.deadman.session_deleted(session)

    def heartbeat(self, session: str, sent_ms: float | None = None) -> None:
        """A page confirms it is alive (:meth:`DeadmanSupervisor.heartbeat`)."""
        self.deadman.heartbeat(session, sent_ms)
        self.hurry.now()

    def add_holder(self, name: str, holder: Any) -> None:
        """Put something that is not a device adapter (an engineer's cyclic transmit list, a replay)
        under the dead-man rule: it offers ``holders()`` and ``session_lost(session, reason)`` like an adapter."""
        self.extra_holders[name] = holder
        self.hurry.now()

    def remove_holder(self, name: str) -> None:
        self.extra_holders.pop(name, None)

    def _holder_items(self) -> list[tuple[str, Any]]:
        return [*self.adapters.items(), *self.extra_holders.items()]

    def _supervise_deadman(self, now: float) -> None:
        """Apply the dead-man rule at monotonic time ``now`` (:meth:`DeadmanSupervisor.supervise`)."""
        self.deadman.supervise(now)

    # -- commands: the hand-off to the gate (:mod:`.commands`, :mod:`app.gate`) ---------------------------
    async def invoke(self, device: str, name: str, args: dict | None = None, *, user: str, role: str,
                     session: str = "", confirmed: bool = False) -> Any:
        """Run the declared command ``name`` of ``device`` (:func:`app.gate.invoke`)."""
        try:
            return await gate.invoke(self, device, name, args, user=user, role=role, session=session, confirmed=confirmed)
        finally:
            self.hurry.now()  # it may have taken control: supervised from the next tick on, at 50 ms

    async def command(
        self, device: str, action: Callable[[Any], Awaitable[Any]], *, role: str = "engineer", user: str = "local",
        describe: str = "", record: bool = True, parameter: str = "", old: Any = "", new: Any = "",
    ) -> Any:
        """Run ``action(adapter)`` for ``device`` on behalf of a session (the older way, left to the
        worker's own callers such as restore's save step; pages, the API and the tools use :meth:`invoke`).

        The kind comes from the device type's declared command named ``describe`` when there is one
        (:func:`app.gate.kind_for`); anything else counts as a write.
        """
        try:
            return await commands.command(self, device, action, role=role, user=user, describe=describe, record=record,
                                          parameter=parameter, old=old, new=new)
        finally:
            self.hurry.now()

    async def engineer_action(
        self, action: Callable[[], Awaitable[Any]], *, user: str, role: str, describe: str, target: str = "",
        parameter: str = "", new: Any = "",
    ) -> Any:
        """Anything that changes the plant, the plant file, a device or files on disk
        (adopting a device, recordings, line scans, backups): engineer only, audited."""
        return await self.checked(action, device=target, role=role, user=user, describe=describe, parameter=parameter, new=new)

    async def checked(
        self, action: Callable[[], Awaitable[Any]], *, device: str, role: str, user: str, describe: str,
        kind: str = "write", record: bool = True, parameter: str = "", old: Any = "", new: Any = "",
    ) -> Any:
        """The one place where a change is checked (role) and audited (fail closed) before it runs.

        ``kind`` comes from a declared command (:func:`app.gate.invoke`); the worker's own actions that
        are no device command (a simulation control, ending a recording, stopping the transmit list or
        a replay) name theirs. The role is the account store's at this moment (:func:`app.gate.role_now`).
        A ``stop`` runs for every role, first, and is audited afterwards from a queue; a ``read`` for
        every role, unaudited.
        """
        try:
            return await commands.checked(self, action, device=device, role=role, user=user, describe=describe, kind=kind,
                                          record=record, parameter=parameter, old=old, new=new)
        finally:
            self.hurry.now()

    async def refused(
        self, *, device: str, user: str, role: str, describe: str, reason: str, parameter: str = "", new: Any = "",
    ) -> None:
        """An entry or a request refused before anything was sent (out of range, not confirmed, forbidden by
        the device document): logged on the device and in the audit log with the reason."""
        await commands.refused(self, device=device, user=user, role=role, describe=describe, reason=reason,
                               parameter=parameter, new=new)
