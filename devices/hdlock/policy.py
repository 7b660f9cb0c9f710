"""What this tool never sends to an HD-Lock, and what it confirms first (the HD-Lock document).

Pure data and checks over it, asked through :mod:`devices.sendpolicy` by every path that sends
bytes (transmit list, replay, Modbus poll window, restore, the lock's own commands). Its refusals, risks and
names are :class:`~devices.message.Message` texts: the bus tools and the lock's page word them in their language,
the audit keeps the English.
"""

from __future__ import annotations

from devices.hdlock import codec
from devices.hdlock.params import PARAMS
from devices.hdlock.tables import DOOR_IGNORED_WARNING
from devices.commands import Arg, Command, TxField, TxForm, param_write, read_parameters
from devices.hdlock.adapter import HdLockAdapter, HdLockBackup
from devices.hdlock.can_adapter import HdLockCanAdapter
from devices.message import Message, N_, joined, message_of
from devices.params import Accepted, ParamError
from devices.sendpolicy import Verdict, can_id_owner

TITLE = "HD-Lock"

# -- never sent ---------------------------------------------------------------------------------------------
FWU_REQUEST = Message(N_("a firmware-update request (section 6.6.7, not for users)"))
NEVER_CAN_IDS = {codec.CAN_FWU_ERASE: FWU_REQUEST, codec.CAN_FWU_WRITE: FWU_REQUEST}
NEVER_CAN_COMMANDS = {  # byte 4 of a Command (0x700), section 6.6.1.3
    codec.CanCommand.FIRMWARE_UPDATE_ENTER: Message(N_("cmdFirmwareUpdateEnter is a firmware-update command (section 6.6.1.3)")),
    codec.CanCommand.BOOTLOADER_UPDATE_ENTER: Message(N_("cmdBootloaderUpdateEnter is a firmware-update command (boot loader, "
                                                         "section 6.6.1.3)")),
    codec.CanCommand.UPDATE_LEAVE: Message(N_("cmdUpdateLeave is a firmware-update command (section 6.6.1.3)")),
}
NEVER_REGISTERS = {  # holding registers, whatever the access class says
    0: Message(N_("SettingsRevision (holding 0): a decrement restores the factory settings, an increment saves (section 3.2)")),
    codec.REG_FW_UPDATE: Message(N_("FwUpdateCommandRegister (holding 32770) restarts the lock for a firmware update (section 3.2)")),
    codec.REG_COMMAND: Message(N_("the system-command register (holding 2003): system commands go through the lock's page")),
}

# -- confirmed first ------------------------------------------------------------------------------------------
BROADCAST_RISK = Message(N_("Sent to broadcast: every HD-Lock on this bus takes it."))
BITRATE_RISK = Message(N_("cmdSetCANbaudrate: the lock changes its CAN bit rate and drops off this bus until the bus runs "
                          "at the new rate (section 6.6.1.2)."))
DEVICE_ID_RISK = Message(N_("Set Device Address: the lock answers only under its new device ID (section 6.6.2); each CAN "
                            "ID may belong to one participant only (section 6.2 b)."))
RESERVED_STD_FIRST = 0x7F0  # CAN 2.0A: identifiers 0x7F0-0x7FF (seven recessive MSBs) are not allowed
SOURCE_RISK = DOOR_IGNORED_WARNING  # cmdSetLockRequestSource 0x80-0x87, holding 4 and 1002


