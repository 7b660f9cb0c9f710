"""Every codec decode function rejects any input only with its named error (STYLE.md 9).

The targets and their allowed errors live in bench/fuzz_codecs.py, which runs 100,000 inputs
each; here each runs a modest number so the suite stays quick.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from devices.hdlock import codec as hdlock

_spec = importlib.util.spec_from_file_location("fuzz_codecs", Path(__file__).resolve().parents[2] / "bench" / "fuzz_codecs.py")
fuzz = importlib.util.module_from_spec(_spec)
sys.modules["fuzz_codecs"] = fuzz  # dataclasses look their module up by name
_spec.loader.exec_module(fuzz)

EXAMPLES = 300


@pytest.mark.parametrize("target", fuzz.TARGETS, ids=[t.name for t in fuzz.TARGETS])
def test_decode_raises_only_its_named_error(target):
    seen, sample = fuzz.uncaught(target, EXAMPLES)
    assert not seen, {key: sample[key] for key in seen}


@pytest.mark.parametrize("length", [9, 12, 64])
def test_hdlock_request_longer_than_a_can_frame_is_a_codec_error(length):
    frame = hdlock.CanFrame(0x700, bytes(length))
    with pytest.raises(hdlock.CodecError, match="8"):
        hdlock.decode_request(frame)
    assert "malformed" in hdlock.describe_request(frame)


def test_hdlock_set_address_request_with_an_impossible_new_id_is_described_not_raised():
    frame = hdlock.CanFrame(0x701, bytes.fromhex("ef4aa582 e3ce 1520"))  # new ID 0x2015CEE3: over 29 bits
    assert "malformed" in hdlock.describe_request(frame)
