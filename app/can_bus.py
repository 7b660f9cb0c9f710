"""One CAN bus of the plant, shared by every device adapter on it.

:class:`CanBus` implements :class:`devices.transport.CanTransport` from three parts:

* the link (:class:`app.can_link.CanLink`): opening the python-can bus (any interface: socketcan,
  pcan, kvaser, slcan, gs_usb, virtual, udp_multicast, ...) and reopening it with backoff, receiving
  through python-can's ``Notifier`` and a listener that hands frames to the event loop in bounded
  batches, the dispatch by ID, discovery's share and the send path under one lock;
* its statistics (:class:`app.can_stats.CanStats`): what the bus monitor shows, in :class:`CanBusState`;
* its senders (:class:`app.can_cyclic.CyclicSenders`): keep-alives on python-can's cyclic send tasks,
  each on its own clock under a lease, and loop-timed transmit lists.

The names the rest of the program imports from here (the monitor's records and figures, the limits,
:func:`open_error`, :func:`interface_drops`, :func:`keepalives_running`) are those of the parts.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Any

import can

from app.can_cyclic import CyclicSenders, Make, PeriodicSender, keepalives_running
from app.can_link import (
    DRAIN_BUDGET_S,
    INBOX_FRAMES,
    NO_DISCOVERY_IDS,
    NO_DISCOVERY_S,
    READ_WAIT_S,
    READER_BACKOFF_S,
    UDP_RCVBUF,
    VIRTUAL_READ_WAIT_S,
    CanLink,
    Handler,
    interface_drops,
    open_error,
    read_wait_s,
    recognised_by_a_device_type,
)
from app.can_stats import (
    BURST_GAP_S,
    CYCLE_GAPS,
    CYCLE_STREAMS,
    LOAD_AVERAGE_S,
    LOAD_PEAK_S,
    LOAD_PEAK_WINDOW_S,
    LOAD_PERIOD_S,
    MAX_IDS,
    MONITOR_FRAMES,
    CanBusState,
    CanStats,
    CycleStream,
    FrameRecord,
    IdStats,
    Key,
    frame_bits,
)
from devices.lease import Lease

__all__ = [
    "BURST_GAP_S", "CYCLE_GAPS", "CYCLE_STREAMS", "DRAIN_BUDGET_S", "INBOX_FRAMES", "LOAD_AVERAGE_S", "LOAD_PEAK_S",
    "LOAD_PEAK_WINDOW_S", "LOAD_PERIOD_S", "MAX_IDS", "MONITOR_FRAMES", "NO_DISCOVERY_IDS", "NO_DISCOVERY_S", "READ_WAIT_S",
    "READER_BACKOFF_S", "UDP_RCVBUF", "VIRTUAL_READ_WAIT_S", "CanBus", "CanBusState", "CanStats", "CycleStream", "FrameRecord", "Handler", "IdStats",
    "Key", "PeriodicSender", "frame_bits", "interface_drops", "keepalives_running", "open_error", "read_wait_s",
    "recognised_by_a_device_type",
]


class CanBus:
    """A python-can bus owned by the worker; implements :class:`devices.transport.CanTransport`.

    :param options: plant-file options: ``interface``, ``channel``, ``bitrate`` and any
        further keys, which are passed to :class:`can.Bus` unchanged.
    """

    def __init__(self, name: str, options: dict[str, Any], state: CanBusState):
        self.name = name
        self.options = options
        self.state = state
        self.stats = CanStats(name, state, options.get("bitrate"))
        self.link = CanLink(name, options, self.stats, INBOX_FRAMES)
        self.senders = CyclicSenders(self.link)
        self.link.on_open = self.senders.restart
        self.link.before_close = self.senders.halt
        self.link.on_tick = self.senders.tick
        self.handlers = self.link.handlers
        self.listeners = self.link.listeners  # every received frame whose ID has no handler
        self._task: asyncio.Task | None = None

    # -- the link ----------------------------------------------------------------------
    @property
    def bus(self) -> can.BusABC | None:
        """The open python-can bus (None while closed)."""
        return self.link.bus

    @bus.setter
    def bus(self, bus: can.BusABC | None) -> None:
        self.link.bus = bus

    def open(self) -> can.BusABC:
        """A python-can bus from the options, not yet listened to (blocking); :meth:`start` takes one set as :attr:`bus`."""
        return self.link.open()

    @property
    def filter_own(self) -> bool:
        return self.link.filter_own

    @property
    def recognise(self) -> Callable[[int, bool, bytes], bool] | None:
        return self.link.recognise

    @recognise.setter
    def recognise(self, recognise: Callable[[int, bool, bytes], bool] | None) -> None:
        self.link.recognise = recognise

    @property
    def no_discovery_skipped(self) -> int:
        return self.link.no_discovery_skipped

    def subscribe(self, is_extended: bool, arbitration_id: int, handler: Handler) -> None:
        self.link.subscribe(is_extended, arbitration_id, handler)

    def unsubscribe(self, is_extended: bool, arbitration_id: int, handler: Handler) -> None:
        self.link.unsubscribe(is_extended, arbitration_id, handler)

    def dispatch(self, msg: can.Message) -> None:
        """Echo filter, statistics, then the handlers of the frame's ID (or the listeners)."""
        self.link.dispatch(msg)

    def send(self, arbitration_id: int, data: bytes, is_extended_id: bool = False) -> bool:
        """Send one frame; False (and counted) when the bus is not open or refuses it."""
        return self.link.send(arbitration_id, data, is_extended_id)

    # -- life cycle --------------------------------------------------------------------
    async def start(self) -> None:
        self.link.loop = asyncio.get_running_loop()
        self._task = asyncio.create_task(self.link.supervise(), name=f"can {self.name}")

    async def stop(self) -> None:
        self.senders.stop_all()
        task, self._task = self._task, None
        if task is not None:
            task.cancel()
            try:
                await task
            except asyncio.CancelledError:
                pass
        await asyncio.get_running_loop().run_in_executor(None, self.link.close)

    # -- the senders -------------------------------------------------------------------
    def start_cyclic(self, key: str, period_s: float, make: Make) -> None:
        """Send ``make()`` every ``period_s`` from the loop until :meth:`stop_cyclic` (``None``: skip this period)."""
        self.senders.start_cyclic(key, period_s, make)

    def start_periodic(
        self, key: str, period_s: float, arbitration_id: int, data: bytes, is_extended_id: bool = False, *,
        lease: Lease | None = None, stop_form: Callable[[bytes], bytes] | None = None,
        on_lapse: Callable[[float], None] | None = None,
    ) -> None:
        """Send ``data`` every ``period_s`` on a clock that does not depend on the event loop; while ``lease``
        is not valid only ``stop_form(data)`` leaves (:meth:`app.can_cyclic.CyclicSenders.start_periodic`)."""
        self.senders.start_periodic(key, period_s, arbitration_id, data, is_extended_id,
                                    lease=lease, stop_form=stop_form, on_lapse=on_lapse)

    def modify_periodic(self, key: str, data: bytes, *, send_now: bool = False) -> bool:
        """New contents from the next period on; ``send_now``: also once at once."""
        return self.senders.modify_periodic(key, data, send_now=send_now)

    def stop_cyclic(self, key: str) -> None:
        self.senders.stop(key)

    def cyclic_running(self, key: str) -> bool:
        return self.senders.running(key)
