"""CAN discovery needs evidence (issue 10, item 4): a lock is listed only after its status frame
came repeatedly at about 1 s (HD-Lock document 6.5) on an ID that no device type occupies.

Golden checks: an Electrak control frame (ID 0x06) and frames 0x600-0x6FF are never discovered
as locks; a flood of 100,000 new IDs starting 00 00 keeps the tables bounded and is counted.
"""

from __future__ import annotations

import itertools
import time

import can
import pytest
import plants
from conftest import shot, wait_for
from plants import ELECTRAK_ACTUATORS, can_bus, device, hdlock_can

from app.plant import DeviceConfig, parse_plant
from app.worker import Worker
from devices.hdlock import codec

_channels = itertools.count()
STATUS = codec.encode_status(codec.StatusFrame(0x0200, 0, 100, 4))  # bolt in, door open
ELECTRAK_CONTROL_AT_ZERO = bytes.fromhex("00 00 00 00 BE 03 00 01")  # target 0 mm, default current limit


def plant_text(extra: str = "", channel: str | None = None) -> str:
    """A lock with device ID 660100 (and ``extra`` devices) on a virtual CAN bus, without twins."""
    return plants.plant_text(can_bus(hdlock_can("gate", 660100), extra, channel_name=channel, simulate=None), name=None)


ELECTRAK = device("lift", "electrak", "can1", actuators=list(ELECTRAK_ACTUATORS[:1]))


def worker(extra: str = "") -> Worker:
    """A worker that is not started: frames are handed to discovery directly."""
    return Worker(parse_plant(plant_text(extra)))


def feed(w: Worker, can_id: int, times, data: bytes = STATUS, extended: bool = False) -> None:
    for t in times:
        w._discover_frame("can1", can.Message(arbitration_id=can_id, data=data, is_extended_id=extended, timestamp=t))


def listed(w: Worker) -> set[tuple[bool, int]]:
    return set(w.discovered["can1"])


T0 = 1_700_000_000.0


# -- evidence ------------------------------------------------------------------------------------------


def test_one_status_frame_is_not_a_lock():
    w = worker()
    feed(w, 660102, [T0], extended=True)
    assert listed(w) == set()
    assert w.discovery_summary("can1")["candidates"] == 1


def test_status_at_about_one_second_lists_the_lock():
    w = worker()
    feed(w, 660102, [T0, T0 + 1.0], extended=True)
    assert listed(w) == set()
    feed(w, 660102, [T0 + 2.05], extended=True)
    assert listed(w) == {(True, 660102)}
    entry = w.discovered["can1"][(True, 660102)]
    assert entry["type"] == "hdlock" and entry["device_id"] == 660102 and entry["extended"]
    assert entry["frames"] == 3 and "3 frames in a row" in entry["evidence"]
    assert w.discovery_summary("can1")["candidates"] == 0


def test_standard_id_lock_is_listed_too():
    w = worker()
    feed(w, 0x0C, [T0, T0 + 0.98, T0 + 1.99])
    assert listed(w) == {(False, 0x0C)}


@pytest.mark.parametrize("period_s", [0.1, 0.5, 2.0])
def test_a_frame_at_another_period_is_not_a_lock(period_s):
    w = worker()
    feed(w, 0x123, [T0 + n * period_s for n in range(30)])
    assert listed(w) == set()


def test_a_gap_or_another_frame_starts_the_count_again():
    w = worker()
    feed(w, 0x124, [T0, T0 + 1.0, T0 + 4.0, T0 + 5.0])  # a 3 s gap between 2 and 3
    assert listed(w) == set()
    feed(w, 0x125, [T0, T0 + 1.0])
    feed(w, 0x125, [T0 + 1.5], data=bytes.fromhex("05 00 00 00 00 00 00 00"))  # not a status frame
    feed(w, 0x125, [T0 + 2.0])
    assert listed(w) == set()
    feed(w, 0x125, [T0 + 3.0, T0 + 4.0])
    assert listed(w) == {(False, 0x125)}


