"""Ewellix (Schaeffler) SCU actuator control unit on RS232 (document 002): remote session,
data directory, functions, positions of up to six actuators."""

from typing import Any

from devices.message import Message, N_
from devices.registry import DeviceType, TileAlarm, TileBar, TileLine, TileSpec, When
from devices.scu import codec
from devices.scu.model import PARAMS

_ACTUATOR_KEYS = {"counts_per_mm", "stroke_mm", "in_counts", "out_counts"}
_KEYS = {"actuators", "safety_id", "functions", "speed_select", "serial"}


def _number(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def _check_config(options: dict[str, Any], bus_type: str) -> list[tuple[str, str]]:
    errors = []
    actuators = options.get("actuators", 1)
    if isinstance(actuators, bool) or not isinstance(actuators, int | list):
        errors.append(("actuators", Message(N_("actuators = 2 (a number 1..6) or a list of tables {example}"),
                                            example="[{ counts_per_mm = 12.5 }, { stroke_mm = 300 }, ...]")))
    elif isinstance(actuators, int):
        if not 1 <= actuators <= 6:
            errors.append(("actuators", Message(N_("actuators = {n}: an SCU drives 1 to 6 actuators (section 4.6)"), n=actuators)))
    elif not 1 <= len(actuators) <= 6:
        errors.append(("actuators", Message(N_("{n} actuator tables: an SCU drives 1 to 6 actuators (section 4.6)"),
                                            n=len(actuators))))
    else:
        for n, a in enumerate(actuators, 1):
            if not isinstance(a, dict):
                errors.append(("actuators", Message(N_("actuator {n}: expected a table ({empty} for counts only)"), n=n, empty="{}")))
                continue
            for key in sorted(set(a) - _ACTUATOR_KEYS):
                errors.append(("actuators", Message(N_("actuator {n}: unknown key '{key}'; known: {known}"), n=n, key=key,
                                                    known=", ".join(sorted(_ACTUATOR_KEYS)))))
            if "counts_per_mm" in a and "stroke_mm" in a:
                errors.append(("actuators", Message(N_("actuator {n}: give counts_per_mm or stroke_mm, not both"), n=n)))
            for key in ("counts_per_mm", "stroke_mm"):
                if key in a and (not _number(a[key]) or a[key] <= 0):
                    errors.append(("actuators", Message(N_("actuator {n}: {key} must be a number above 0"), n=n, key=key)))
            ends = [k for k in ("in_counts", "out_counts") if k in a]
            if ends and "stroke_mm" not in a:
                errors.append(("actuators", Message(N_("actuator {n}: in_counts/out_counts belong to stroke_mm"), n=n)))
            if len(ends) == 1:
                errors.append(("actuators", Message(N_("actuator {n}: give both in_counts and out_counts (or neither: then the "
                                                       "unit's virtual limits of UserPositionData are used)"), n=n)))
            for k in ends:
                if isinstance(a[k], bool) or not isinstance(a[k], int):
                    errors.append(("actuators", Message(N_("actuator {n}: {key} must be a whole number of counts"), n=n, key=k)))
            if len(ends) == 2 and a["in_counts"] == a["out_counts"]:
                errors.append(("actuators", Message(N_("actuator {n}: in_counts and out_counts must differ"), n=n)))
    n_act = actuators if isinstance(actuators, int) else len(actuators) if isinstance(actuators, list) else 6
    functions = options.get("functions")
    if functions is not None:
        if not isinstance(functions, dict) or not functions:
            errors.append(("functions", Message(N_("functions = {example}: the actuators each function drives"),
                                                example="{ F1 = [1], F2 = [2, 3] }")))
        else:
            for key, acts in functions.items():
                if not (isinstance(key, str) and key[:1] in "Ff" and key[1:].isdigit() and 1 <= int(key[1:]) <= 10):
                    errors.append(("functions", Message(N_("functions: '{key}' is not F1 .. F10"), key=key)))
                if not isinstance(acts, list) or not acts or any(
                        isinstance(a, bool) or not isinstance(a, int) or not 1 <= a <= n_act for a in acts):
                    errors.append(("functions", Message(N_("functions.{key}: a list of 1 to 6 actuator numbers 1..{n}"), key=key,
                                                        n=n_act)))
    if options.get("speed_select", "relative") not in ("relative", "absolute"):
        errors.append(("speed_select", Message(N_("speed_select = \"relative\" (%, 0..100, the standard) or \"absolute\" "
                                                  "(counts/s, 0..1000), as the unit is parametrised (table 7)"))))
    safety = options.get("safety_id", int(codec.DEFAULT_SAFETY_ID))
    if isinstance(safety, bool) or safety not in tuple(codec.SafetyId):
        errors.append(("safety_id", Message(N_("safety_id must be 0, 1 or 2 (RO, section 4.1; default 1)"))))
    serial = options.get("serial")
    if serial is not None and (isinstance(serial, bool) or not isinstance(serial, int | str) or serial == ""):
        errors.append(("serial", Message(N_("serial = \"...\" or a number: the unit's serial number from its type plate (no "
                                            "data ID carries it, section 4.3); it names the unit in backups, batches and "
                                            "replacements"))))
    for key in sorted(set(options) - _KEYS):
        errors.append((key, Message(N_("unknown key '{key}' for an SCU; known: {known}"), key=key, known=", ".join(sorted(_KEYS)))))
    return errors


TILE = TileSpec(
    lines=(
        TileLine("Session", "remote session: {text}", missing="remote session: closed"),
        TileLine("A1 position", "A1 {text}", missing="A1: no position yet"),
        TileLine("Battery Mains", "supply: {text}", missing=""),
    ),
    alarms=(
        TileAlarm(When("Emergency stop", (True,)), "EMERGENCY STOP (F20) {text}"),
        TileAlarm(When("Error code", (0, None), negate=True), "error: {text}"),
        TileAlarm(When("Session", ("lost",)), "{text}"),
    ),
    bar=TileBar("A1 position", "A1 {value} of {full} counts", full_scale_point="A1 out end"),
    icon="open_in_full",
)

DEVICE_TYPE = DeviceType(
    name="scu",
    title="Ewellix SCU",
    manufacturer="Ewellix",
    bus_types=("serial",),
    params=PARAMS,
    adapters={"serial": "devices.scu.adapter:ScuAdapter"},
    sims={"serial": "devices.scu.sim:ScuSim"},
    check_config=_check_config,
    bus_identity=lambda options, bus_type: "the point-to-point line (one SCU per RS232 line, section 3)",
    tile=TILE,
)
