"""Recorded files: PEAK .trc besides .log/.asc/.blf/.csv, the format from the content, errors that say
where, reading in chunks with progress, and the recordings folder in the data folder (issue 17 item 3,
issue 15 item 15)."""

from __future__ import annotations

import asyncio
import threading
from pathlib import Path

import can
import pytest
from plants import can_bus, plant_text

from app import recording as rec
from app import runtime as rt
from app.can_bus import CanBusState
from app.plant import parse_plant

FRAMES = [
    can.Message(timestamp=1000.0 + i * 0.01, arbitration_id=can_id, is_extended_id=ext, data=data, is_rx=True, channel=None)
    for i, (can_id, ext, data) in enumerate([
        (0x422, False, b"\x03"),
        (0x000A1284, True, bytes.fromhex("0000170100000200")),
        (0x07, False, bytes.fromhex("E803410000000000")),
        (0x0B, False, b""),
        (0x1FFFFFFF, True, bytes(range(8))),
    ])
]


def _write(path: Path, suffix: str, frames=FRAMES) -> Path:
    writer_class = rec.WRITERS[suffix][0]
    writer = writer_class(path)
    for msg in frames:
        writer.on_message_received(msg)
    writer.stop()
    return path


def _same(loaded: rec.LoadedLog, frames=FRAMES) -> None:
    assert [(f.arbitration_id, f.is_extended_id, f.data) for f in loaded.frames] == [
        (m.arbitration_id, m.is_extended_id, bytes(m.data)) for m in frames]
    gaps = [b.time - a.time for a, b in zip(loaded.frames, loaded.frames[1:], strict=False)]
    assert all(abs(g - 0.01) < 0.0015 for g in gaps), gaps  # .trc keeps 0.1 ms


def test_trc_is_a_recording_format(tmp_path: Path):
    assert ".trc" in rec.WRITERS and ".trc" in rec.READ_SUFFIXES
    state = CanBusState("can1", "can", "virtual x")
    recording = rec.start_recording(state, ".trc", tmp_path)
    assert recording.path.suffix == ".trc" and recording.path.parent == tmp_path
    for msg in FRAMES:
        recording.on_message_received(msg)
    rec.stop_recording(state)
    assert recording.error == "" and recording.frames == len(FRAMES)
    loaded = rec.read_log(recording.path)
    assert loaded.format == ".trc"
    _same(loaded)
    assert [f.name for f in rec.list_recordings(tmp_path)] == [recording.path.name]


@pytest.mark.parametrize("suffix", [".log", ".asc", ".blf", ".csv", ".trc"])
@pytest.mark.parametrize("wrong", ["", ".dat", ".log", ".asc"])
def test_the_format_comes_from_the_content(tmp_path: Path, suffix: str, wrong: str):
    if wrong == suffix:
        return
    written = _write(tmp_path / f"source{suffix}", suffix)
    renamed = written.rename(tmp_path / f"trace{wrong}")
    loaded = rec.read_log(renamed)
    assert loaded.format == suffix
    assert (loaded.frames[1].arbitration_id, loaded.frames[1].is_extended_id) == (0x000A1284, True)
    assert [f.data for f in loaded.frames] == [bytes(m.data) for m in FRAMES]


def test_detect_format_on_heads():
    assert rec.detect_format(b"LOGG\x90\x00\x00\x00") == ".blf"
    assert rec.detect_format(b";$FILEVERSION=2.1\r\n;$STARTTIME=45000.1\r\n") == ".trc"
    assert rec.detect_format(b"timestamp,arbitration_id,extended,remote,error,dlc,data\n") == ".csv"
    assert rec.detect_format(b"(1700000000.000000) can0 422#03\n") == ".log"
    assert rec.detect_format(b"date Mon Jan 1 10:00:00.000 am 2024\nbase hex  timestamps absolute\n") == ".asc"
    assert rec.detect_format(b"hello world\n") is None
    assert rec.detect_format(b"") is None


def test_a_broken_trc_names_its_line(tmp_path: Path):
    path = _write(tmp_path / "t.trc", ".trc")
    lines = path.read_text().splitlines()
    body = [i for i, line in enumerate(lines) if line.strip() and not line.startswith(";")]
    broken = body[2]
    lines[broken] = lines[broken].replace("DT", "DT  1 ZZZZ Rx -  8", 1)[:40] + " not hex"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(rec.RecordingError) as info:
        rec.read_log(path)
    text = str(info.value)
    assert f"line {broken + 1}" in text and "t.trc" in text and "after 2 frames" in text


