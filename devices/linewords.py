"""How the bus monitor words the telegrams of a line that is no shared field bus (an RS232 or LogiTed line), and
what it filters them on: the contract between a device package and the monitor.

A device type whose own protocol runs on such a line may put a module ``linewords.py`` beside its adapter with

- ``decoder(devices, adapters, bus_type, bus_options)``: a :class:`LineDecoder` for one line (``devices``: the
  plant's device configurations on it, ``adapters``: name -> adapter);
- ``FILTERS``: the :class:`LineFilter` the monitor offers for that line.

The monitor (app/recording/lines.py, pages/monitor.py) finds it through the registry, never by the type's name.
Pure: no I/O.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

from devices.message import N_, Message

MAX_CACHE = 20_000  # texts kept per line decoder


@dataclass(frozen=True, slots=True)
class LineText:
    """One telegram (or request and answer) in words.

    :param request: the request as the device page names it (or the line's own words when it cannot be decoded)
    :param decoded: the answer in words (a value with its name and unit, or the refusal and what it means)
    :param tags: what the monitor's filters match (:attr:`LineFilter.tag`)
    """

    request: str
    decoded: str
    tags: frozenset[str] = frozenset()


def _same(text: str) -> str:
    return text


@dataclass(frozen=True)
class LineFilter:
    """One filter of a line's monitor: a choice (``choices``: tag -> words) or a typed entry (``parse``: the text ->
    the tag it matches, raising ValueError with what is allowed)."""

    key: str
    label: str
    choices: dict[str, str] = field(default_factory=dict)
    placeholder: str = ""
    hint: str = ""
    parse: Callable[[str], str] = _same


class LineDecoder(Protocol):
    """Words a line's transactions (:class:`app.line_base.Transaction`: ``request`` in the line's own words,
    ``request_hex``, ``response_hex``, ``error``)."""

    def refresh(self) -> None: ...

    def text(self, t: Any) -> LineText: ...


def cached(cache: dict, key: tuple, make: Callable[[], LineText]) -> LineText:
    """``make()`` once per telegram (``key``), bounded; a decoding bug is shown as such, never raised."""
    text = cache.get(key)
    if text is None:
        if len(cache) >= MAX_CACHE:
            cache.clear()
        try:
            text = make()
        except Exception as exc:  # noqa: BLE001 - a codec bug must not take the monitor down
            text = LineText(str(key[0]), Message(N_("cannot decode: {error}"), error=str(exc)))
        cache[key] = text
    return text


def from_hex(text: str) -> bytes:
    try:
        return bytes.fromhex(text or "")
    except ValueError:
        return b""