def test_electrak_control_and_internal_frames_are_never_locks():
    """Even at a lock's period and with a lock's form, on a bus without an Electrak in the plant."""
    w = worker()
    times = [T0 + n for n in range(6)]
    feed(w, 0x06, times, data=ELECTRAK_CONTROL_AT_ZERO)
    for can_id in (0x07, 0x0A, 0x0B, 0x600, 0x650, 0x6FF):
        feed(w, can_id, times)
    for can_id in range(0x700, 0x708):  # the HD-Lock request block itself
        feed(w, can_id, times)
    assert listed(w) == set()
    assert w.discovery_summary("can1")["candidates"] == 0
    assert w.discovery_summary("can1")["refused_frames"] == 6 * 15
    feed(w, 0x5FF, times)  # next to the range: a lock may sit there
    assert listed(w) == {(False, 0x5FF)}


def test_ids_of_configured_devices_are_refused():
    """An M3IO with SW1 0x1A (0x422-0x426): its Sync 0x426, sent by the master, is no lock."""
    w = worker('[[device]]\nname = "io"\ntype = "m3io"\nbus = "can1"\nvariant = "KM"\nsw1 = 0x1A\n')
    feed(w, 0x426, [T0 + n for n in range(5)])
    feed(w, 0x424, [T0 + n for n in range(5)])
    assert listed(w) == set()
    w_electrak = worker(ELECTRAK)
    feed(w_electrak, 0x0A, [T0 + n for n in range(5)])
    assert listed(w_electrak) == set()


# -- bounds -----------------------------------------------------------------------------------------------


def test_a_flood_of_new_ids_is_bounded_and_counted():
    from app.worker import FLOOD_QUIET_S

    w = worker()
    feed(w, 0x0D, [T0])  # a real lock, heard before the flood
    flood = 100_000
    started = time.perf_counter()
    for n in range(flood):
        w._discover_frame("can1", can.Message(arbitration_id=0x10000 + n, data=STATUS, is_extended_id=True, timestamp=T0 + n * 1e-5))
    elapsed = time.perf_counter() - started
    summary = w.discovery_summary("can1")
    assert summary["candidates"] == 0 and summary["flood"].startswith("flood of new CAN IDs")
    assert listed(w) == set()
    # while the flood's echo lasts nothing is listed, the lock neither ...
    feed(w, 0x0D, [T0 + 1.0, T0 + 2.0, T0 + 3.0])
    assert listed(w) == set()
    # ... once it has been quiet for FLOOD_QUIET_S, the lock shows its evidence again and is listed
    quiet = T0 + 1 + FLOOD_QUIET_S
    feed(w, 0x0D, [quiet, quiet + 1.0, quiet + 2.0])
    assert listed(w) == {(False, 0x0D)}
    print(f"flood of {flood} new IDs: {elapsed:.2f} s, {elapsed / flood * 1e6:.1f} us per frame")
    assert elapsed < 20  # O(1) per frame: a few us each on a quiet machine


def test_a_flood_cycling_at_a_locks_period_is_a_flood_not_a_crowd_of_locks():
    """The probe of issue 33 (item 8): 9,009 frames/s (a 1 Mbit/s bus full) of 9,009 unknown extended IDs,
    data 00 00 ..., so each ID comes back every second, as a lock's status does."""
    w = worker()
    ids = 9009
    for second in range(4):
        for i in range(ids):
            w._discover_frame("can1", can.Message(arbitration_id=0x1000000 + i * 7919 % 0xFFFFFF, is_extended_id=True,
                                                  data=bytes([0, 0, i & 0xFF, i >> 8 & 0xFF, 0, 0, 0, 0]),
                                                  timestamp=T0 + second + i / ids))
    summary = w.discovery_summary("can1")
    assert listed(w) == set(), f"{len(listed(w))} flood IDs listed as locks"
    assert summary["candidates"] == 0 and summary["flood"] and summary["floods"] == 1