def test_a_broken_candump_line_and_a_broken_blf_say_where(tmp_path: Path):
    path = tmp_path / "c.log"
    path.write_text("(1.000000) can0 422#03\n(1.100000) can0 423#01\n(1.200000) can0 zz#00\n")
    with pytest.raises(rec.RecordingError, match=r"c\.log: not a valid \.log file at line 3 \(after 2 frames\)"):
        rec.read_log(path)
    blf = _write(tmp_path / "b.blf", ".blf")
    data = bytearray(blf.read_bytes())
    data[200:] = b"\xff" * (len(data) - 200)  # the objects after the header are garbage
    (tmp_path / "b2.blf").write_bytes(bytes(data))
    with pytest.raises(rec.RecordingError, match=r"b2\.blf: .*byte offset \d+"):
        rec.read_log(tmp_path / "b2.blf")


def test_unrecognised_content_with_an_unknown_suffix(tmp_path: Path):
    path = tmp_path / "notes"
    path.write_text("hello\n")
    with pytest.raises(rec.RecordingError, match="unsupported file type .none. and the content is not a recording"):
        rec.read_log(path)


def _many(path: Path, n: int) -> Path:
    path.write_text("".join(f"({i / 1000:.6f}) can0 {0x100 + i % 5:03X}#{i % 256:02X}\n" for i in range(n)))
    return path


def test_progress_and_chunks(tmp_path: Path):
    path = _many(tmp_path / "many.log", 12_000)
    reports: list[tuple[int, float]] = []
    loaded = rec.read_log(path, progress=lambda frames, fraction: reports.append((frames, fraction)))
    assert len(loaded.frames) == 12_000 and not loaded.truncated
    assert [r[0] for r in reports] == [5_000, 10_000, 12_000]
    assert 0.3 < reports[0][1] < 0.5 and reports[-1][1] == 1.0
    chunks = list(rec.iter_log(path, chunk_frames=4_000))
    assert [len(c) for c in chunks] == [4_000, 4_000, 4_000]
    assert loaded.pages(200) == 60 and loaded.page(59, 200)[-1].data == bytes([11_999 % 256])
    assert loaded.page(60, 200) == []
    limited = rec.read_log(path, limit=7_000)
    assert len(limited.frames) == 7_000 and limited.truncated
    exact = rec.read_log(path, limit=12_000)
    assert len(exact.frames) == 12_000 and not exact.truncated


def test_cancel_stops_reading(tmp_path: Path):
    path = _many(tmp_path / "many.log", 12_000)
    cancel = threading.Event()

    def progress(frames: int, _fraction: float) -> None:
        cancel.set()

    loaded = rec.read_log(path, progress=progress, cancel=cancel)
    assert len(loaded.frames) == 5_000 and loaded.truncated


async def test_load_log_reports_progress_on_the_loop(tmp_path: Path):
    path = _many(tmp_path / "many.log", 11_000)
    loop_thread = threading.get_ident()
    seen: list[tuple[int, float, bool]] = []
    loaded = await rec.load_log(path, progress=lambda f, x: seen.append((f, x, threading.get_ident() == loop_thread)))
    await asyncio.sleep(0)  # the last report was scheduled from the reading thread
    assert len(loaded.frames) == 11_000
    assert seen and all(on_loop for _f, _x, on_loop in seen) and seen[-1][:2] == (11_000, 1.0)


def test_recordings_go_to_the_data_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.delenv(rec.DIR_ENV, raising=False)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("COMMISSION_DATA_DIR", str(tmp_path / "userdata"))
    assert rec.recordings_dir() == tmp_path / "userdata" / "recordings"  # no plant running: the user's data folder
    plant = parse_plant(plant_text(can_bus(name="c", channel_name="rd-1", simulate=None)))
    runtime = rt.Runtime(plant, simulate=False, data_dir=tmp_path / "data")
    rt.set_current(runtime)
    try:
        assert rec.recordings_dir() == tmp_path / "data" / "recordings"
        state = CanBusState("c", "can", "virtual rd-1")
        recording = rec.start_recording(state, ".log")
        rec.stop_recording(state)
        assert recording.path.parent == runtime.data_dir / "recordings" == runtime.backups_dir.parent / "recordings"
        assert not (tmp_path / "recordings").exists()
    finally:
        rt.set_current(None)
    monkeypatch.setenv(rec.DIR_ENV, str(tmp_path / "elsewhere"))
    assert rec.recordings_dir() == tmp_path / "elsewhere"
