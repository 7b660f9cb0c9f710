"""The one root of every device codec's errors.

Each device family keeps its own ``CodecError`` (``devices.scu.codec.CodecError``, ...), so an
adapter catches exactly its family; code that handles bad wire data of any device catches
:class:`CodecError` from here. It is a ``ValueError``: a telegram or value that cannot be
encoded or decoded is a bad value, never a crash (STYLE.md item 9). Bad wire data of the byte-stream
codecs (SCU, MO 64) is a ``devices.framing.FrameError`` below it, in each family under its own ``CodecError``.
"""

from __future__ import annotations


class CodecError(ValueError):
    """A telegram, frame or value of any device that cannot be encoded or decoded."""
