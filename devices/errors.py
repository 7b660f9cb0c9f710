"""The one root of everything a device, a command or a transport can refuse: :class:`DeviceError`.

A page and the CLI catch the project's refusals by type (``except DeviceError``) and let bugs
surface (STYLE.md item 19). Below it:

- :class:`CodecError`: a telegram, frame or value that cannot be encoded or decoded. Each device
  family keeps its own ``CodecError`` (``devices.scu.codec.CodecError``, ...) under this one, so an
  adapter catches exactly its family; it is a ``ValueError`` too (bad wire data is a bad value, never a
  crash, STYLE.md item 9). Bad wire data of the byte-stream codecs (SCU, MO 64) is a
  ``devices.framing.FrameError`` below it.
- :class:`CommandError`: a command that did not take effect (refused by the rules, by the device, or
  not possible now); the message says what to do. Each adapter's ``CommandError`` is one of these, and
  so is ``devices.commands.CommandError`` (an argument out of its declared range).
- :class:`ControlBusy`: another session controls the device.
- ``devices.transport.TransportError``: the line or bus did not carry the request (timeout, closed).
"""

from __future__ import annotations


class CommissionError(Exception):
    """The root of every error the project raises on purpose: a refusal, a bad file, a bad entry.

    Below it, each module's own errors keep the builtin they also are (a ``PlantError`` is a
    ``ValueError``, a ``FileRefused`` an ``OSError``), so a caller may catch either.
    """


class DeviceError(CommissionError):
    """Anything a device, a command or a transport refuses or cannot do."""


class CodecError(DeviceError, ValueError):
    """A telegram, frame or value of any device that cannot be encoded or decoded."""


class CommandError(DeviceError):
    """A command that did not take effect; the message says what to do."""


class ControlBusy(CommandError):
    """Another session controls the device."""