def register_verdict(address: int, value: int) -> Verdict:
    """A raw write of ``value`` (a 16-bit word, two's complement for signed registers) to holding ``address``
    (Modbus poll window, transmit list, replay, the CAN command that sets holding 4).

    The word is taken as the lock stores it (:func:`codec.stored_value`) and turned into the declared write of its
    parameter: the parameter model checks it (access, range, value table) and :func:`write_verdict` judges it, as
    it judges the write of a page, the API or a restore.
    """
    if address in NEVER_REGISTERS:
        return _never_written(address)
    param = PARAMS.get("holding", address)
    if param is None:
        covering = next((p for p in PARAMS.space("holding") if address in p.addresses), None)
        if covering is None:
            return Verdict(refused=Message(N_("holding {address} is not in the register map of the HD-Lock: not written"),
                                           address=address), name=_holding(address))
        param = covering
    name = _named(param, address)
    if param.never_write:
        return Verdict(refused=Message(N_("{name} is never written by this tool"), name=name), name=name)
    if not param.writable:
        return Verdict(refused=Message(N_("{name} is {access}: not writable"), name=name, access=param.access.value),
                       name=name)
    raw = value & 0xFFFF
    stored = codec.stored_value(address, raw)

    def kept(text: str) -> str:  # a word the lock stores as its low byte says so
        return text if stored == raw else Message(N_("{text} (sent as 0x{raw:04X}: the lock keeps the low byte, "
                                                     "section 6.6.1.1)"), text=text, raw=raw)
    try:
        accepted = param.accept(param.decode(stored))
    except ParamError as exc:
        return Verdict(refused=Message(N_("{error}: not written"), error=kept(message_of(exc))), name=name)
    verdict = write_verdict(accepted)
    return Verdict(verdict.refused, verdict.confirm, kept(verdict.name), verdict.kind)


def write_verdict(accepted: Accepted) -> Verdict:
    """The one rule for a write of a value the parameter model accepted (every path: page, API, restore, and the raw
    writes of :func:`register_verdict`): never to the registers of :data:`NEVER_REGISTERS`, and confirmed first
    where the parameter asks."""
    param = accepted.param
    if param.address in NEVER_REGISTERS:
        return _never_written(param.address)
    risk = accepted.risk
    return Verdict(confirm=(risk,) if risk else (), kind="write",
                   name=Message("{name} = {value}", name=_named(param, param.address), value=accepted.text))


def _never_written(address: int) -> Verdict:
    return Verdict(refused=Message(N_("{why}: never written"), why=NEVER_REGISTERS[address]), name=_holding(address))


def _holding(address: int) -> Message:
    return Message(N_("holding {address}"), address=address)


def _named(param, address: int) -> Message:
    return Message(N_("{name} (holding {address})"), name=param.label or param.name, address=address)


def check_modbus(function: int, address: int, values: list[int], device) -> Verdict:
    """A Modbus write to a lock: registers one by one (section 5.3: 06; 16 only as several 06)."""
    from devices.sendpolicy import combine

    if function in (5, 15):
        return Verdict(refused=Message(N_("the HD-Lock has no coils (section 5: holding and input registers only)")),
                       name=Message(N_("coil {address}"), address=address))
    if not values:
        return Verdict(refused=Message(N_("no value to write")))
    verdicts = [register_verdict(address + i, v) for i, v in enumerate(values)]
    merged = combine(verdicts)
    names = joined([v.name for v in verdicts if v.name])
    name = Message("{device} {names}", device=device.name, names=names) if device is not None and names else names
    return Verdict(merged.refused, merged.confirm, name or (device.name if device is not None else ""), merged.kind)


