"""Allowed ranges as an engineer reads them: no exponent notation, whole numbers with thousands
separators, a limit at the 32-bit range shown as no limit ("any")."""

from __future__ import annotations

from pages.widgets import INT32_LIMIT, number_text, range_text


def test_ordinary_ranges_read_as_before():
    assert range_text(1, 254) == "allowed 1 .. 254"
    assert range_text(0, 65535) == "allowed 0 .. 65535"
    assert range_text(6, 32, "mm/s") == "allowed 6 .. 32 mm/s"
    assert range_text(0.0, 100.0, "%") == "allowed 0 .. 100 %"


def test_large_numbers_with_separators_never_exponents():
    assert number_text(21474836) == "21,474,836"
    assert number_text(-214748364.8) == "-214,748,364.8"
    assert number_text(1e-7) == "0.0000001"
    assert "e+" not in range_text(0, 2_000_000_000, "counts")
    assert range_text(0, 2_000_000_000, "counts") == "allowed 0 .. 2,000,000,000 counts"


def test_32_bit_limits_are_no_limit():
    assert range_text(-(2 ** 31), INT32_LIMIT, "mm") == "allowed: any mm"
    assert range_text(-(2 ** 31), INT32_LIMIT) == "allowed: any value"
    assert range_text(0, 2 ** 32 - 1, "counts") == "allowed from 0 counts"
    assert range_text(-(2 ** 31), 21474836, "mm") == "allowed up to 21,474,836 mm"
    # A1 of lift-1 without a stroke: INT32 counts at 10 counts/mm
    low, high = round(-(2 ** 31) / 10, 1), round(INT32_LIMIT / 10, 1)
    assert range_text(low, high, "mm", any_beyond=min(abs(low), abs(high))) == "allowed: any mm"