def test_locks_powered_up_together_are_not_a_flood():
    w = worker()
    locks = 40  # a whole network switched on at once
    for second in range(3):
        for n in range(locks):
            feed(w, 0x40000 + n, [T0 + second + n * 0.001], extended=True)
    assert len(listed(w)) == locks and not w.discovery_summary("can1")["flood"]


def test_silent_candidates_make_room(monkeypatch):
    from app.worker import MAX_CANDIDATES

    # the table's own bound, not the flood rule: patched in the namespace the worker's code runs in
    # (page tests may have imported app.worker afresh since this module imported Worker)
    monkeypatch.setitem(Worker.__init__.__globals__, "FLOOD_NEW_IDS_PER_S", 10 * MAX_CANDIDATES)
    w = worker()
    for n in range(MAX_CANDIDATES):
        w._discover_frame("can1", can.Message(arbitration_id=0x20000 + n, data=STATUS, is_extended_id=True, timestamp=T0))
    feed(w, 0x0E, [T0 + 0.5])
    assert w.discovery_summary("can1")["dropped"] == 1
    feed(w, 0x0E, [T0 + 5.0, T0 + 6.0, T0 + 7.0])  # the flood went silent 5 s ago: its entries give way
    assert listed(w) == {(False, 0x0E)}


def test_the_list_is_bounded():
    from app.worker import MAX_DISCOVERED

    w = worker()
    for n in range(MAX_DISCOVERED + 5):  # one new device a second: no flood
        feed(w, 0x30000 + n, [T0 + n, T0 + n + 1, T0 + n + 2], extended=True)
    assert len(w.discovered["can1"]) == MAX_DISCOVERED
    assert w.discovery_summary("can1")["listed_dropped"] == 5


# -- adopting ---------------------------------------------------------------------------------------------


def test_adopt_refuses_an_overlap():
    w = worker(ELECTRAK)
    with pytest.raises(ValueError, match=r"0x0B.*'spare'.*HD-Lock device ID 11.*'lift'.*Electrak service answer"):
        w.adopt(DeviceConfig("spare", "hdlock", "can1", {"device_id": 11, "extended": False}))
    assert "spare" not in w.plant.devices and "spare" not in w.adapters


def test_adopted_lock_leaves_the_list_and_its_ids_are_refused():
    w = worker()
    feed(w, 0x0F, [T0, T0 + 1, T0 + 2])
    assert listed(w) == {(False, 0x0F)}
    w.adopt(DeviceConfig("spare", "hdlock", "can1", {"device_id": 0x0F, "extended": False}))
    assert listed(w) == set() and "spare" in w.adapters
    assert (False, 0x0F) in w.known_ids("can1")


# -- on a real (virtual) bus ---------------------------------------------------------------------------


async def test_on_the_bus_only_the_lock_is_listed():
    """Frames through python-can and the worker's CanBus, with the senders' time stamps kept."""
    channel = f"discovery-bus-{next(_channels)}-{id(object())}"
    w = Worker(parse_plant(plant_text(channel=channel)))
    await w.start()
    assert await wait_for(lambda: w.store.buses["can1"].connected, timeout=5)
    sender = can.Bus(interface="virtual", channel=channel, preserve_timestamps=True)
    try:
        t0 = time.time() - 10
        for n in range(5):
            t = t0 + n
            sender.send(can.Message(arbitration_id=0x06, data=ELECTRAK_CONTROL_AT_ZERO, is_extended_id=False, timestamp=t))
            sender.send(can.Message(arbitration_id=0x650, data=STATUS, is_extended_id=False, timestamp=t + 0.01))
            sender.send(can.Message(arbitration_id=660102, data=STATUS, is_extended_id=True, timestamp=t + 0.02))
            for k in range(10):  # a node that sends a status-like frame every 100 ms
                sender.send(can.Message(arbitration_id=0x321, data=STATUS, is_extended_id=False, timestamp=t + 0.1 * k))
        assert await wait_for(lambda: (True, 660102) in w.discovered["can1"], timeout=5)
        # every frame sent has been through discovery (dispatch counts a frame before its listeners run)
        assert await wait_for(lambda: w.store.buses["can1"].rx_frames >= 5 * 13, timeout=5), w.store.buses["can1"].rx_frames
        assert listed(w) == {(True, 660102)}
        assert w.discovery_summary("can1")["refused_frames"] == 10
    finally:
        sender.shutdown()
        await w.stop()