def check_can(can_id: int, extended: bool, data: bytes, devices, bus=()) -> Verdict | None:
    """A frame on the HD-Lock request block 0x700-0x707 (section 6.6), or one under a lock's device ID (what
    the lock sends: never sent by this tool); other IDs are not the lock's."""
    sender = next((d.name for d in devices if _device_id(d) == (extended, can_id)), None)
    if sender is not None:
        ident = codec.DeviceId(can_id, extended)
        return Verdict(refused=Message(N_("CAN ID {ident} is what HD-Lock {sender} sends under its device ID (its status, "
                                          "answers and firmware-update status, section 6.5): this tool never sends it, so "
                                          "nothing can pose as the lock"), ident=str(ident), sender=sender),
                       name=Message(N_("{sender} frame"), sender=sender), kind="system")
    if extended or can_id not in codec.CAN_REQUEST_IDS:
        return None
    name = codec.CAN_REQUEST_NAMES[can_id]
    if can_id in NEVER_CAN_IDS:
        return Verdict(refused=Message(N_("HD-Lock '{name}' (0x{id:03X}) is {what}: never sent"), name=name, id=can_id,
                                       what=NEVER_CAN_IDS[can_id]), name=f"HD-Lock {name}", kind="system")
    if len(data) < 4:
        return Verdict(refused=Message(N_("HD-Lock '{name}' (0x{id:03X}) needs the target address in bytes 0-3"), name=name,
                                       id=can_id), name=name)
    target = int.from_bytes(data[0:4], "little")
    broadcast = (BROADCAST_RISK,) if target == codec.CAN_BROADCAST else ()
    if can_id in (codec.CAN_READ_INPUT, codec.CAN_READ_HOLDING):
        return Verdict(name=f"HD-Lock {name}", kind="read")
    if can_id == codec.CAN_COMMAND:
        if len(data) < 5:
            return Verdict(refused=Message(N_("HD-Lock Command (0x700) without a command byte (section 6.6.1)")), name=name)
        command = data[4]
        if command in NEVER_CAN_COMMANDS:
            cmd_name = codec.CanCommand(command).name
            return Verdict(refused=Message(N_("HD-Lock Command {command} ({name}): {why}: never sent"), command=command,
                                           name=cmd_name, why=NEVER_CAN_COMMANDS[command]),
                           name=f"HD-Lock Command {command}", kind="system")
        value = int.from_bytes(data[6:8], "little") if len(data) >= 8 else None
        if command == codec.CanCommand.SET_LOCK_REQUEST_SOURCE:
            if value is None:
                return Verdict(refused=Message(N_("HD-Lock cmdSetLockRequestSource needs its value in bytes 6-7 (8 bytes, "
                                                  "section 6.6.1)")), name=f"HD-Lock {name}")
            # the command sets holding 4 (section 6.5.1): judged as that write, on the byte the lock keeps
            verdict = register_verdict(codec.REG_LOCK_REQUEST_SOURCE, value)
            source = "HD-Lock cmdSetLockRequestSource: {text}"
            return Verdict(verdict.refused and Message(source, text=verdict.refused), verdict.confirm + broadcast,
                           Message(source, text=verdict.name), "write")
        if command == codec.CanCommand.SET_CAN_BAUDRATE:
            return Verdict(confirm=(BITRATE_RISK,) + broadcast, name=f"HD-Lock cmdSetCANbaudrate = {value}", kind="system")
        return Verdict(refused=Message(N_("HD-Lock Command {command} is not in the document (section 6.6.1): not sent"),
                                       command=command), name=f"HD-Lock Command {command}")
    if can_id == codec.CAN_SET_DEVICE_ADDRESS:
        if len(data) < 8:
            return Verdict(refused=Message(N_("HD-Lock Set Device Address needs the new ID in bytes 4-7 (section 6.6.2)")),
                           name=name)
        try:
            new = codec.DeviceId.from_u32(int.from_bytes(data[4:8], "little"))
        except codec.CodecError as exc:
            return Verdict(refused=Message(N_("HD-Lock Set Device Address: {error} (section 6.6.2)"), error=message_of(exc)),
                           name=name, kind="system")
        owner = can_id_owner(bus, new.value, new.extended, exclude=_target_name(devices, target))
        if new.value == codec.CAN_BROADCAST:
            return Verdict(refused=Message(N_("device ID 0 is the broadcast address (section 6.4)")), name=name, kind="system")
        if not new.extended and new.value >= RESERVED_STD_FIRST:
            return Verdict(refused=Message(N_("CAN ID {ident}: standard IDs 0x7F0-0x7FF are not allowed (CAN 2.0A: the seven "
                                              "most significant identifier bits must not all be recessive)"), ident=str(new)),
                           name=name, kind="system")
        if owner:
            return Verdict(refused=Message(N_("CAN ID {ident} is used by {owner}: each CAN ID belongs to one participant "
                                              "only (section 6.2 b)"), ident=str(new), owner=owner), name=name, kind="system")
        return Verdict(confirm=(DEVICE_ID_RISK,) + broadcast, name=f"HD-Lock Set Device Address {new}", kind="system")
    # Write / Silent Write Holding-Register: bytes 4-5 address, 6-7 the value (SPEC-NOTES)
    if len(data) < 8:
        return Verdict(refused=Message(N_("HD-Lock '{name}' needs address and value (8 bytes, section 6.6.5)"), name=name),
                       name=name)
    address = int.from_bytes(data[4:6], "little")
    value = int.from_bytes(data[6:8], "little")
    verdict = register_verdict(address, value)
    return Verdict(verdict.refused and Message(N_("HD-Lock '{name}' of {refusal}"), name=name, refusal=verdict.refused),
                   verdict.confirm + broadcast, Message("HD-Lock {name} {what}", name=name, what=verdict.name), verdict.kind)


