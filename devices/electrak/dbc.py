"""The Electrak HD network's telegrams as DBC messages for app/dbc.py."""

from __future__ import annotations

from typing import Any

from cantools.database.can import Message

from devices.dbcform import NODE, bits, ident, sig
from devices.electrak import codec

# -- Electrak HD network (control 0x06, status 0x07, service 0x0A/0x0B) ----------------------------------

def dbc_messages(device: str, _options: dict[str, Any]) -> list[Message]:
    node = ident(device)
    words = [("Position", "mm"), ("Current", "A"), ("Speed", "mm/s")]
    control = [
        sig("TargetPosition", 0, 16, scale=0.1, unit="mm"),
        sig("CurrentLimit", 16, 16, scale=0.1, unit="A", comment="0 = calibrated default"),
        sig("TargetSpeed", 32, 16, scale=0.1, unit="mm/s"),
        sig("Enable", 56 + codec.ENABLE.bit_length() - 1, 1),
        sig("Override", 56 + codec.OVERRIDE.bit_length() - 1, 1, comment="override / reset"),
    ]
    status = [sig(name, 16 * i, 16, scale=0.1, unit=unit) for i, (name, unit) in enumerate(words)]
    # byte 6 motion flags, byte 7 error flags, by their named bits (cantools refuses overlapping signals)
    status += bits({bit: name for bit, (name, _) in codec.MOTION_FLAGS.items()}, 48)
    status += bits({bit: name for bit, (name, *_rest) in codec.ERROR_FLAGS.items()}, 56)
    service_types = {int(t): t.name for t in codec.ServiceType}
    service = [sig("Type", 0, 8, choices=service_types), sig("Specifier", 8, 8), sig("Length", 16, 8),
               sig("Payload", 32, 32)]
    return [
        Message(codec.CONTROL_ID, ident(f"{device}_Control"), 8, control, senders=[NODE],
                cycle_time=int(codec.CONTROL_PERIOD_S * 1000), comment="control telegram: every 100 ms while controlling"),
        Message(codec.STATUS_ID, ident(f"{device}_Status"), 8, status, senders=[node],
                cycle_time=int(codec.STATUS_PERIOD_S * 1000), comment="status of each actuator (cannot be told apart)"),
        Message(codec.SERVICE_REQUEST_ID, ident(f"{device}_ServiceRequest"), 8, service, senders=[NODE]),
        Message(codec.SERVICE_RESPONSE_ID, ident(f"{device}_ServiceResponse"), 8,
                [sig(s.name, s.start, s.length, choices=service_types if s.name == "Type" else None) for s in service],
                senders=[node]),
    ]


