"""Tamper evidence of the commissioning record: the chain of row hashes, the archive's manifest and
``commission verify``, against a record edited with sqlite3 from outside and an archive with one
byte changed (issue 43, "The record")."""

from __future__ import annotations

import asyncio
import io
import json
import os
import sqlite3
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from app.record_store import RecordStore
from app.verify import check_archive, check_database, content_sha256

pytestmark = pytest.mark.timeout(120)
ROOT = Path(__file__).resolve().parents[2]


def _store(tmp_path: Path) -> RecordStore:
    store = RecordStore(tmp_path / "record.sqlite")
    approved = store.add(plant="p", device="door", kind="approved", user="anna", role="engineer",
                         data={"parameters": {"holding:3000": {"name": "LockRequestDelay", "raw": 200, "text": "200 ms"}}})
    store.add(plant="p", device="door", kind="checkout", user="anna", role="engineer", title="Lock cycle: passed",
              data={"status": "passed", "steps": []})
    store.add(plant="p", device="", kind="signoff", user="anna", role="engineer", title="signed by Anna Berg",
              data={"name": "Anna Berg", "comment": "all fine", "content": {}, "sha256": content_sha256({})})
    store.add(plant="p", device="door", kind="snapshot", user="anna", role="engineer", data={"parameters": {}},
              supersedes=approved)
    store.close()
    return store


def _outside(path: Path, *sql: str) -> None:
    """Another program (sqlite3) edits the record."""
    db = sqlite3.connect(path)
    for statement in sql:
        db.execute(statement)
    db.commit()
    db.close()


def test_a_fresh_record_is_intact_and_each_row_carries_the_hash_of_the_one_before(tmp_path):
    _store(tmp_path)
    check = check_database(tmp_path / "record.sqlite")
    assert check.ok, check.lines()
    assert check.rows == 4 and check.head[0] == 4
    db = sqlite3.connect(tmp_path / "record.sqlite")
    rows = db.execute("SELECT prev_hash, hash FROM record ORDER BY id").fetchall()
    assert rows[0][0] == "0" * 64 and all(rows[i][0] == rows[i - 1][1] for i in range(1, len(rows)))


def test_a_sign_off_replaced_from_outside_is_named(tmp_path):
    _store(tmp_path)
    path = tmp_path / "record.sqlite"
    db = sqlite3.connect(path)
    row = db.execute("SELECT * FROM record WHERE id = 3").fetchone()
    db.close()
    forged = json.dumps({"name": "Mallory", "comment": "changed", "content": {}, "sha256": content_sha256({})})
    replace = f"INSERT OR REPLACE INTO record VALUES ({', '.join('?' * len(row))})"
    db = sqlite3.connect(path)
    with pytest.raises(sqlite3.DatabaseError, match="append-only"):  # refused while the protection is in place
        db.execute(replace, (*row[:8], forged, *row[9:]))
    db.close()
    _outside(path, "DROP TRIGGER record_no_replace")
    db = sqlite3.connect(path)
    db.execute(replace, (*row[:8], forged, *row[9:]))  # the hash columns copied as they were
    db.commit()
    db.close()
    check = check_database(path)
    assert not check.ok
    assert check.problems[0].startswith("row #3 (signoff 'signed by Anna Berg') was changed"), check.problems

    # and the program, opening the record again, says so instead of putting the protection back silently
    store = RecordStore(path)
    found = store.verify()
    assert any("record_no_replace" in p and "removed from outside" in p for p in found.problems), found.problems
    assert [e.kind for e in store.list("", "")][:1] == ["integrity"]  # a row of the database, of no plant
    store.close()
    again = RecordStore(path).verify()  # and on every later opening: the alteration stays in the record
    assert any("record_no_replace" in p for p in again.problems) and any("row #3" in p for p in again.problems)


