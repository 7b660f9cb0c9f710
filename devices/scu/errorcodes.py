"""The SCU's Error_Code bits (document 002, section 4.5, table 10; data IDs 0x00D1..0x00D5): what each bit means,
what sets it and what the unit does, and an error code in words. Pure: no I/O."""

from __future__ import annotations

from dataclasses import dataclass

from devices.message import N_


# -- error code bits (section 4.5, table 10; data IDs 0x00D1..0x00D5) ----------------------------------------
@dataclass(frozen=True)
class ErrorBit:
    """One bit of Error_Code: ``bit`` is the document's number 1..32, ``mask`` = 1 << (bit - 1)."""

    bit: int
    key: str
    cause: str
    condition: str  # marked for the catalog (the page words it); "" for none
    behaviour: str  # marked for the catalog

    @property
    def mask(self) -> int:
        return 1 << (self.bit - 1)  # "Bit n" is numbered from 1 (SPEC-NOTES)


_FAST = N_("motion is stopped (fast stop)")
_NOT_EXEC = N_("motion is not executed or is stopped")
_RESET = N_("motion is stopped; the controller resets")
_FAST_RESET = N_("motion is stopped (fast stop); the controller resets")
# the causes are the device words of app/device_words.py ("bit n: cause"); conditions and behaviours are marked here
_ERROR_TABLE = [
    (1, "rom_crc", "CRC error in the ROM test (faulty ROM)", "", _RESET),
    (2, "ram_test", "RAM test failed (faulty RAM)", "", _RESET),
    (3, "cpu_test", "CPU test failed (faulty CPU)", "", _RESET),
    (4, "stack_overflow", "stack overflow detected", "", _FAST_RESET),
    (5, "program_flow", "program flow error (watchdog reset)", "", _FAST_RESET),
    (6, "hand_switch_test", "hand switch test failed (short circuit in the hand switch)",
     N_("only if the hand switch is configured as safe"), _FAST),
    (7, "binary_input_test", "binary input test failed (short circuit between binary inputs)",
     N_("only if the binary inputs are configured as safe and no analogue input"), _FAST),
    (8, "relay_fet_test", "relay and FET test failed (faulty relay or FET)", N_("tested at the start of a motion"),
     N_("motion is not executed")),
    (10, "move_enable_comm", "communication with the MoveEnable controller failed",
     N_("no answer from the MoveEnable controller"), _FAST),
    (11, "move_enable_output", "MoveEnable output check failed (the MoveEnable controller's output is wrong)", "",
     _FAST),
    (12, "over_temperature", "over-temperature at the rectifier or FET", "", _FAST),
    (13, "battery_deep_discharge", "switched off because of deep discharge of the battery", "",
     N_("motion is stopped (fast stop); the control unit switches off")),
    (14, "total_current", "total current exceeded", N_("while moving"),
     N_("motion is stopped (fast stop); cleared with the next motion")),
    *[(14 + n, f"actuator_{n}", f"error of actuator {n}",
       N_("peak current, short-circuit current, sensor monitor, over-current (not at a limit position) or "
          "timeout (not at a limit position)"), N_("the actuator is stopped (fast stop); cleared with the next motion"))
      for n in range(1, 7)],
    (21, "position_difference", "position difference between the actuators too large (synchronised parallel run)",
     N_("only if synchronised parallel run is configured"), N_("motion is not started or is stopped (fast stop); "
                                                               "cleared with the next motion")),
    (22, "remote_timeout", "remote communication timeout", "", N_("depends on the Safety_ID (RO)")),
    (24, "locking_box_i2c", "locking box I2C communication error", N_("only if the locking box is configured as safe"),
     _NOT_EXEC),
    (25, "config_crc", "RAM copy of the EEPROM configuration data has a wrong CRC", "", _NOT_EXEC),
    (26, "user_data_crc", "RAM copy of the EEPROM user data has a wrong CRC", "", _NOT_EXEC),
    (27, "locking_box_data_crc", "EEPROM locking box data has a wrong CRC", "", _NOT_EXEC),
    (28, "dynamic_data_crc", "RAM copy of the EEPROM dynamic data has a wrong CRC", "", _NOT_EXEC),
    (29, "calibration_data_crc", "RAM copy of the EEPROM calibration data has a wrong CRC", "", _NOT_EXEC),
    # Bit 30 repeats bit 29's text word for word in table 10; kept as printed, under its own key.
    (30, "calibration_data_crc_2", "RAM copy of the EEPROM calibration data has a wrong CRC (as printed for bit 30)",
     "", _NOT_EXEC),
    (31, "io_test", "IO test", N_("run while no motion is active"), N_("motion is not executed")),
    (32, "motion_blocked", "motions are not executed", "", _NOT_EXEC),
]
ERROR_BITS: dict[int, ErrorBit] = {row[0]: ErrorBit(*row) for row in _ERROR_TABLE}  # bits 9 and 23 are unused
REMOTE_TIMEOUT_MASK = ERROR_BITS[22].mask
# Table 10: bits 14 to 21 are reset "mit nächster Bewegung". Bit 22 (remote timeout) names no clearing condition
# ("abhängig von der Safety_ID"): read as cleared by the next movement as well (SPEC-NOTES), so a master that
# reopens the session can still read why it was lost. A checkout does not fail on these before it moves.
CLEARED_BY_NEXT_MOVE = sum(ERROR_BITS[n].mask for n in range(14, 23))


def error_bits(code: int) -> list[ErrorBit]:
    """The documented bits set in an Error_Code value (undocumented bits: see :func:`unknown_error_bits`)."""
    return [b for n, b in sorted(ERROR_BITS.items()) if code & b.mask]


def unknown_error_bits(code: int) -> list[int]:
    """Document numbers (1..32) of set bits that table 10 leaves empty (9, 23)."""
    return [n for n in range(1, 33) if code >> (n - 1) & 1 and n not in ERROR_BITS]


NO_ERROR = "no error"  # Error_Code 0: no bit of table 10 set


def error_text(code: int) -> str:
    """An Error_Code value in words (section 4.5, table 10): ``"no error"`` for 0, else each set bit with its
    document number and cause (``"bit 14: total current exceeded"``), undocumented bits by number."""
    code = int(code)
    if code == 0:
        return NO_ERROR
    words = [f"bit {b.bit}: {b.cause}" for b in error_bits(code)]
    words += [f"bit {n}: not in table 10" for n in unknown_error_bits(code)]
    return "; ".join(words)


def error_hex(code: int) -> str:
    """The raw Error_Code as the vendor reads it: ``0x00002000``."""
    return f"0x{int(code):08X}"