def _device_id(dev) -> tuple[bool, int] | None:
    try:
        ident = codec.DeviceId.make(int(dev.options["device_id"]), dev.options.get("extended"))
    except (KeyError, TypeError, ValueError, codec.CodecError):
        return None
    return ident.extended, ident.value


def _target_name(devices, target: int) -> str:
    """The plant's lock a request addresses (bytes 0-3), so its own ID does not count as taken."""
    try:
        ident = codec.DeviceId.from_u32(target)
    except codec.CodecError:  # no lock has that ID (more than 29 bits)
        return ""
    return next((d.name for d in devices if _device_id(d) == (ident.extended, ident.value)), "")


# -- declared commands (devices/commands.py): what the lock's page, the API and restore invoke by name ----------


def _source_risk(args) -> str:
    risks = list(register_verdict(codec.REG_LOCK_REQUEST_SOURCE, args["value"]).confirm)
    risks += [BROADCAST_RISK] if args.get("broadcast") else []
    return joined(risks, " ") if risks else ""


def _source_refusal(args, bus, device: str) -> str:
    """cmdSetLockRequestSource sets holding 4: the same rules as that write (value table, section 6.6.1.1)."""
    return register_verdict(codec.REG_LOCK_REQUEST_SOURCE, args["value"]).refused


def _bitrate_risk(args) -> str:
    return joined([BITRATE_RISK, BROADCAST_RISK], " ") if args.get("broadcast") else BITRATE_RISK


def _device_id_refusal(args, bus, device: str) -> str:
    """Set Device Address through the one policy: the frame the lock would get, judged like any other."""
    from devices.sendpolicy import check_can

    try:
        new = codec.DeviceId.make(int(args["new_value"]), args.get("extended") or None)
    except codec.CodecError as exc:
        return message_of(exc)
    this = next((d for d in bus if d.name == device), None)
    target = codec.DeviceId.make(int(this.options["device_id"]), this.options.get("extended")) if this else codec.BROADCAST_ID
    frame = codec.encode_set_device_address(target, new)
    return check_can(bus, frame.arbitration_id, frame.is_extended_id, frame.data).refused


RESTORE_RISK = Message(N_("All changes not yet saved are discarded and the saved values reloaded (section 4.2)."))
BROADCAST_ADDRESS_RISK = Message(N_("Set Modbus Address to broadcast address 255 (section 4.3): every lock on the line whose "
                                    "LockStatus meets (P1 & LockStatus) ^ P2 == 0 takes the new address at once, and none "
                                    "answers."))
ADDRESS_RISK = Message(N_("Set Modbus Address (section 4.3): if the condition holds the lock answers only at the new address "
                          "from now on; send Save-Settings afterwards to keep it, and change the address in the plant file."))


def unsaved_changes(state) -> list[str]:
    """The parameters written since the last Save-Settings, with the value each has now (what a save makes permanent)."""
    lines = []
    for key in sorted(state.unsaved, key=lambda k: (PARAMS.by_key[k].address if k in PARAMS.by_key else 1 << 20, k)):
        p = PARAMS.by_key.get(key)
        if p is None:
            lines.append(key)
            continue
        raw = state.raw(p)
        lines.append(f"{p.label or p.name} (holding {p.address}) = {'not read' if raw is None else p.display(raw)}")
    return lines


def _write_verdict(accepted: Accepted) -> tuple[str, str]:
    """A parameter write judged as the lock's Modbus or CAN write of that register (one policy for every path)."""
    verdict = write_verdict(accepted)
    return verdict.refused, verdict.question


def _save_audit(args, adapter) -> dict:
    changes = unsaved_changes(adapter.state)
    return {"parameter": "Save-Settings", "new": "; ".join(changes) or "no unsaved changes"}


def _address_audit(args, adapter) -> dict:
    return {"action": f"Set Modbus Address {args['new_address']}", "parameter": "DeviceAddress",
            "old": _fact(adapter.state, "Modbus address", ""), "new": args["new_address"]}


def _fact(state, point: str, default):
    """A published fact's value (devices/hdlock/adapter.py P_ADDRESS and the like), else ``default``."""
    value = state.points.get(point)
    return default if value is None or value.value is None else value.value


