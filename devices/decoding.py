"""What an adapter does with a telegram it cannot decode: count it and say why, never raise.

Bad wire data is a state, not a crash (ARCHITECTURE.md rule 9): the device's ``malformed`` counter
goes up and the reason becomes its last error, shown on its page, without an event in its log (a
flood of bad frames would otherwise push every other event out). Every family's ``CodecError``
derives from :class:`devices.errors.CodecError`, which is what :func:`decoded` catches.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, TypeVar

from devices.errors import CodecError

if TYPE_CHECKING:
    from devices.live import DeviceState

D = TypeVar("D")
T = TypeVar("T")


def malformed(state: DeviceState, reason: str | None = None) -> None:
    """Count one telegram that could not be decoded; ``reason`` (if any) becomes the last error."""
    state.counters.malformed += 1
    if reason is not None:
        state.error(reason, log=False)


def decoded(state: DeviceState, decode: Callable[[D], T], data: D, what: str | None,
            show_bytes: bool = False) -> T | None:
    """``decode(data)``, or None once a :class:`CodecError` is counted as malformed.

    :param what: names the telegram in the last error, ``"malformed <what>: <reason>"``; None only
        counts it.
    :param show_bytes: put the telegram's bytes in hex after ``what``.
    """
    try:
        return decode(data)
    except CodecError as exc:
        if what is None:
            malformed(state)
        elif show_bytes:
            malformed(state, f"malformed {what} {bytes(data).hex(' ')}: {exc}")  # type: ignore[arg-type]
        else:
            malformed(state, f"malformed {what}: {exc}")
        return None
