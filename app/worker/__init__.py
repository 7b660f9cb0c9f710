"""The bus worker: owns every transport, polls every device, runs commands from pages.

Pages never touch a transport. They read :class:`~app.state.StateStore` and submit what they
want done to the worker's one way in, its command gate (``worker.gate``, an
:class:`app.gate.CommandGate`): it checks the role, writes the audit row, runs the adapter's
method on the bus task's transport and returns the result or a clear error.

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
  no page is connected and nothing is held).
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable
from typing import Any

from app.aio import end_tasks
from app.audit import AuditLog
from app.can_bus import CanBus
from app.gate import WRITE_ROLES  # noqa: F401 - named here for callers
from app.gate import AuditUnavailable, CommandGate, PermissionDenied, UnknownDevice  # noqa: F401 - raised by the gate; named here for callers
from app.modbus_line import ModbusLine
from app.plant import DeviceConfig, Plant
from app.state import StateStore
from app.worker import loophealth
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


def no_accounts(user: str) -> None:
    """No account store: every caller's role stands."""
    return None


async def nothing_to_keep() -> None:
    """Nothing to make durable after a change."""


class Worker:
    """Every adapter is reached through it; one polling task per bus, one supervision tick.

    :param role_of: the role of a user as the account store says now, None where no accounts are in use
        (the runtime's); by default no accounts: the caller's role stands
    :param after_change: awaited after every action that is not a read (the runtime's: unsaved reminders
        onto disk before a write is reported done)
    """

    def __init__(self, plant: Plant, store: StateStore | None = None, audit: AuditLog | None = None, *,
                 role_of: Callable[[str], str | None] = no_accounts,
                 after_change: Callable[[], Awaitable[None]] = nothing_to_keep):
        self.plant = plant
        self.role_of = role_of  # read by the gate at every action
        self.after_change = after_change
        self.audit = audit
        self.store = store or StateStore()
        self.transports = Transports(plant, self.store)
        self.devices = Devices(plant, self.store, self.transports)
        self.polling = Polling(plant, self.store, self.devices.adapters, self.transports.can_buses)
        self.extra_holders: dict[str, Any] = {}  # transmit lists, replays: under the dead-man rule like adapters
        self.deadman = DeadmanSupervisor(self._holder_items)
        self.loop_health = LoopHealth()
        self.hurry = loophealth.Hurry()  # a page connecting or a command coming ends the idle tick's wait
        # the one way in for commands; after each the tick hurries (a command may have taken control: supervised
        # from the next tick on, at 50 ms)
        self.gate = CommandGate(self, done=self.hurry.now)
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
        # a cancellation can be swallowed when pymodbus's wait_for gets its answer in the same loop iteration:
        # cancelled again until every task has really ended (bounded, app/aio.py)
        await end_tasks(self.tasks, "bus tasks", STOP_S)
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
