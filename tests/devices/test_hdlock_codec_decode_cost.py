"""Every status frame of a lock on the bus is decoded: the decoded frames are small slotted records,
the same values from bytes, bytearray and memoryview (section 6.5)."""

from __future__ import annotations

import pytest

from devices.hdlock import codec


@pytest.mark.parametrize("data, expected", [
    (bytes([0, 0, 0x00, 0x02, 0x05, 0x00, 0xC4, 0x01]), codec.StatusFrame(0x0200, 5, 7, 4)),  # (7 << 6) + 4
    (bytes([0, 0, 0x80, 0x00, 0x01, 0x00, 0x41, 0x01]), codec.StatusFrame(0x0080, 1, 3, 0x81)),  # ForceActive: (3 << 6) + 0x81
    (bytes([0, 0, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF]), codec.StatusFrame(0xFFFF, 0xFFFF, 0xFF7F >> 6, 0x80 | 0x3F)),  # ForceActive set: 0x80 taken off first
    (bytes([1, 0, 1, 0, 0, 0]), codec.FwuStatusFrame(True, False)),
    (bytes([0, 1, 0x34, 0x12, 0xCD, 0xAB]), codec.RegisterAnswer("input", 0x1234, 0xABCD)),
    (bytes([1, 1, 0xE8, 0x03, 0x02, 0x00, 0x99, 0x99]), codec.RegisterAnswer("holding", 1000, 2)),
])
def test_golden_frames_from_any_buffer(data, expected):
    for buffer in (data, bytearray(data), memoryview(data)):
        assert codec.decode_lock_frame(buffer) == expected


@pytest.mark.parametrize("data", [b"", b"\x00", bytes(7), bytes([1, 0, 0, 0, 0]), bytes([0, 1, 0, 0, 0]), bytes([2, 0, 0, 0, 0, 0])])
def test_short_or_unknown_frames_are_codec_errors(data):
    with pytest.raises(codec.CodecError):
        codec.decode_lock_frame(data)


def test_decoded_frames_are_slotted_and_frozen():
    frames = [codec.decode_lock_frame(d) for d in (bytes(8), bytes([1, 0, 0, 0, 1, 0]), bytes([0, 1, 0, 0, 0, 0]))]
    for frame in frames:
        assert not hasattr(frame, "__dict__")  # no dict per frame: a flood of status frames allocates less
        with pytest.raises((AttributeError, TypeError)):
            frame.space = "x"  # type: ignore[misc]


def test_a_status_is_worded_as_before_and_its_bit_names_once_per_status_word():
    data = bytes([0, 0, 0x03, 0x01, 0x05, 0x00, 0xC4, 0x01])  # LockRequest, ProximityInPlace, BoltLocked
    text = codec.describe_lock_frame(data)
    assert text.startswith("Status 0x0103 [LockRequest, ProximityInPlace, BoltLocked] motorPos 5 proximity 7 source 4")
    assert codec.describe_lock_frame(bytes(8)).startswith("Status 0x0000 [-] motorPos 0 proximity 0 source 0")
    hits = codec._status_names.cache_info().hits
    for low in range(16):  # discovery words every status-like frame of a flood of unknown IDs
        codec.discovered(0x1000000 + low, True, bytes([0, 0, 0x03, 0x01, low, 0, 0xC4, 0x01]))
    assert codec._status_names.cache_info().hits >= hits + 16
