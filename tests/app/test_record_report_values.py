"""The as-left report on the record page (read=False) shows the values the device page shows: the
live store's, before any snapshot was taken; and says what is missing rather than leaving blanks."""

from __future__ import annotations

import pytest

from app.report import commissioned_text, device_content, device_html
from tests.conftest import wait_for
from tests.recordutil import demo_runtime

pytestmark = pytest.mark.timeout(60)


async def test_report_preview_shows_the_live_values_of_an_online_device_without_a_snapshot(tmp_path):
    async with demo_runtime(tmp_path, ("door-1",)) as runtime:
        state = runtime.store.devices["door-1"]
        assert await wait_for(lambda: state.value("LockRequestDelay") is not None, 15)
        content = await device_content(runtime, "door-1", read=False)
        by_name = {r["name"]: r for r in content["parameters"]}
        assert by_name["LockRequestDelay"]["value"] == "200 ms"
        assert content["counts"]["not approved"] == len(content["parameters"]) > 50
        assert "no parameters read" not in content["parameters_source"]
        html = device_html(content)
        assert "to .</p>" not in html and "not signed yet" in commissioned_text(content)
        assert "0 live value" not in html
        assert content["identity"].get("serial") == 660020  # as the device page shows it, without a snapshot


def test_commissioned_text_names_the_dates_it_has():
    d = {"commissioned_by": ["anna"], "commissioned": ["2026-11-24 10:00:00", "2026-11-24 12:00:00"], "signoff": {"id": 1}}
    assert commissioned_text(d) == "Commissioned by anna from 2026-11-24 10:00:00 to 2026-11-24 12:00:00."
    assert commissioned_text({**d, "signoff": None}, plant_signed=True).endswith("12:00:00.")
    assert commissioned_text({"commissioned_by": [], "commissioned": ["", ""], "signoff": None}) == \
        "Commissioned by nobody yet (no checkout, approved set or snapshot recorded), not signed yet."
