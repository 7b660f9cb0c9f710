"""What this tool confirms before it sends raw bytes to a CAN-M3IO module (the M3IO document).

DigOut with an SSR bit switches mains voltage onto a load (section 7.2.1): confirmed in the
transmit list, never replayed. What the module sends (DigIn, temperatures, MData) is never sent. Sync frames that write the configuration or customer data
(section 7.2.4, areas 1 and 4) are confirmed; a cfg byte with P2 set (the Sync cfg, or area 1 index 15) asks what the
declared write of P2 asks (devices/m3io/params.py). Asked through :mod:`devices.sendpolicy`. Its refusals, risks and
names are :class:`~devices.message.Message` texts: the bus tools word them in their language, the audit keeps the English.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from devices.commands import Arg, Command, CommandError, TxField, TxForm, param_write, read_parameters
from devices.m3io import codec
from devices.m3io.adapter import OUTPUT_NAMES, M3ioAdapter
from devices.m3io.params import P2_RISK, PARAMS
from devices.message import Message, N_
from devices.sendpolicy import Verdict

TITLE = "CAN-M3IO"
check_modbus = None  # hooks of devices/sendpolicy.py this type has none of

MODULE_SENDS = ("DigIn", "Temp1-4", "Temp5-6", "MData")  # sender "Modul" in the tables of section 5.8
MAINS_RISK = N_("{device}: DigOut switches {outputs} on: mains voltage on the load(s) (section 7.2.1).")
CONFIG_RISK = N_("{device}: Sync area 1 writes the module's configuration (section 7.2.4).")
CUSTOMER_RISK = N_("{device}: Sync area 4 writes the module's customer data (section 7.2.4).")


def check_can(can_id: int, extended: bool, data: bytes, devices, bus=()) -> Verdict | None:
    if extended:
        return None
    for dev in devices:
        try:
            ids = codec.derive_ids(int(dev.options["sw1"]))
            variant = codec.Variant(dev.options.get("variant", "HM"))
        except (KeyError, TypeError, ValueError, codec.CodecError):
            continue
        sent_by_module = {name: i for name, i in ids.by_name().items() if name in MODULE_SENDS}
        if can_id in sent_by_module.values():
            frame = next(name for name, i in sent_by_module.items() if i == can_id)
            return Verdict(refused=Message(N_("{device}: {frame} (0x{id:03X}) is what the module sends (sections 5.8, "
                                              "7.2): this tool never sends it, so nothing can pose as the module"),
                                           device=dev.name, frame=frame, id=can_id), name=f"{dev.name} {frame}",
                           kind="system")
        if can_id == ids.dig_out:
            if len(data) != 1:
                return Verdict(refused=Message(N_("{device}: DigOut has 1 byte (section 7.2.1), not {n}"), device=dev.name,
                                               n=len(data)), name=f"{dev.name} DigOut")
            outputs = codec.decode_dig_out(variant, data)
            mains = [n for n, on in outputs.items() if on and n != "LED"]
            on = " ".join(n for n, v in outputs.items() if v) or Message(N_("all off"))
            name = Message("{device} DigOut: {on}", device=dev.name, on=on)
            if mains:
                return Verdict(confirm=(Message(MAINS_RISK, device=dev.name, outputs=", ".join(mains)),), name=name,
                               kind="mains")
            return Verdict(name=name, kind="stop" if not any(outputs.values()) else "write")
        if can_id == ids.sync and data:
            if len(data) == 1 and data[0] & codec.P2:  # the Sync cfg byte with P2 (7.2.4)
                return Verdict(confirm=(P2_RISK,), name=f"{dev.name} Sync cfg P2", kind="write")
            if data[0] == codec.AREA_WRITE_CONFIG:
                p2 = (P2_RISK,) if len(data) > 2 and data[2] & codec.P2 else ()
                return Verdict(confirm=(Message(CONFIG_RISK, device=dev.name), *p2),
                               name=Message(N_("{device} write config"), device=dev.name), kind="write")
            if data[0] == codec.AREA_WRITE_CUSTOMER:
                return Verdict(confirm=(Message(CUSTOMER_RISK, device=dev.name),),
                               name=Message(N_("{device} write customer data"), device=dev.name), kind="write")
            return Verdict(name=f"{dev.name} Sync", kind="read")
    return None


THREE_PHASE_RISK = Message(N_("The three-phase output switches 400 V to the connected load. Make sure nobody works on it."))
MAINS_OUTPUT_RISK = Message(N_("This output switches mains voltage (230/400 V) to the connected load. Make sure nobody works "
                               "on it."))


@dataclass(frozen=True)
class BytesArg:
    """Bytes given as hex text (or bytes), at most ``size`` of them (a customer record holds 6, 7.2.4.2)."""

    name: str
    size: int = 6
    sent: bool = True

    def check(self, value: Any) -> bytes:
        if isinstance(value, bytes | bytearray):
            payload = bytes(value)
        elif isinstance(value, str):
            try:
                payload = bytes.fromhex(value)
            except ValueError:
                raise CommandError(Message(N_("{name}: {value} is not bytes as hex, e.g. 01 02 0A"), name=self.name,
                                           value=repr(value))) from None
        else:
            raise CommandError(Message(N_("{name}: {value} is not bytes as hex"), name=self.name, value=repr(value)))
        if len(payload) > self.size:
            raise CommandError(Message(N_("{name}: at most {size} bytes ({n} given)"), name=self.name, size=self.size,
                                       n=len(payload)))
        return payload


def _switch(output: str, on: bool) -> Command:
    """``"<output> on"`` / ``"<output> off"``: the output is part of the name, never the caller's to choose.
    On: an SSR switches mains (confirmed, engineers, audited first); the LED is a write. Off: a stop."""

    def fixed(values: dict[str, Any]) -> dict[str, Any]:
        return {**values, "name": output, "on": on}

    def audit(values: Mapping[str, Any], adapter: Any) -> dict[str, Any]:
        return {"new": ""}

    if not on:
        kind, risk = "stop", ""
    elif output == "LED":
        kind, risk = "write", ""
    else:
        kind, risk = "mains", THREE_PHASE_RISK if output == "SSR1-3" else MAINS_OUTPUT_RISK
    return Command(f"{output} {'on' if on else 'off'}", kind, run=M3ioAdapter.set_output, session=True, extras=("name", "on"),
                   prepare=fixed, risk=risk, audit=audit)


def _customer_audit(values: Mapping[str, Any], adapter: Any) -> dict[str, Any]:
    return {"parameter": f"Customer data {values['index']}", "new": values["payload"].hex(" ")}


COMMANDS = (
    Command("take control", "write", run=M3ioAdapter.take_control, session=True, extras=("user",)),
    Command("release control", "stop", run=M3ioAdapter.release_control, session=True, extras=("reason",)),
    *(_switch(output, on) for output in OUTPUT_NAMES for on in (True, False)),
    Command("all off", "stop", run=M3ioAdapter.all_off_pressed),
    # P2 on asks what the parameter model's P2 asks (a lost phase is no longer a load fault, section 4.3)
    Command("P2", "write", run=M3ioAdapter.set_two_phase, args=(Arg("on", 0, 1),), risk=lambda values: P2_RISK if values.get("on") else ""),
    Command("read identity", "read", run=M3ioAdapter.read_identity),
    Command("read customer data", "read", run=M3ioAdapter.read_customer, args=(Arg("index", 1, 15),)),
    Command("write customer data", "write", run=M3ioAdapter.write_customer, args=(Arg("index", 1, 15), BytesArg("payload")),
            audit=_customer_audit),
    Command("read load data", "read", run=M3ioAdapter.read_load_data),
    # the parameter model (devices/m3io/params.py): customer records and P2, checked and confirmed by the model
    param_write(PARAMS, M3ioAdapter.write_accepted),
    read_parameters(M3ioAdapter.backup_read),
)


# -- frames the transmit list builds by name (app/transmit.py) -----------------------------------------------


def _tx_dig_out(device: str, options, values) -> tuple[int, bool, bytes, str]:
    """A DigOut frame (section 7.2.1) for the module's SW1 and variant; the policy asks for mains bits."""
    ids = codec.derive_ids(int(options["sw1"]))
    variant = codec.Variant(options.get("variant", "HM"))
    outputs = {name: bool(values.get(name)) for name in codec.OUTPUT_BITS[variant]}
    on = " ".join(name for name, value in outputs.items() if value) or "all off"
    return ids.dig_out, False, codec.encode_dig_out(variant, outputs), f"M3IO {device} DigOut: {on}"


def transmit_forms(options) -> list[TxForm]:
    variant = codec.Variant(options.get("variant", "HM"))
    return [TxForm("DigOut", tuple(TxField(name, "flag", default=False) for name in codec.OUTPUT_BITS[variant]), _tx_dig_out)]
