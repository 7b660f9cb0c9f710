"""Plant files for the tests, built from parts instead of written out in each test: a bus with its
devices is one call, a plant is its buses. Every simulated endpoint is on a free port or a CAN channel
of its own unless the test names one. Standard library and the app only (the benchmarks use it too).

    plant(modbus_line(locks=(("door-1", 1), ("door-2", 2))), scu_line())   # a parsed Plant
    plant_text(can_bus(hdlock_can("gate-1", 11)), name="t")               # the file's text

A value of ``None`` leaves the key out of the file (the loader's default then applies). The parts of a
plant file (:func:`bus`, :func:`device`, :func:`plant_text`) are bench/liveapp.py's, which the benchmarks use."""

from __future__ import annotations

from itertools import count

from liveapp import ELECTRAK_ACTUATORS, bus, device, free_port, plant_text, table  # noqa: F401 - for the tests

from app.plant import Plant, parse_plant

SCU_ACTUATORS = ({"counts_per_mm": 10}, {"stroke_mm": 300})  # one actuator without a stroke, one with
_channels = count(1)


def plant(*buses: str, name: str | None = "t", head: str = "") -> Plant:
    return parse_plant(plant_text(*buses, name=name, head=head))


def channel(prefix: str) -> str:
    """A virtual CAN channel nobody else in this run uses."""
    return f"{prefix}-{free_port()}-{next(_channels)}"


# -- the usual buses ----------------------------------------------------------------------------


def modbus_line(locks=(("door-1", 1),), port: int | str | None = None, name: str = "line1", **options) -> str:
    """A simulated RTU line on TCP ``port`` (a free one by default; text: a serial device or URL as it is)
    with HD-Lock ``(name, address)`` pairs."""
    options = {"timeout": 0.2, "retries": 0, "poll_period": 0.1, "simulate": True, **options}
    return bus(name, "modbus-rtu", *(device(lock, "hdlock", name, address=address) for lock, address in locks),
               port=port if isinstance(port, str) else f"socket://127.0.0.1:{port or free_port()}", **options)


def can_bus(*devices: str, name: str = "can1", channel_name: str | None = None, **options) -> str:
    """A simulated python-can bus with ``devices``: ``virtual`` on a channel of its own unless ``options`` say
    otherwise (``interface="udp_multicast"``, ``port=...``)."""
    options = {"interface": "virtual", "simulate": True, **options}
    return bus(name, "can", *devices, channel=channel_name or channel(name), **options)


def hdlock_can(name: str, device_id: int, bus_name: str = "can1", **options) -> str:
    return device(name, "hdlock", bus_name, device_id=device_id, **options)


def m3io_can(name: str = "hm", bus_name: str = "can3", variant: str = "HM", sw1: int = 0x1A, **options) -> str:
    """A CAN-M3IO module (``options``: its others, such as ``master``)."""
    return device(name, "m3io", bus_name, variant=variant, sw1=sw1, **options)


def scu_line(name: str = "lift", bus_name: str = "rs1", port: int | None = None, actuators=SCU_ACTUATORS,
             **options) -> str:
    """A simulated SCU on a serial line through ``socket://`` (``actuators``: their settings, or how many)."""
    options = {"timeout": 0.3, "poll_period": 0.2, "simulate": True, **options}
    return bus(bus_name, "serial", device(name, "scu", bus_name,
                                                  actuators=actuators if isinstance(actuators, int) else list(actuators)),
               port=f"socket://127.0.0.1:{port or free_port()}", **options)


def mo64_tcp(name: str = "gate", bus_name: str = "gate-bus", port: int | None = None, travel_s: float | None = 0.6,
             device_options: dict | None = None, **options) -> str:
    """A simulated MO 64 on its own LogiTed TCP connection (``device_options``: the twin's, such as
    ``refuse_queries``)."""
    options = {"timeout": 0.5, "poll_period": 0.2, "simulate": True, **options}
    return bus(bus_name, "logited-tcp", device(name, "mo64", bus_name, travel_s=travel_s, **(device_options or {})),
               host="127.0.0.1", port=port or free_port(), **options)


def mo64_rs485(*gates: str, bus_name: str = "gates-485", port: int | None = None, **options) -> str:
    """Simulated MO 64 units sharing one LogiTed RS485 line (``gates`` from :func:`device`)."""
    options = {"shared": True, "next_master": 1, "poll_period": 0.3, "simulate": True, **options}
    return bus(bus_name, "logited-rs485", *gates, port=f"socket://127.0.0.1:{port or free_port()}", **options)


def electrak_bus(name: str = "lift", bus_name: str = "can2", channel_name: str | None = None,
                 actuators=ELECTRAK_ACTUATORS, **options) -> str:
    """A simulated Electrak HD network (two HD24 actuators by default) on a CAN bus of its own."""
    options = {"bitrate": 500000, **options}
    return can_bus(device(name, "electrak", bus_name, actuators=list(actuators)), name=bus_name,
                   channel_name=channel_name, **options)


def modbus_plant(port: int | None = None, locks: tuple[tuple[str, int], ...] = (("door-1", 1),), **options) -> Plant:
    """A plant with one simulated RTU line on a free port and the given (name, address) locks."""
    return plant(modbus_line(locks, port, **options), name=None)


def motion_plant_text(name: str = "motion", scu: dict | None = None, mo64: dict | None = None) -> str:
    """The three motion devices: an Electrak network ``lift``, an SCU ``scu`` and an MO 64 ``gate``
    (``scu`` and ``mo64``: options of :func:`scu_line` and :func:`mo64_tcp`)."""
    return plant_text(electrak_bus(channel_name=channel(name)), scu_line("scu", **(scu or {})), mo64_tcp(**(mo64 or {})),
                      name=name)


def heater_and_lock(channel_name: str) -> str:
    """An M3IO HM heater (SW1 0x1A) and an HD-Lock with extended device ID 335 on one virtual CAN bus,
    without twins: for the tests that watch what reaches the bus."""
    return plant_text(can_bus(device("heater", "m3io", "can1", variant="HM", sw1=0x1A),
                              hdlock_can("lock", 335, extended=True),
                              channel_name=channel_name, bitrate=500000, poll_period=2.0, simulate=None), name=None)


__all__ = ["ELECTRAK_ACTUATORS", "SCU_ACTUATORS", "bus", "can_bus", "channel", "device", "electrak_bus", "free_port",
           "hdlock_can", "heater_and_lock", "m3io_can", "modbus_line", "modbus_plant", "mo64_rs485", "mo64_tcp", "motion_plant_text",
           "plant", "plant_text", "scu_line", "table"]
