"""MO 64 restore rows: a backed-up value is described in the same words as the device's own answer."""

from __future__ import annotations

from scripts import RX, TX
from test_mo64_adapter import Mo64Script, answer, make_adapter, query

from devices.mo64 import codec


async def test_restore_text_matches_the_backup_text_of_every_setting():
    steps = []
    values = {"t_open": 1000, "t_prewarn_open": 100, "t_prewarn_close": 200, "change_monitoring": 0,
              "maintenance_interval": 50000, "status_mask": {"mask": 0, "more": b""}, "multi_relays": [1, 0, 0, 0, 0, 2],
              "config_flags": dict(zip(("konfig0", "konfig1", "konfig2", "konfig3"), [0, 1, 0, 0]))}
    for key, setting in codec.SETTINGS.items():
        if setting.backup:
            steps += [(TX, query(setting.query)), (RX, answer(setting.query + 5, values[key]))]
    steps += [(TX, query(codec.Q_INDUCTION_LOOPS)), (RX, answer(0x12, [1, 2, 3])),
              (TX, query(codec.Q_DIRECTION_LOGICS)), (RX, answer(0x13, [5, 6])),
              (TX, query(codec.Q_DEC_BT)), (RX, answer(0x10, 0)),
              (TX, query(codec.Q_LOOP_PERIODS)), (RX, answer(0x1B, bytes(6)))]
    async with Mo64Script(steps) as script:
        adapter = make_adapter(script.port)
        entries = await adapter.backup_read()
        script.done()
    described = [e for e in entries if e["writable"]]
    assert described
    for e in described:
        assert adapter.restore_text(e["key"], e["value"]) == e["text"], e["key"]
    # a value the device does not hold now (what a restore would write) in the same words
    assert adapter.restore_text("multi_relays", [1, 0, 0, 0, 0, 3]).startswith("multi1: fault, multi2: off")
    assert adapter.restore_text("t_open", 1100) == "11 s (1100 x 10 ms)"
