"""The transports: every bus of the plant opened once, owned here and lent to the adapters.

ARCHITECTURE rule 2: one owner per bus. A ``can`` bus is a python-can bus (:class:`~app.can_bus.CanBus`);
every other bus type is a line: Modbus RTU (pymodbus), ``serial`` (pyserial) and the two LogiTed
forms. Each registers its live record in the store, where pages read it.
"""

from __future__ import annotations

from app.can_bus import CanBus, CanBusState
from app.logited import LogitedRs485, LogitedTcp
from app.modbus_line import ModbusLine
from app.plant import Plant
from app.serial_line import SerialLine
from app.state import BusState, StateStore

Line = ModbusLine | SerialLine | LogitedTcp | LogitedRs485
LINE_CLASSES = {"serial": SerialLine, "logited-tcp": LogitedTcp, "logited-rs485": LogitedRs485}  # else Modbus RTU


class Transports:
    """The plant's CAN buses and lines, by bus name."""

    def __init__(self, plant: Plant, store: StateStore):
        self.can_buses: dict[str, CanBus] = {}
        self.lines: dict[str, Line] = {}
        for bus in plant.buses.values():
            if bus.type == "can":
                can_state = CanBusState(bus.name, bus.type, f"{bus.options['interface']} {bus.options['channel']}")
                store.buses[bus.name] = can_state
                self.can_buses[bus.name] = CanBus(bus.name, bus.options, can_state)
            else:
                bus_state = BusState(bus.name, bus.type, bus.endpoint)
                store.buses[bus.name] = bus_state
                self.lines[bus.name] = LINE_CLASSES.get(bus.type, ModbusLine)(bus.name, bus.options, bus_state)

    def of(self, bus: str) -> CanBus | Line | None:
        """The transport of the bus named ``bus``."""
        return self.lines.get(bus) or self.can_buses.get(bus)

    async def open(self) -> None:
        """Open the CAN buses (a line opens itself on its first request)."""
        for can_bus in self.can_buses.values():
            await can_bus.start()

    async def close(self) -> None:
        for line in self.lines.values():
            line.close()
        for can_bus in self.can_buses.values():
            await can_bus.stop()
