"""The CAN-M3IO's frames as DBC messages (sections 5.8, 7.2) for app/dbc.py."""

from __future__ import annotations

from typing import Any

from cantools.database.can import Message, Signal

from devices.dbcform import NODE, DbcError, bits, ident, sig
from devices.m3io import codec

# -- CAN-M3IO (sections 5.8, 7.2) -----------------------------------------------------------------------

def dbc_messages(device: str, options: dict[str, Any]) -> list[Message]:
    """DigOut, DigIn and the temperature frames at the IDs SW1 gives (section 5.8)."""
    try:
        ids = codec.derive_ids(options["sw1"])
        variant = codec.Variant(options.get("variant", "HM"))
    except (KeyError, TypeError, ValueError) as exc:
        raise DbcError(f"{device}: no SW1/variant to derive its IDs from ({exc})") from None
    node = ident(device)
    dig_out = bits({bit: name for name, bit in codec.OUTPUT_BITS[variant].items()}, 0) + [sig("REQ", 7, 1, comment="obsolete DigIn request")]
    dig_in = bits({i: f"E{i + 1}" for i in range(6)}, 0)

    def temp_word(word_number: int, first_bit: int) -> list[Signal]:
        name = f"T{word_number}"
        sensor = codec.temp_input(variant, word_number)
        return [  # the temperature word (section 7.2.2): 12-bit two's complement in 0.1 C, then sb, Last, Triac, Si
            sig(f"{name}_Temp", first_bit, 12, signed=True, scale=0.1, unit="degC",
                 comment=f"TEMP{sensor}; below 0 or above 200.0 C: out of measuring range"),
            sig(f"{name}_sb", first_bit + 12, 1),
            sig(f"{name}_Last", first_bit + 13, 1, comment="load present; Si and Triac mean nothing while 0"),
            sig(f"{name}_Triac", first_bit + 14, 1),
            sig(f"{name}_Si", first_bit + 15, 1, comment="0 = fuse blown"),
        ]

    temp14 = [s for n in range(1, 5) for s in temp_word(n, 16 * (n - 1))]
    temp56 = [s for n in (5, 6) for s in temp_word(n, 16 * (n - 5))]
    if ids.addressed:  # 7.2.4: Sync [area, index, payload], MData [area, index, 6 bytes]
        areas = {int(k): v for k, v in codec.SYNC_AREAS.items()}
        record = [sig("Area", 0, 8, choices=areas), sig("Index", 8, 8), sig("Payload", 16, 48)]
        sync = [sig(s.name, s.start, s.length, choices=areas if s.name == "Area" else None) for s in record]
        addressed = [
            Message(ids.sync, ident(f"{device}_Sync"), 8, sync, senders=[NODE], comment="addressed data request (7.2.4)"),
            Message(ids.mdata, ident(f"{device}_MData"), 8, record, senders=[node],
                    comment="addressed data answer, 0xFF-padded (7.2.4)"),
        ]
    else:  # 7.2.4: the cfg byte, P2 in bit 7 (not stored in the module)
        addressed = [Message(ids.sync, ident(f"{device}_Sync"), 1, [sig("P2", 7, 1, comment="three-phase output on two phases (HMR)")],
                             senders=[NODE], comment="Sync cfg (7.2.4)")]
    temperatures = [] if variant == codec.Variant.KM else [  # a KM has no power part, no Pt100 (section 4.1)
        Message(ids.temp14, ident(f"{device}_Temp1_4"), 8, temp14, senders=[node], cycle_time=int(codec.TEMP_PERIOD_S * 1000)),
        Message(ids.temp56, ident(f"{device}_Temp5_6"), 4, temp56, senders=[node], cycle_time=int(codec.TEMP_PERIOD_S * 1000)),
    ]
    return [
        Message(ids.dig_out, ident(f"{device}_DigOut"), 1, dig_out, senders=[NODE], cycle_time=int(codec.DIGOUT_PERIOD_S * 1000),
                comment=f"{variant.value} outputs; keep-alive within {codec.WATCHDOG_S:g} s"),
        Message(ids.dig_in, ident(f"{device}_DigIn"), 1, dig_in, senders=[node]),
        *temperatures,
        *addressed,
    ]


