"""What an open M3IO page costs per push (issue 34): telegrams with the same values draw nothing; the page's
once-a-second round draws the ages and stale marks; a new value is drawn on the push that brings it."""

from __future__ import annotations

import time

import pytest
from plants import can_bus, m3io_can, plant
from webutil import eventually, push_the_same_values, refresh_on_the_round, simulated_user

from app.runtime import Runtime

pytestmark = pytest.mark.timeout(60)

DRAWN = ("E1", "TEMP1", "SSR1 Last")




async def test_telegrams_with_the_same_values_draw_nothing_and_the_round_draws_ages(tmp_path, monkeypatch):
    runtime = Runtime(plant(can_bus(m3io_can("heater-hm", master="always"), name="can3", bitrate=500000)),
                      simulate=True, data_dir=tmp_path)
    async with simulated_user(runtime) as user:
        state = runtime.store.devices["heater-hm"]
        await eventually(lambda: all(n in state.points for n in DRAWN), timeout=10)
        view, read = await push_the_same_values(user, runtime, "heater-hm", monkeypatch)
        now = time.time()
        assert not [n for n in read if n in DRAWN], read  # nothing drawn again
        refresh_on_the_round(runtime.store, view)  # the once-a-second round: ages and stale marks drawn
        assert set(DRAWN) <= set(read)
        read.clear()  # a new value is drawn on the push that brings it
        state.publish_telegram(now, {"E1": state.points["E1"]._replace(value=not state.points["E1"].value)})
        view.refresh()
        assert "E1" in read
        (lamp,) = [e for e in user.client.elements.values() if e.props.get("data-lamp") == "E1"]
        assert lamp.props["data-on"] == str(int(bool(state.points["E1"].value)))
