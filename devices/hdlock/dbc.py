"""The HD-Lock's CAN frames as DBC messages (section 6.5, 6.6) for app/dbc.py."""

from __future__ import annotations

from typing import Any

from cantools.database.can import Message, Signal

from devices.dbcform import NODE, DbcError, ident, sig
from devices.hdlock import codec

# -- HD-Lock (section 6.5) ------------------------------------------------------------------------------

HDLOCK_KIND_STATUS = 0x0000  # bytes 0-1 = 00 00: status (6.5.1)
HDLOCK_KIND_FWU = 0x0001  # 01 00: firmware-update status (6.5.2)
HDLOCK_KIND_INPUT = 0x0100  # 00 01: input-register answer (6.5.3)
HDLOCK_KIND_HOLDING = 0x0101  # 01 01: holding-register answer (6.5.4)


def dbc_messages(device: str, options: dict[str, Any]) -> list[Message]:
    """The frames a lock sends under its device ID, multiplexed by bytes 0-1 (read little-endian)."""
    try:
        lock_id = codec.DeviceId.make(options["device_id"], options.get("extended"))
    except (KeyError, TypeError, codec.CodecError) as exc:
        raise DbcError(f"{device}: no CAN device ID ({exc})") from None
    status_bits = {bit: name.replace(" (bit 4)", "_bit4") for bit, name in codec.LOCK_STATUS_NAMES.items()}
    kinds = {HDLOCK_KIND_STATUS: "Status", HDLOCK_KIND_FWU: "FwuStatus", HDLOCK_KIND_INPUT: "InputRegisterAnswer",
             HDLOCK_KIND_HOLDING: "HoldingRegisterAnswer"}
    signals = [sig("FrameKind", 0, 16, is_multiplexer=True, choices=kinds, comment="bytes 0-1 (section 6.5)")]
    status = [HDLOCK_KIND_STATUS]
    # bytes 2-7: Status word (= holding 1000), motorPos, (proximity << 6) + LockRequestSource (SPEC-NOTES)
    # the status word (= holding 1000) by its named bits: overlapping signals are refused by cantools' strict check
    signals += [sig(f"LockStatus_{name}", 16 + bit, 1, multiplexer_ids=status, multiplexer_signal="FrameKind")
                for bit, name in sorted(status_bits.items())]
    signals += [
        sig("MotorPos", 32, 16, multiplexer_ids=status, multiplexer_signal="FrameKind", unit="increments"),
        sig("LockRequestSource", 48, 6, multiplexer_ids=status, multiplexer_signal="FrameKind",
             comment="low 6 bits of LockRequestSource; with ForceActive set the source is 0x80 + these bits and "
                     "Proximity reads 2 too high (0x80 = 2 << 6, SPEC-NOTES)"),
        sig("Proximity", 54, 10, multiplexer_ids=status, multiplexer_signal="FrameKind"),
        sig("FwuFlashing", 16, 16, multiplexer_ids=[HDLOCK_KIND_FWU], multiplexer_signal="FrameKind"),
        sig("FwuApplication", 32, 16, multiplexer_ids=[HDLOCK_KIND_FWU], multiplexer_signal="FrameKind"),
    ]
    for kind, space in ((HDLOCK_KIND_INPUT, "Input"), (HDLOCK_KIND_HOLDING, "Holding")):  # one mux value per signal in DBC
        signals += [sig(f"{space}RegisterAddress", 16, 16, multiplexer_ids=[kind], multiplexer_signal="FrameKind"),
                    sig(f"{space}RegisterValue", 32, 16, multiplexer_ids=[kind], multiplexer_signal="FrameKind")]
    return [Message(lock_id.value, ident(f"{device}_HDLock"), 8, signals, is_extended_frame=lock_id.extended,
                    senders=[ident(device)], cycle_time=int(codec.STATUS_PERIOD_S * 1000),
                    comment=f"HD-Lock {device}, device ID {lock_id}: status every 1 s and register answers (section 6.5)")]



# -- the requests of section 6.6 (0x700-0x707): one block shared by every lock of a bus -----------------------


def _target() -> list[Signal]:
    return [sig("TargetDeviceId", 0, 31, comment="bytes 0-3: the lock's device ID, 0 = broadcast (section 6.4)"),
            sig("TargetExtended", 31, 1, comment="0x80000000: extended (29-bit) device ID (section 6.3)")]


def dbc_bus_messages(devices: list[Any]) -> list[Message]:
    """The request frames this tool (or a controller) sends to the locks of a bus (section 6.6)."""
    receivers = [ident(d.name) for d in devices]
    word = {"receivers": receivers}
    layouts = {
        codec.CAN_COMMAND: [sig("Command", 32, 16, choices={int(c): c.name for c in codec.CanCommand}, **word),
                            sig("Value", 48, 16, **word)],
        codec.CAN_SET_DEVICE_ADDRESS: [sig("NewDeviceId", 32, 31, **word), sig("NewExtended", 63, 1, **word)],
        codec.CAN_READ_INPUT: [sig("RegisterAddress", 32, 16, **word), sig("Count", 48, 16, **word)],
        codec.CAN_READ_HOLDING: [sig("RegisterAddress", 32, 16, **word), sig("Count", 48, 16, **word)],
        codec.CAN_WRITE_HOLDING: [sig("RegisterAddress", 32, 16, **word),
                                  sig("Value", 48, 16, comment="the value written (labelled Count in 6.6.5)", **word)],
        codec.CAN_SILENT_WRITE_HOLDING: [sig("RegisterAddress", 32, 16, **word), sig("Value", 48, 16, **word)],
    }
    messages = []
    for can_id, name in codec.CAN_REQUEST_NAMES.items():
        never = " Firmware update: never sent by this tool (section 6.6.7)." if can_id in (codec.CAN_FWU_ERASE, codec.CAN_FWU_WRITE) else ""
        messages.append(Message(can_id, ident("HDLock_" + name.replace(" ", "").replace("-", "")), 8,
                                [s for s in _target()] + layouts.get(can_id, []), senders=[NODE],
                                comment=f"HD-Lock request '{name}' (section 6.6).{never}"))
    return messages
