"""Every device codec's errors derive from one root (``devices.errors.CodecError``)."""

from __future__ import annotations

import importlib

import pytest

from devices import errors

FAMILIES = ("electrak", "hdlock", "m3io", "mo64", "scu")


@pytest.mark.parametrize("family", FAMILIES)
def test_every_codec_error_has_the_one_root(family):
    codec = importlib.import_module(f"devices.{family}.codec")
    assert issubclass(codec.CodecError, errors.CodecError) and codec.CodecError is not errors.CodecError
    assert issubclass(errors.CodecError, ValueError)
    for name in dir(codec):
        obj = getattr(codec, name)
        if isinstance(obj, type) and issubclass(obj, Exception) and obj.__module__ == codec.__name__:
            assert issubclass(obj, codec.CodecError), name


def test_one_family_does_not_catch_another():
    from devices.mo64 import codec as mo64
    from devices.scu import codec as scu

    with pytest.raises(errors.CodecError):
        raise scu.ChecksumError(b"\x00\x00")
    assert not issubclass(scu.CodecError, mo64.CodecError) and not issubclass(mo64.CodecError, scu.CodecError)