def test_a_row_replaced_with_its_hash_recomputed_is_named_by_the_next_link(tmp_path):
    from app.verify import row_hash

    _store(tmp_path)
    path = tmp_path / "record.sqlite"
    db = sqlite3.connect(path)
    db.row_factory = sqlite3.Row
    row = dict(db.execute("SELECT * FROM record WHERE id = 2").fetchone())
    db.close()
    row["user"] = "eve"
    row["hash"] = row_hash(row)  # the rules are public: a forger can recompute the row's own hash
    _outside(path, "DROP TRIGGER record_no_replace")
    db = sqlite3.connect(path)
    db.execute(f"INSERT OR REPLACE INTO record ({', '.join(row)}) VALUES ({', '.join('?' * len(row))})", tuple(row.values()))
    db.commit()
    db.close()
    assert check_database(path).problems[0] == "row #2 was changed or replaced: row #3 no longer links to it"


def test_drop_trigger_and_delete_name_the_missing_row(tmp_path):
    _store(tmp_path)
    path = tmp_path / "record.sqlite"
    _outside(path, "DROP TRIGGER record_no_delete", "DELETE FROM record WHERE id = 2")
    check = check_database(path)
    assert check.problems[0] == "row #2 is missing (deleted from outside the program): row #3 follows #1", check.problems
    assert any("record_no_delete was removed" in p for p in check.problems)


def test_the_last_row_deleted_is_named_by_the_head_kept_beside_the_record(tmp_path):
    _store(tmp_path)
    path = tmp_path / "record.sqlite"
    _outside(path, "DROP TRIGGER record_no_delete", "DELETE FROM record WHERE id = 4",
             "CREATE TRIGGER record_no_delete BEFORE DELETE ON record BEGIN SELECT RAISE(ABORT, 'x'); END;")
    check = check_database(path)
    assert check.problems == ["row #4, the last one written, is missing (deleted from outside the program)"], check.problems


def test_a_record_of_an_older_version_gets_its_chain_with_the_digest_of_its_rows(tmp_path):
    path = tmp_path / "record.sqlite"
    db = sqlite3.connect(path)
    db.executescript("""CREATE TABLE record (id INTEGER PRIMARY KEY AUTOINCREMENT, time REAL NOT NULL, plant TEXT NOT NULL,
        device TEXT NOT NULL, kind TEXT NOT NULL, user TEXT NOT NULL, role TEXT NOT NULL, title TEXT NOT NULL DEFAULT '',
        data TEXT NOT NULL, supersedes INTEGER);
        INSERT INTO record (time, plant, device, kind, user, role, data) VALUES (1.5, 'p', 'd', 'snapshot', 'anna', 'engineer', '{}');""")
    db.commit()
    db.close()
    store = RecordStore(path)
    store.add(plant="p", device="d", kind="snapshot", user="anna", role="engineer", data={})
    check = store.verify()
    assert check.ok and check.rows == 2 and "1 rows were recorded before" in check.notes[0], check.lines()
    store.close()
    _outside(path, "DROP TRIGGER record_no_update", "UPDATE record SET user = 'eve' WHERE id = 1",
             "CREATE TRIGGER record_no_update BEFORE UPDATE ON record BEGIN SELECT RAISE(ABORT, 'x'); END;")
    assert "recorded before the chain began, were changed" in check_database(path).problems[0]


# -- with the running plant: the sign-off, the report and the archive --------------------------------
async def _signed_plant(runtime, tmp_path):
    from app.report import plant_content
    from tests.recordutil import run_checkout

    runtime.users.add("anna", "engineer", "anna-password")
    await runtime.record.approve("door-2", user="local", role="engineer", account="anna")
    await run_checkout(runtime, "door-2", act=True)
    content = await plant_content(runtime, read=False)
    return await runtime.record.sign("", user="local", role="engineer", name="Anna Berg", signer_role="commissioning engineer",
                                     comment="door-2 cycled", content=content, account="anna")