# -- the codec's part -------------------------------------------------------------------------------------


def test_codec_asks_for_three_status_frames_one_second_apart():
    """Section 6.5: status "alle 1000 ms", 8 bytes, bytes 0-1 = 0."""
    entry = codec.discovered(660102, True, bytes.fromhex("00 00 17 01 73 00 C4 00"))
    assert entry["evidence"]["period_s"] == 1.0 and entry["evidence"]["frames"] == 3
    assert 0 < entry["evidence"]["tolerance"] < 0.5
    assert entry["status"] == codec.StatusFrame(0x0117, 0x73, 3, 4)
    assert codec.discovered(0x703, False, STATUS) is None  # the request block
    assert codec.discovered(0, False, STATUS) is None  # section 6.4: 0 is the broadcast target
    assert codec.discovered(0x123, False, codec.encode_fwu_status(codec.FwuStatusFrame(False, True))) is None
    assert codec.discovered(0x123, False, STATUS[:6]) is None


# -- the overview in a real browser --------------------------------------------------------------------


# Vue marks an entering element with "...-enter-from/-active/-to" classes until its transition has ended
DIALOG_OPEN_JS = """() => { const d = document.querySelector('.q-dialog');
    if (!d) return false;
    const parts = [d, ...d.querySelectorAll('*')];
    return !parts.some(e => typeof e.className === 'string' && /-enter-/.test(e.className))
        && d.getAnimations({subtree: true}).length === 0
        && getComputedStyle(d.querySelector('.q-dialog__inner')).opacity === '1'; }"""


def test_overview_lists_the_spare_lock_with_its_evidence_and_adopts_it(tmp_path, chromium):
    """The demo plant's spare lock (a simulated lock not in the plant) at 1440x900 and 1024x768."""
    from conftest import free_port, inside_viewport
    from playwright.sync_api import expect
    from webutil import demo_plant_text, running_app

    with running_app(demo_plant_text(free_port()), tmp_path) as url:
        for width, height in ((1440, 900), (1024, 768)):
            context = chromium.new_context(viewport={"width": width, "height": height})
            try:
                page = context.new_page()
                page.set_default_timeout(10_000)
                errors: list[str] = []
                page.on("pageerror", lambda exc, errors=errors: errors.append(str(exc)))
                page.goto(url + "/")
                adopt = page.locator('[data-adopt="660102"]')
                expect(adopt).to_be_visible()
                listing = page.locator('[data-discovered="can1"]')
                expect(listing).to_contain_text("HD-Lock with device ID 660102 (ext 0xA1286)")
                expect(listing).to_contain_text("3 frames in a row")
                adopt.scroll_into_view_if_needed()
                inside_viewport(page, adopt)
                shot(page, str(tmp_path / f"overview-discovered-{width}.png"))
                adopt.click()
                dialog = page.locator(".q-dialog .q-card")
                expect(dialog).to_contain_text("CAN IDs it uses: 0x000A1286 (ext) HD-Lock device ID 660102")
                # the dialog's opening transition has ended: nothing in it is animated any more
                page.wait_for_function(DIALOG_OPEN_JS)
                inside_viewport(page, dialog)
                expect(dialog.get_by_role("button", name="Add to the running plant")).to_be_visible()
                shot(page, str(tmp_path / f"overview-adopt-{width}.png"))
                if width == 1024:
                    page.get_by_role("button", name="Add to the running plant").click()
                    expect(page.locator('[data-device="hdlock-660102"]')).to_be_visible()
                    expect(page.locator('[data-adopt="660102"]')).to_have_count(0, timeout=5_000)
            finally:
                context.close()
            assert not errors, f"JavaScript errors on the page: {errors}"
