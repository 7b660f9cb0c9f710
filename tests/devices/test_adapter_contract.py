"""Every device adapter meets the contract of devices/adapter.py for the capabilities it has."""

from __future__ import annotations

import inspect

import pytest

from devices import adapter as contract
from devices.electrak.adapter import ElectrakAdapter
from devices.hdlock.adapter import HdLockAdapter
from devices.hdlock.can_adapter import HdLockCanAdapter
from devices.m3io.adapter import M3ioAdapter
from devices.mo64.adapter import Mo64Adapter
from devices.scu.adapter import ScuAdapter

ADAPTERS = (ElectrakAdapter, HdLockAdapter, HdLockCanAdapter, M3ioAdapter, Mo64Adapter, ScuAdapter)


@pytest.mark.parametrize("cls", ADAPTERS, ids=lambda c: c.__name__)
def test_every_adapter_polls_backs_up_and_holds_sessions(cls):
    for protocol in (contract.PollingAdapter, contract.BackupAdapter, contract.SessionHolder):
        assert issubclass(cls, protocol), protocol.__name__
    assert issubclass(cls, contract.ParamWriter) or issubclass(cls, contract.EntryRestorer)
    assert issubclass(cls, contract.BackupDefaults)  # what it declares about its backup, read without probing


@pytest.mark.parametrize("cls", [c for c in ADAPTERS if issubclass(c, contract.ControlAdapter)], ids=lambda c: c.__name__)
def test_take_control_is_async_in_every_adapter(cls):
    assert inspect.iscoroutinefunction(cls.take_control)


def test_the_control_adapters_are_the_motion_and_mains_devices():
    assert {c.__name__ for c in ADAPTERS if issubclass(c, contract.ControlAdapter)} == {"ElectrakAdapter", "M3ioAdapter", "ScuAdapter"}
