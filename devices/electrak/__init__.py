"""Thomson Electrak HD linear actuators with the SY2 CAN option (a network of 1..n actuators)."""

from typing import Any

from devices.electrak import codec
from devices.electrak.params import PARAMS
from devices.message import Message, N_
from devices.registry import CanIdUse, DeviceType, OpenRead, TileAlarm, TileBar, TileLine, TileSpec, When


def _check_config(options: dict[str, Any], bus_type: str) -> list[tuple[str, str]]:
    errors = []
    actuators = options.get("actuators")
    if not isinstance(actuators, list) or not actuators:
        return [("actuators", Message(N_("actuators = {example} is required, one entry per networked actuator"),
                                      example='[{ model = "HD24", gearing = "B026", stroke_mm = 300 }, ...]'))]
    for n, a in enumerate(actuators, 1):
        if not isinstance(a, dict):
            errors.append(("actuators", Message(N_("actuator {n}: expected a table with model, gearing, stroke_mm"), n=n)))
            continue
        if a.get("model") not in codec.CURRENT_LIMIT_A:
            errors.append(("actuators", Message(N_("actuator {n}: model {model!r} is not one of {known}"), n=n, model=a.get("model"),
                                                known=", ".join(codec.CURRENT_LIMIT_A))))
        if a.get("gearing") not in codec.SPEED_RANGE_MM_S:
            errors.append(("actuators", Message(N_("actuator {n}: gearing {gearing!r} is not one of {known}"), n=n,
                                                gearing=a.get("gearing"), known=", ".join(codec.SPEED_RANGE_MM_S))))
        stroke = a.get("stroke_mm")
        if not isinstance(stroke, int | float) or isinstance(stroke, bool) or not 0 < stroke <= 6553.5:
            errors.append(("actuators", Message(N_("actuator {n}: stroke_mm must be the ordered stroke in mm (0 < stroke <= "
                                                   "6553.5)"), n=n)))
        for key in sorted(set(a) - {"model", "gearing", "stroke_mm"}):
            errors.append(("actuators", Message(N_("actuator {n}: unknown key '{key}'"), n=n, key=key)))
    if not errors:
        try:  # one control telegram drives every actuator at one speed
            codec.Limits.of([codec.Actuator(a["model"], a["gearing"], float(a["stroke_mm"])) for a in actuators])
        except codec.CodecError as exc:
            errors.append(("actuators", str(exc)))
    for key in sorted(set(options) - {"actuators"}):
        errors.append((key, Message(N_("unknown key '{key}' for an Electrak network; known: actuators"), key=key)))
    return errors


# document, "Das Netzwerk im Überblick": fixed standard IDs of every SY2 network, whatever its configuration
CAN_FIXED_IDS = (
    CanIdUse.one(codec.CONTROL_ID, "Electrak control telegram", "master", shared=True),
    CanIdUse.one(codec.STATUS_ID, "Electrak status telegram (every actuator, every 100 ms)", "device", shared=True),
    CanIdUse.one(codec.SERVICE_REQUEST_ID, "Electrak service request", "master", shared=True),
    CanIdUse.one(codec.SERVICE_RESPONSE_ID, "Electrak service answer", "device", shared=True),
    CanIdUse(codec.INTERNAL_IDS.start, codec.INTERNAL_IDS.stop - 1, "Electrak internal traffic between the actuators (0x600-0x6FF)", "device", shared=True),
)


_IDLE = When("Controlled by", (None,))  # nobody sends control telegrams
TILE = TileSpec(
    lines=(
        TileLine(cases=(
            (When("Extending", (True,)), "moving: extending", ""),
            (When("Retracting", (True,)), "moving: retracting", ""),
            (_IDLE, "idle (no controller)", ""),
            (When("Controlled by", (None,), negate=True), "standing", ""),
        ), missing="waiting for status telegrams"),
        TileLine("Devices heard", "actuators heard: {value}", missing="actuators heard: 0"),
        TileLine("Devices configured", "actuators configured: {value}"),
    ),
    alarms=tuple(
        # "Message timeout" is the normal state while no control telegrams are sent (document, Fehler-Flags)
        TileAlarm(When(name, (True,)), name, unless=_IDLE if bit == 5 else None)
        for bit, (name, *_) in codec.ERROR_FLAGS.items()
    ),
    bar=TileBar("Position", "{value:.1f} of {full:g} mm", full_scale_point="Stroke"),
    icon="height",
)


DEVICE_TYPE = DeviceType(
    worded_names=True,  # its parameter names are the tool's words, worded by the catalogs (docs/i18n.md)
    name="electrak",
    title="Electrak HD network",
    manufacturer="Thomson",
    bus_types=("can",),
    params=PARAMS,
    adapters={"can": "devices.electrak.adapter:ElectrakAdapter"},
    sims={"can": "devices.electrak.sim:ElectrakSim"},
    check_config=_check_config,
    bus_identity=lambda options, bus_type: "the bus's Electrak network (its IDs 0x06/0x07 are fixed: one network per bus)",  # one network per bus: the IDs 0x06/0x07 are fixed
    can_codec="devices.electrak.codec",
    can_fixed_ids=CAN_FIXED_IDS,
    tile=TILE,
    # the service parameters' entries start at the actuators' values: read once when a page opens on a network
    # never read (a read changes nothing)
    open_reads=(OpenRead("read service parameters"),),
)
