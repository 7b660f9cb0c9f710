"""Naming frames: the device codecs' ``describe_frame`` and the adapters' own describers."""

from __future__ import annotations

import importlib
from collections.abc import Iterable
from types import ModuleType
from typing import Any

from app.can_bus import FrameRecord
from app.i18n import N_
from app.message import Message, message_of
from app.recording.base import MAX_CACHE, UNKNOWN, Key
from app.recording.filters import Owner, device_of
from devices.adapter import FrameDescriber
from devices.registry import DEVICE_TYPES


# -- decoding -------------------------------------------------------------------------------------------


def can_codecs(prefer: Iterable[str] = ()) -> list[ModuleType]:
    """The codec modules of every device type that speaks CAN, those named in ``prefer`` first.

    Device types reuse small standard IDs (an Electrak's service response 0x0B is an
    HD-Lock's device ID 11), so the types present on a bus are asked before the others.
    """
    prefer = set(prefer)
    types = [dt for dt in DEVICE_TYPES.values() if dt.can_codec and "can" in dt.bus_types]
    types.sort(key=lambda dt: dt.name not in prefer)  # stable: registry order otherwise
    return [importlib.import_module(dt.can_codec) for dt in types]


class AdapterDescriber:
    """A device adapter whose frame IDs follow from its configuration (e.g. an M3IO's SW1),
    asked like a codec module."""

    def __init__(self, adapter: Any):
        self.adapter = adapter

    def __eq__(self, other: object) -> bool:
        return isinstance(other, AdapterDescriber) and other.adapter is self.adapter

    def __hash__(self) -> int:
        return id(self.adapter)

    def describe_frame(self, arbitration_id: int, is_extended: bool, data: bytes, known_ids: set[Key]) -> str | None:
        return self.adapter.describe_frame(arbitration_id, is_extended, data)


def describers(worker: Any, bus: str, types_on_bus: Iterable[str]) -> list[Any]:
    """What decodes frames on a bus: adapters that know their own IDs, then the device codecs."""
    adapters = [
        AdapterDescriber(worker.adapters[d.name])
        for d in worker.plant.devices_on(bus)
        if isinstance(worker.adapters.get(d.name), FrameDescriber)
    ]
    return adapters + can_codecs(types_on_bus)


def describe(arbitration_id: int, is_extended: bool, data: bytes, known_ids: set[Key], codecs: Iterable[ModuleType] | None = None) -> str:
    """The first device codec's meaning of a frame, else ``"unknown"``."""
    for codec in can_codecs() if codecs is None else codecs:
        try:
            text = codec.describe_frame(arbitration_id, is_extended, data, known_ids)
        except (LookupError, ValueError) as exc:  # a codec's refusal (a ValueError) or an unknown code: shown as such
            return Message(N_("decode failed: {error}"), error=message_of(exc))
        if text is not None:
            return text
    return UNKNOWN


class FrameDecoder:
    """:func:`describe` with the codecs resolved once and a bounded cache of texts; with
    ``owners`` (:func:`device_owners`) it also names the device of a frame (:meth:`device`)."""

    def __init__(self, known_ids: set[Key] | None = None, codecs: Iterable[ModuleType] | None = None,
                 owners: Iterable[tuple[str, Owner]] = ()):
        self.known_ids: set[Key] = set(known_ids or ())
        self.codecs = list(can_codecs() if codecs is None else codecs)
        self.owners: list[tuple[str, Owner]] = list(owners)
        self._cache: dict[tuple[bool, int, bytes], str] = {}
        self._devices: dict[tuple[bool, int, bytes], str] = {}

    def set_owners(self, owners: Iterable[tuple[str, Owner]]) -> None:
        owners = list(owners)
        if [name for name, _ in owners] != [name for name, _ in self.owners]:
            self._devices.clear()
        self.owners = owners

    def device(self, arbitration_id: int, is_extended: bool, data: bytes) -> str:
        """The plant name(s) of the device(s) a frame comes from or is addressed to, else ``""``."""
        key = (is_extended, arbitration_id, data)
        name = self._devices.get(key)
        if name is None:
            if len(self._devices) >= MAX_CACHE:
                self._devices.clear()
            name = self._devices[key] = device_of(self.owners, arbitration_id, is_extended, data)
        return name

    def record_device(self, rec: FrameRecord) -> str:
        if rec.is_error_frame:
            return ""
        return self.device(rec.arbitration_id, rec.is_extended_id, b"" if rec.is_remote_frame else rec.data)

    def set_codecs(self, codecs: Iterable[ModuleType]) -> None:
        codecs = list(codecs)
        if codecs != self.codecs:
            self.codecs = codecs
            self._cache.clear()

    def set_known_ids(self, known_ids: set[Key]) -> None:
        if known_ids != self.known_ids:
            self.known_ids = set(known_ids)
            self._cache.clear()
            self._devices.clear()  # a device ID changed (Set Device Address) or a device was adopted

    def __call__(self, arbitration_id: int, is_extended: bool, data: bytes) -> str:
        key = (is_extended, arbitration_id, data)
        text = self._cache.get(key)
        if text is None:
            if len(self._cache) >= MAX_CACHE:
                self._cache.clear()
            text = self._cache[key] = describe(arbitration_id, is_extended, data, self.known_ids, self.codecs)
        return text

    def record(self, rec: FrameRecord) -> str:
        if rec.is_error_frame:
            return "error frame"
        if rec.is_remote_frame:
            meaning = self(rec.arbitration_id, rec.is_extended_id, b"")
            return Message(N_("remote request")) if meaning == UNKNOWN else Message(N_("remote request ({meaning})"), meaning=meaning)
        return self(rec.arbitration_id, rec.is_extended_id, rec.data)


def ids_of_devices(frames: Iterable[FrameRecord], codecs: Iterable[ModuleType] | None = None) -> set[Key]:
    """IDs in a recorded file that some codec recognises as a device (its ``discovered`` hook)."""
    codecs = list(can_codecs() if codecs is None else codecs)
    hooks = [c.discovered for c in codecs]  # every CAN codec has one (devices.registry.DeviceType.can_codec)
    found: set[Key] = set()
    for rec in frames:
        key = (rec.is_extended_id, rec.arbitration_id)
        if key in found or rec.is_error_frame or rec.is_remote_frame:
            continue
        for hook in hooks:
            try:
                if hook(rec.arbitration_id, rec.is_extended_id, rec.data):
                    found.add(key)
                    break
            except ValueError:  # a frame a codec cannot parse (its CodecError) is simply not a device
                continue
    return found
