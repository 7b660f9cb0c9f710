"""The adapter contract: what app/ may ask of a device adapter, one small Protocol per capability.

An adapter (``devices/<type>/adapter.py``) offers the capabilities its device has and nothing
else; app/ asks ``isinstance(adapter, BackupAdapter)`` instead of probing attribute names. The
Protocols are ``runtime_checkable``, so an adapter needs no base class: having the methods is
taking part. Things that are not device adapters but live under the dead-man rule (a cyclic
transmit list, a replay) are :class:`SessionHolder` the same way.

Optional declarations with a default stay plain attributes: ``backup_available`` (True),
``restore_refused`` and ``restore_wear`` ("").
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable


# -- polling -----------------------------------------------------------------------------------------
@runtime_checkable
class PollingAdapter(Protocol):
    """Reads its device on the worker's clock and publishes what it reads."""

    async def poll(self) -> None: ...


@runtime_checkable
class ShutdownAdapter(Protocol):
    """Has last words on its still open line when the worker stops; returns what it could not do."""

    async def shutdown(self) -> list[str]: ...


# -- backup and restore (app/backup.py) ----------------------------------------------------------------
class BackupDefaults:
    """What a backup adapter declares about itself unless it says otherwise (members of
    :class:`BackupAdapter`, read without probing)."""

    backup_available: bool = True  # this device has something to back up in its configuration
    restore_wear: str = ""  # what each restored write costs the device (an EEPROM's wear), in words
    restore_refused: str = ""  # why this device takes no restore (its backup is a record only)


@runtime_checkable
class BackupAdapter(Protocol):
    """Reads its device's settings for a backup file and names the device. Every one inherits
    :class:`BackupDefaults` (tests/devices/test_adapter_contract.py), so app/ reads ``backup_available``,
    ``restore_wear`` and ``restore_refused`` of a backup adapter without probing."""

    async def backup_read(self, progress: Callable[[float], Any] | None = None) -> list[dict]: ...

    def backup_identity(self) -> dict: ...

    async def save_step(self) -> str | None: ...


@runtime_checkable
class ParamWriter(Protocol):
    """Restores by writing parameters of its parameter model (validated, read back): an entry as it is
    (``write_param``), or what the parameter model accepted already (``write_accepted``, not checked again)."""

    async def write_param(self, param: Any, value: Any, *, confirmed: bool = False) -> int: ...

    async def write_accepted(self, accepted: Any, *, confirmed: bool = False) -> int: ...


@runtime_checkable
class EntryRestorer(Protocol):
    """Restores a backup entry of its own (a device without a parameter model)."""

    async def restore_entry(self, key: str, raw: Any) -> Any: ...


@runtime_checkable
class RestoreDescriber(Protocol):
    """Names a backed-up value in the words its page uses."""

    def restore_text(self, key: str, value: Any) -> str: ...


# -- control and the dead-man rule (app/gate.py, app/worker/deadman.py) -----------------------------------------
@runtime_checkable
class SessionHolder(Protocol):
    """Keeps something running for browser sessions and stops it when a session is lost."""

    def holders(self) -> set[str]: ...

    def session_lost(self, session: str, reason: str) -> None: ...


@runtime_checkable
class SessionStopper(Protocol):
    """Stops a disconnected session's motion but keeps its control until the page is gone for good."""

    def session_stop(self, session: str, reason: str) -> None: ...


@runtime_checkable
class SessionResumer(Protocol):
    """Gives a session back what it controlled when its page confirms it is alive again."""

    def session_back(self, session: str) -> None: ...


@runtime_checkable
class LeaseRenewer(Protocol):
    """Keeps its cyclic senders under a lease the dead-man supervisor renews (devices/lease.py)."""

    def renew_leases(self, alive: set[str]) -> None: ...


@runtime_checkable
class ControlAdapter(Protocol):
    """One browser session at a time controls the device."""

    async def take_control(self, session: str, user: str) -> None: ...

    def release_control(self, session: str, reason: str = "released") -> Any: ...


@runtime_checkable
class ControlChecker(Protocol):
    """Tells control of the device apart from running motion (the gate's check)."""

    def controls(self, session: str) -> bool: ...


# -- frame ownership (app/recording.py: the bus monitor) ------------------------------------------------
@runtime_checkable
class FrameOwner(Protocol):
    """Knows the CAN frames it sends and the requests addressed to it."""

    def owns_frame(self, arbitration_id: int, is_extended: bool, data: bytes) -> bool: ...


@runtime_checkable
class FrameDescriber(Protocol):
    """Decodes frames on its bus in its own words (``None``: not one of its frames)."""

    def describe_frame(self, arbitration_id: int, is_extended: bool, data: bytes) -> str | None: ...
