"""``commission approve``, ``checkout`` and ``sign`` say their refusals in the command line's language (issue 47): a plant
file that does not load, a login refused, a device the plant does not have, a role that may not act, a checkout running
already, a sign-off by no engineer account; the record keeps what it stores as it was written."""

from __future__ import annotations

import asyncio
import io

import pytest
from plants import can_bus, device, modbus_line, plant_text

from app import cli, cli_lang
from app.record_cli import approve_devices, checkout_devices, sign_record
from app.users import UserStore
from tests.recordutil import demo_runtime

pytestmark = pytest.mark.timeout(120)


@pytest.fixture
def german():
    cli_lang.set_language("de")
    yield
    cli_lang.set_language("en")


def _german(argv: list[str], capsys, stdin: str = "") -> tuple[object, str]:
    """``commission --lang de ARGV``: its exit code (or SystemExit's) and what it printed."""
    import sys

    saved = sys.stdin
    sys.stdin = io.StringIO(stdin)  # a password read from standard input, as a pipe gives it
    try:
        try:
            code = cli.main(["--lang", "de", *argv])
        except SystemExit as exit_:
            code = exit_.code
    finally:
        sys.stdin = saved
        cli.set_language("en")
    captured = capsys.readouterr()
    return code, captured.out + captured.err + (code if isinstance(code, str) else "")


@pytest.mark.parametrize("command", (["approve", "--all", "--account", "anna"], ["checkout", "--all"],
                                     ["sign", "--name", "Anna", "--account", "anna"]))
def test_a_plant_file_that_does_not_load_is_said_in_german(command, tmp_path, capsys):
    path = tmp_path / "plant.toml"
    path.write_text(plant_text(modbus_line(locks=()), name="p") + "\n[[devices]]\nname = \"x\"\n")
    code, out = _german([*command, "--plant", str(path), "--data-dir", str(tmp_path)], capsys, stdin="secret\n")
    assert code == 2, out
    assert "commission: " in out and "unbekannter Abschnitt [[devices]]; war [[device]] gemeint? bekannt: " in out, out
    assert "unknown section" not in out, out


def test_a_refused_login_and_an_unknown_device_in_german(tmp_path, capsys):
    path = tmp_path / "plant.toml"
    heater = device("heater", "m3io", "can-a", variant="HMR", sw1=0xCA, serial=42120023, master="always")
    path.write_text(plant_text(can_bus(heater, name="can-a", bitrate=500000), name="bench"))
    UserStore(tmp_path / "data" / "users.toml").add("anna", "engineer", "anna-password")
    common = ["--plant", str(path), "--data-dir", str(tmp_path / "data"), "--wait", "0"]
    code, out = _german(["approve", "--all", "--account", "anna", *common], capsys, stdin="guess\n")
    assert code == 1 and "commission: Falscher Benutzername oder falsches Passwort für das Konto 'anna': " in out, out
    assert "Wrong user name" not in out
    code, out = _german(["checkout", "--device", "nope", "--answer", "yes", *common], capsys)
    assert "commission: kein Gerät nope in der Anlage bench (Geräte: heater)" in out, out
    code, out = _german(["checkout", "--all", "--answer", "yes", "--sim-action", "nope:blow fuse", *common], capsys)
    assert code == 2 and "commission: --sim-action 'nope:blow fuse': 'nope' ist kein simuliertes Gerät dieser Anlage" in out, out


async def test_the_roles_a_running_checkout_and_a_sign_off_without_an_engineer_account_in_german(tmp_path, german):
    said: list[str] = []
    async with demo_runtime(tmp_path, ("door-2",)) as runtime:
        assert await approve_devices(runtime, ["door-2"], user="vera", role="viewer", out=said.append) == 1
        assert said[-1] == "commission: vera hat die Rolle Betrachter und darf dem Inbetriebnahmeprotokoll nichts hinzufügen", said
        assert await checkout_devices(runtime, ["door-2"], user="vera", role="viewer", answer="yes", out=said.append) == 1
        assert said[-1] == "commission: vera hat die Rolle Betrachter und darf keine Funktionsprüfungen ausführen", said
        assert await sign_record(runtime, user="vera", role="viewer", name="Vera", comment="", out=said.append) == 1
        assert said[-1] == "commission: vera hat die Rolle Betrachter und darf dem Inbetriebnahmeprotokoll nichts hinzufügen", said

        asked, answered = asyncio.Event(), asyncio.Event()

        async def ask(question: str) -> bool:
            asked.set()
            await answered.wait()
            return False

        run = runtime.record.new_run("door-2", user="anna", role="engineer", ask=ask)
        task = asyncio.create_task(run.run())
        try:
            await asyncio.wait_for(asked.wait(), 30)
            said.clear()
            await checkout_devices(runtime, ["door-2"], user="cli:anna", role="engineer", answer="yes", out=said.append)
        finally:
            answered.set()
            await asyncio.wait_for(task, 30)
        assert "door-2: door-2: eine Funktionsprüfung läuft bereits" in said, said
        assert said[-1] == "  door-2: nicht gelaufen: door-2: eine Funktionsprüfung läuft bereits", said  # the summary

        runtime.users.add("anna", "engineer", "anna-password")
        assert await sign_record(runtime, user="cli:anna", role="engineer", name="Anna", comment="", out=said.append,
                                 account="bob", sign_anyway=True) == 1
        assert said[-1].startswith("commission: nicht abgezeichnet: bob ist kein Inbetriebnehmer-Konto"), said
        assert [e.kind for e in await runtime.record.timeline()] == ["checkout"]  # the run that was running, as written
