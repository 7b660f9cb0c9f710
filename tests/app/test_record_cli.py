"""``commission approve``, ``commission checkout`` and ``commission sign``: the commissioning record
without a browser, run as a real subprocess against a small simulated plant with a private data dir."""

from __future__ import annotations

import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
from plants import can_bus, device, plant_text

from app.record_cli import checkout_devices, sign_record
from tests.recordutil import demo_runtime

pytestmark = pytest.mark.timeout(180)

ROOT = Path(__file__).resolve().parents[2]


def _plant(tmp_path: Path) -> Path:
    """One simulated CAN bus of its own with the demo's HMR heater module (6 SSR, 6 inputs)."""
    path = tmp_path / "plant.toml"
    heater = device("heater", "m3io", "can-a", variant="HMR", sw1=0xCA, serial=42120023, master="always")
    path.write_text(plant_text(can_bus(heater, name="can-a", bitrate=500000), name="bench"))
    return path


def _cli(tmp_path: Path, *args: str, stdin: str | None = None, plant: bool = True) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "app.cli", *args, *(("--plant", str(tmp_path / "plant.toml")) if plant else ()),
                           "--data-dir", str(tmp_path / "data")],
                          cwd=ROOT, env=env, input=stdin, capture_output=True, text=True, timeout=150, check=False)


def _rows(tmp_path: Path, kind: str) -> list[tuple]:
    with sqlite3.connect(tmp_path / "data" / "record.sqlite") as db:
        return db.execute("SELECT device, user, role, title FROM record WHERE kind = ? ORDER BY id", (kind,)).fetchall()


def test_checkout_sign_and_a_fault_from_the_command_line(tmp_path):
    _plant(tmp_path)
    added = _cli(tmp_path, "user", "add", "anna", "--role", "engineer", "--password-stdin", stdin="anna-password\n", plant=False)
    assert added.returncode == 0, added.stdout + added.stderr
    wrong = _cli(tmp_path, "approve", "--all", "--account", "anna", stdin="guess\n")
    assert wrong.returncode != 0 and "Wrong user name or password for account 'anna'" in wrong.stdout, wrong.stdout
    approve = _cli(tmp_path, "approve", "--all", "--account", "anna", stdin="anna-password\n")
    assert approve.returncode == 0, approve.stdout + approve.stderr
    assert "heater: approved set stored" in approve.stdout

    ok = _cli(tmp_path, "checkout", "--all", "--answer", "yes")
    assert ok.returncode == 0, ok.stdout + ok.stderr
    out = ok.stdout
    assert "heater (m3io): SSR outputs on and off" in out
    assert "[passed] SSR1-3 on then off" in out and "[passed] E6 toggled (asked)" in out
    assert "answered by cli:" in out and "with --answer yes" in out
    assert "heater: passed in" in out and "1 of 1 checkouts passed" in out

    # a blown fuse on the twin (its declared control, as the page's sim card): the SSR step fails with the reason
    bad = _cli(tmp_path, "checkout", "--device", "heater", "--answer", "yes", "--sim-action", "heater:blow fuse:channel=4")
    assert bad.returncode != 0, bad.stdout + bad.stderr
    assert "heater: simulation: blow fuse channel=4" in bad.stdout
    assert "[failed] SSR4 on then off" in bad.stdout, bad.stdout
    failed_line = next(line for line in bad.stdout.splitlines() if line.startswith("heater: failed"))
    assert "SSR4" in failed_line and ("Si" in failed_line or "fuse" in failed_line.lower()), failed_line
    assert "0 of 1 checkouts passed" in bad.stdout

    # no terminal and no --answer: nobody to ask, the first question fails the run (it does not hang)
    mute = _cli(tmp_path, "checkout", "--device", "heater", stdin="")
    assert mute.returncode != 0 and "nobody to ask" in mute.stdout

    # --answer ask reads the answers on standard input; "no" fails the step and is recorded as given
    asked = _cli(tmp_path, "checkout", "--device", "heater", "--answer", "ask", stdin="no\n")
    assert asked.returncode != 0 and "answered no by cli:" in asked.stdout

    # the last run failed: the sign-off lists it and signs only when told to sign anyway
    held = _cli(tmp_path, "sign", "--name", "Anna Berg", "--comment", "bench commissioned", "--account", "anna",
                stdin="anna-password\n")
    assert held.returncode == 1 and "heater: last SSR outputs on and off failed" in held.stdout, held.stdout
    signed = _cli(tmp_path, "sign", "--name", "Anna Berg", "--comment", "bench commissioned", "--account", "anna", "--yes",
                  stdin="anna-password\n")
    assert signed.returncode == 0, signed.stdout + signed.stderr
    assert "plant bench: signed by Anna Berg (commissioning engineer) with account anna" in signed.stdout
    assert "SSR outputs on and off: failed (4 runs)" in signed.stdout  # every run stays in the record

    checkouts = _rows(tmp_path, "checkout")
    assert [title for _d, _u, _r, title in checkouts] == [
        "SSR outputs on and off: passed", "SSR outputs on and off: failed", "SSR outputs on and off: failed",
        "SSR outputs on and off: failed"]
    assert all(user.startswith("cli") and role == "engineer" for _d, user, role, _t in checkouts)
    assert _rows(tmp_path, "signoff") == [("", "anna", "engineer", "signed by Anna Berg (commissioning engineer) as anna")]
    assert _rows(tmp_path, "approved")[0][1] == "anna"

    verified = _cli(tmp_path, "verify", "--record", plant=False)
    assert verified.returncode == 0 and "intact" in verified.stdout, verified.stdout + verified.stderr