def _broadcast_audit(args, adapter) -> dict:
    known = args.get("known") or {}
    return {"action": f"Broadcast Set Modbus Address (255) P1 0x{args['mask']:04X} P2 0x{args['expected']:04X}, "
                      f"{len(known)} known locks", "parameter": "DeviceAddress", "new": args["new_address"]}


def _broadcast_refusal(args, bus, device: str) -> str:
    known = args.get("known") or {}
    target = args["new_address"]
    if target not in known:
        return ""
    return Message(N_("address {address} is {lock}: choose an address no lock uses"), address=target, lock=known[target])


_ADDRESS_ARGS = (Arg("new_address", codec.MODBUS_ADDRESS_MIN, codec.MODBUS_ADDRESS_MAX), Arg("mask", 0, 0xFFFF),
                 Arg("expected", 0, 0xFFFF))

# one function per adapter where both serve a command; a command one adapter lacks is not offered on its bus kind
COMMANDS = (
    Command("Save-Settings", "system", run=(HdLockAdapter.save_settings, HdLockCanAdapter.save_settings),
            audit=_save_audit),
    Command("Restore-Settings", "system", run=(HdLockAdapter.restore_settings, HdLockCanAdapter.restore_settings),
            risk=RESTORE_RISK),
    # CAN only (section 6.6)
    Command("cmdSetLockRequestSource", "write", run=HdLockCanAdapter.set_lock_request_source,
            args=(Arg("value", 0, 0x87),), flags=("broadcast",), risk=_source_risk, refuse_if=_source_refusal),
    Command("cmdSetCANbaudrate", "system", run=HdLockCanAdapter.set_can_bitrate, args=(Arg("code", 0, 255),),
            flags=("broadcast",), risk=_bitrate_risk),
    Command("Set Device Address", "system", run=HdLockCanAdapter.set_device_address,
            args=(Arg("new_value", 1, codec.EXT_ID_MAX),), flags=("extended",), risk=DEVICE_ID_RISK,
            refuse_if=_device_id_refusal),
    # Modbus only (section 4.3); broadcast first: "Set Modbus Address" answers to names it starts (an older caller's wording)
    Command("Broadcast Set Modbus Address (255)", "system", run=HdLockAdapter.broadcast_set_address, args=_ADDRESS_ARGS,
            extras=("known",), risk=BROADCAST_ADDRESS_RISK, refuse_if=_broadcast_refusal, audit=_broadcast_audit),
    Command("Set Modbus Address", "system", run=HdLockAdapter.set_address, prefix=True, args=_ADDRESS_ARGS,
            risk=ADDRESS_RISK, audit=_address_audit),
    param_write(PARAMS, (HdLockAdapter.write_accepted, HdLockCanAdapter.write_accepted), _write_verdict),
    read_parameters(HdLockBackup.backup_read),
)


# -- frames the transmit list builds by name (app/transmit.py) -----------------------------------------------

TX_OPERATIONS = {"holding": "read holding", "input": "read input", "write": "write holding"}


def _tx_register(device: str, options, values) -> tuple[int, bool, bytes, str]:
    """A Read Input/Holding-Register (6.6.3/6.6.4) or Write Holding-Register (6.6.5) request to the lock."""
    target = codec.DeviceId.make(int(options["device_id"]), options.get("extended"))
    operation, address, number = values["operation"], int(values["register"]), int(values["count"])
    if operation == "write":
        frame = codec.encode_write(target, address, number)
        param = PARAMS.get("holding", address)
        what = f"write holding {address}{' ' + (param.label or param.name) if param else ''}={number}"
    else:
        frame = codec.encode_read(target, operation, address, max(1, number))
        param = PARAMS.get(operation, address)
        what = f"read {operation} {address}+{max(1, number)}{' ' + (param.label or param.name) if param else ''}"
    return frame.arbitration_id, frame.is_extended_id, bytes(frame.data), f"HD-Lock {device} {what}"


def transmit_forms(options) -> list[TxForm]:
    return [TxForm("register", (TxField("operation", "choice", default="holding", choices=TX_OPERATIONS),
                                TxField("register", default=1000), TxField("count", default=1)), _tx_register)]
