"""Bad files get a clear message, never a traceback nor a silent acceptance (issue 33, item 9):
backups with huge numbers, deep nesting or fields of the wrong kind; plant and account files
with bytes that are not UTF-8; traces with NaN time stamps or IDs wider than 29 bits."""

from __future__ import annotations

import json
import re

import pytest

from app import backup
from app.cli import main
from app.plant import PlantError, load_plant
from app.recording import UPLOADS_KEPT, RecordingError, read_log, store_upload, upload_name
from app.users import UserError, UserStore
from webutil import DEMO_PLANT

GOOD = {"schema": "commission-backup", "version": 1, "device": {"name": "door-1", "type": "hdlock", "bus": "line1"},
        "identity": {"serial": 1}, "plant": "demo", "time": "2026-11-22T10:15:00+00:00",
        "tool": {"name": "commission", "version": "0.1.0"},
        "parameters": [{"key": "holding:3000", "name": "LockRequestDelay", "raw": 200, "value": 200, "writable": True}]}


def variant(**changes) -> bytes:
    return json.dumps({**GOOD, **changes}).encode()


BAD_BACKUPS = {
    "5000-digit number": json.dumps(GOOD).replace('"raw": 200', '"raw": ' + "9" * 5000).encode(),
    "200k-deep nesting": b'{"schema": "commission-backup", "version": 1, "x": ' + b"[" * 200_000 + b"]" * 200_000 + b"}",
    "tool not an object": variant(tool="commission 0.1"),
    "identity not an object": variant(identity=[1, 2]),
    "device name not a text": variant(device={"name": 7, "type": "hdlock"}),
    "parameter key not a text": variant(parameters=[{"key": 3000, "name": "x", "raw": 1, "writable": True}]),
    "not UTF-8": b'{"schema": "\xff\xfe"}',
    "too large": b" " * (backup.MAX_BACKUP_BYTES + 1),
}


@pytest.mark.parametrize("what", BAD_BACKUPS)
def test_a_bad_backup_is_refused_by_name(what):
    with pytest.raises(backup.BackupError) as refused:
        backup.load_document(BAD_BACKUPS[what], "door-1.json")
    assert str(refused.value).startswith("door-1.json: ")


def test_the_good_backup_still_loads():
    assert backup.load_document(variant(), "door-1.json")["tool"]["version"] == "0.1.0"


@pytest.mark.parametrize("what", ["5000-digit number", "200k-deep nesting", "tool not an object"])
def test_restore_command_names_a_bad_backup_without_a_traceback(tmp_path, capsys, what):
    path = tmp_path / "bad.json"
    path.write_bytes(BAD_BACKUPS[what])
    assert main(["restore", "--device", "door-1", str(path), "--yes"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("commission restore: ") and "Traceback" not in err


def test_a_plant_file_that_is_not_utf8_is_named(tmp_path, capsys):
    path = tmp_path / "site.toml"
    path.write_bytes(DEMO_PLANT.read_bytes().replace(b'name = "demo"', b'name = "d\xe9mo"'))
    with pytest.raises(PlantError, match=r"site\.toml:4: .*not UTF-8.*byte 0xe9"):
        load_plant(path)
    with pytest.raises(SystemExit) as stopped:
        main(["sim", "--plant", str(path)])
    assert stopped.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("commission: ") and "not UTF-8" in err and "Traceback" not in err


def test_an_accounts_file_that_is_not_utf8_is_named(tmp_path):
    (tmp_path / "users.toml").write_bytes(b'[[user]]\nname = "\xff"\n')
    with pytest.raises(UserError, match="not UTF-8"):
        UserStore(tmp_path / "users.toml")


def test_simulate_must_be_a_boolean(tmp_path):
    path = tmp_path / "site.toml"
    path.write_text(re.sub(r"(?m)^simulate = true", 'simulate = "yes"', DEMO_PLANT.read_text(), count=1))
    with pytest.raises(PlantError, match=r"simulate must be true or false \(without quotes\), not 'yes'"):
        load_plant(path)


@pytest.mark.parametrize("suffix, text, why", [
    (".log", "(1700000000.000000) can0 123#00\n(nan) can0 123#00\n", "line 2.*not a number"),
    (".csv", "timestamp,arbitration_id,extended,remote,error,dlc,data\n1700000000.0,0x123,0,0,0,1,AA==\n"
             "1700000000.5,0xFFFFFFFFF,1,0,0,1,AA==\n", "line 3.*does not fit 29 bits"),
])
def test_a_trace_with_an_impossible_frame_is_refused_where_it_is(tmp_path, suffix, text, why):
    path = tmp_path / f"trace{suffix}"
    path.write_text(text)
    with pytest.raises(RecordingError, match=why):
        read_log(path)


# -- uploaded recordings (the replay page) --------------------------------------------------------


@pytest.mark.parametrize("name", ["..", ".", "", "../", "a/..", ".hidden"])
def test_an_upload_named_dot_or_dotdot_is_refused_by_name(name):
    with pytest.raises(RecordingError, match="is not a file name"):
        upload_name(name)


async def test_uploads_are_streamed_into_one_folder_and_only_the_newest_kept(tmp_path):
    from nicegui.elements.upload_files import LargeFileUpload, SmallFileUpload

    line = "(1700000000.000000) can0 123#00\n"
    big = tmp_path / "spooled"
    big.write_text(line * 1000)
    uploads = [SmallFileUpload(f"trace-{n}.log", "text/plain", line.encode()) for n in range(UPLOADS_KEPT + 2)]
    uploads.append(LargeFileUpload("../../big.log", "text/plain", big))
    paths = [await store_upload(u, tmp_path / "recordings") for u in uploads]
    folder = tmp_path / "recordings" / "uploads"
    assert all(p.parent == folder for p in paths) and paths[-1].name.endswith("-big.log")
    assert sorted(folder.iterdir()) == sorted(paths[-UPLOADS_KEPT:])  # nothing else is left behind
    assert read_log(paths[-1]).frames[0].arbitration_id == 0x123