def test_an_unknown_device_is_named(tmp_path):
    _plant(tmp_path)
    result = _cli(tmp_path, "checkout", "--device", "nope", "--answer", "yes")
    assert result.returncode != 0 and "no device nope" in (result.stdout + result.stderr)


async def test_viewers_can_neither_run_checkouts_nor_sign(tmp_path):
    said: list[str] = []
    async with demo_runtime(tmp_path, ("door-2",)) as runtime:
        code = await checkout_devices(runtime, ["door-2"], user="vera", role="viewer", answer="yes", out=said.append)
        assert code == 1 and any("vera has the viewer role and may not run checkouts" in s for s in said), said
        code = await sign_record(runtime, user="vera", role="viewer", name="Vera", comment="", out=said.append)
        assert code == 1 and "may not add to the commissioning record" in said[-1]
        assert await runtime.record.timeline() == []

        said.clear()
        code = await checkout_devices(runtime, ["door-2"], user="cli:anna", role="engineer", answer="yes", out=said.append)
        assert code == 0, said
        assert any(s.startswith("door-2: passed in") for s in said)
        code = await sign_record(runtime, user="cli:anna", role="engineer", name="Anna", comment="ok", out=said.append)
        assert code == 1 and "a sign-off needs a named account" in said[-1]  # the login of the command line is none
        runtime.users.add("anna", "engineer", "anna-password")
        code = await sign_record(runtime, user="cli:anna", role="engineer", name="Anna", comment="ok", out=said.append,
                                 account="anna", sign_anyway=True)
        assert code == 0 and [e.kind for e in await runtime.record.timeline()] == ["signoff", "checkout"]


def test_read_only_values_that_moved_are_live_values_not_changes():
    from app.record_sets import LIVE_VALUE, compare_with_approved
    from app.report import _with_unit

    approved = {"input:0": {"name": "LockState", "raw": 0, "text": "Unlocked (0)", "writable": False},
                "holding:3000": {"name": "LockRequestDelay", "raw": 200, "text": "200 ms", "writable": True}}
    now = {"input:0": {"name": "LockState", "raw": 1, "text": "Locked (1)", "unit": "", "writable": False},
           "holding:3000": {"name": "LockRequestDelay", "raw": 350, "text": "350 ms", "unit": "ms", "writable": True}}
    verdicts = {r["key"]: r["verdict"] for r in compare_with_approved(now, approved)}
    assert verdicts == {"input:0": LIVE_VALUE, "holding:3000": "changed"}
    assert _with_unit("115 Inc", "Inc") == "115 Inc" and _with_unit("115", "Inc") == "115 Inc"