async def test_archive_verifies_and_one_byte_changed_names_the_file(tmp_path):
    from app.report_archive import write_plant
    from tests.recordutil import demo_runtime

    async with demo_runtime(tmp_path, ("door-2",)) as runtime:
        await _signed_plant(runtime, tmp_path)
        paths = await write_plant(runtime, tmp_path / "out")
    archive = paths["zip"]
    check = check_archive(archive)
    assert check.ok, check.lines()
    names = zipfile.ZipFile(archive).namelist()
    assert {"manifest.json", "manifest.sha256", "record/chain.jsonl"} <= set(names)
    assert any(n.startswith("evidence/door-2/") for n in names)
    manifest = json.loads(zipfile.ZipFile(archive).read("manifest.json"))
    assert manifest["simulated"] == ["door-2"] and manifest["tool"].startswith("commission ")
    assert manifest["chain"]["head"]["id"] == check.head[0]

    # one byte changed inside one file's data: that file is named
    data = bytearray(archive.read_bytes())
    with zipfile.ZipFile(io.BytesIO(bytes(data))) as z:
        info = next(i for i in z.infolist() if i.filename.startswith("evidence/door-2/"))
    offset = info.header_offset + 30 + len(info.filename.encode()) + len(info.extra) + info.compress_size // 2
    data[offset] ^= 0x01
    bad = tmp_path / "bad.zip"
    bad.write_bytes(bytes(data))
    check = check_archive(bad)
    assert not check.ok and check.problems[0].startswith(f"file {info.filename} was altered"), check.problems

    # a forged chain inside an otherwise rebuilt archive: the manifest's hash names the chain file
    with zipfile.ZipFile(archive) as z:
        files = {n: z.read(n) for n in z.namelist()}
    files["record/chain.jsonl"] = files["record/chain.jsonl"].replace(b"Anna Berg", b"Eve Forge")
    forged = tmp_path / "forged.zip"
    with zipfile.ZipFile(forged, "w") as z:
        for n, b in files.items():
            z.writestr(n, b)
    check = check_archive(forged)
    assert check.problems[0] == "file record/chain.jsonl was altered: its SHA-256 is not the one in the manifest", check.problems

    # any byte of the archive changed (file data, the deflate stream's padding, headers, the directory): found
    clean = archive.read_bytes()
    for offset in [*range(0, len(clean), max(1, len(clean) // 400)), len(clean) - 1]:
        changed = bytearray(clean)
        changed[offset] ^= 0x40
        bad.write_bytes(bytes(changed))
        assert not check_archive(bad).ok, offset


async def test_a_record_changed_from_outside_is_reported_altered_by_verify_and_the_report(tmp_path):
    from app.report import plant_content, plant_html
    from app.runtime import Runtime
    from tests.recordutil import demo_plant, demo_runtime

    async with demo_runtime(tmp_path, ("door-2",)) as runtime:
        signoff = await _signed_plant(runtime, tmp_path)
    path = tmp_path / "data" / "record.sqlite"
    db = sqlite3.connect(path)
    row = db.execute("SELECT * FROM record WHERE id = ?", (signoff,)).fetchone()
    db.close()
    data = json.loads(row[8])
    data.update(name="Eve Forge", comment="forged")
    _outside(path, "DROP TRIGGER record_no_replace")
    db = sqlite3.connect(path)
    db.execute(f"INSERT OR REPLACE INTO record VALUES ({', '.join('?' * len(row))})", (*row[:8], json.dumps(data), *row[9:]))
    db.commit()
    db.close()
    _outside(path, "DROP TRIGGER record_no_delete", f"DELETE FROM record WHERE id = {signoff - 1}")

    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    result = await asyncio.to_thread(
        subprocess.run, [sys.executable, "-m", "app.cli", "verify", "--record", "--data-dir", str(tmp_path / "data")],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 1, result.stdout + result.stderr
    first = result.stdout.splitlines()[0]
    assert "ALTERED" in first and f"row #{signoff - 1} is missing" in first, result.stdout
    assert f"row #{signoff} (signoff" in result.stdout

    runtime = Runtime(demo_plant(("door-2",)), simulate=True, data_dir=tmp_path / "data")
    await runtime.start()
    try:
        content = await plant_content(runtime, read=False)
    finally:
        await runtime.stop()
    assert not content["record_check"]["ok"]
    html = plant_html(content)
    assert "The record was altered outside the program" in html and "record_no_delete" in html
    assert f"row #{signoff - 1} is missing" in html
