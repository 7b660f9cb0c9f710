"""The adapters publish the words the pages show: SCU bit fields and error codes, the MO 64's newest error level."""

from __future__ import annotations

import time

from devices.live import DeviceState
from devices.mo64 import codec as mo_codec
from devices.mo64.adapter import Mo64Adapter
from devices.scu import codec as scu_codec
from devices.scu import params as p
from devices.scu.adapter import ERROR_BIT_GROUPS, ScuAdapter, value_text
from devices.scu.control import ScuControl
from devices.scu.keepalive import RcKeepAlive
from devices.scu.livedata import ScuLiveData
from devices.scu.settings import ScuSettings


def test_scu_flag_words_in_the_pages_words():
    for data_id in p.FLAG_WORDS:
        vtype = p.item(data_id).vtype
        for raw in (0, 1, 5):
            decoded = vtype.decode(raw.to_bytes(vtype.size, "little"))  # as the adapter gets it
            assert value_text(data_id, decoded) == p.flags_text(data_id, raw)
            assert not value_text(data_id, decoded).startswith("0x")


def test_scu_error_codes_in_the_pages_words():
    adapter = ScuAdapter.__new__(ScuAdapter)  # only the publishing path: no line
    adapter.state = DeviceState("scu-1", "scu", "rs1")
    adapter.scales = []
    adapter.core = ScuControl()  # session closed
    adapter.settings = ScuSettings(adapter)
    adapter.rc = RcKeepAlive(adapter)
    adapter.live = ScuLiveData(adapter)
    adapter.rc_times = []
    adapter.live.remote_timeout_seen = False
    now = time.time()
    for data_id, title in ERROR_BIT_GROUPS:
        for code in (0, 1 << 14, (1 << 14) | (1 << 30)):
            adapter.live.publish_one(data_id, code, now)
            assert adapter.state.points[title].text == scu_codec.error_text(code)


def test_mo64_error_memory_point_in_the_pages_words():
    adapter = Mo64Adapter.__new__(Mo64Adapter)  # only the publishing path: no line
    adapter.state = DeviceState("gate-1", "mo64", "gate-bus")
    adapter.error_memory = []
    adapter._error_entry([{"flags": 0b1010, "timestamp_h": 120}, {"flags": 0b0010, "timestamp_h": 100}])
    point = adapter.state.points["Error memory"]
    assert point.value == 0b1010
    assert mo_codec.error_level_meaning(0b1010, 120, 0b0010) in point.text and "120 h" in point.text
    adapter._error_entry([{"flags": 0, "timestamp_h": 0}])
    assert mo_codec.EMPTY_LEVEL in adapter.state.points["Error memory"].text
