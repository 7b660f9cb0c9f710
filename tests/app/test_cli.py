"""The command line: help, plant errors at start-up, and `commission sim` in its own process."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from conftest import free_port, sim_process, wait_for
from plants import bus, can_bus, device, modbus_line, plant_text

from app.cli import main
from app.plant import parse_plant
from app.runtime import Runtime

ROOT = Path(__file__).resolve().parents[2]


def test_help_documents_everything(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for words in ("--plant", "--host", "--port", "--no-sim", "commission sim", "demo plant"):
        assert words in out


def test_malformed_plant_stops_with_its_line(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('[[bus]]\nname = "l"\ntype = "modbus-rtu"\nport = "/dev/x"\n[[device]]\nname = "d"\ntype = "hdlock"\nbus = "l"\naddress = 999\n')
    with pytest.raises(SystemExit) as exc:
        main(["--plant", str(bad)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"{bad}:9:" in err and "outside 1..254" in err


def test_sim_without_simulated_bus_says_so(tmp_path, capsys):
    plant = tmp_path / "real.toml"
    plant.write_text(plant_text(bus("l", "modbus-rtu", port="/dev/ttyUSB0"), name=None))
    assert main(["sim", "--plant", str(plant)]) == 2
    assert "simulate = true" in capsys.readouterr().err


async def test_missing_serial_port_is_reported_and_worker_keeps_running():
    plant = parse_plant(_missing_port_plant())
    runtime = Runtime(plant, simulate=False)
    await runtime.start()
    try:
        state = runtime.store.devices["d"]
        assert await wait_for(lambda: state.status == "offline", timeout=5)
        assert "/dev/ttyNOPE" in runtime.store.buses["l"].last_error
        assert "/dev/ttyNOPE" in state.last_error
        assert all(not t.done() for t in runtime.worker.tasks)
    finally:
        await runtime.stop()


async def test_gui_worker_talks_to_commission_sim_in_another_process(tmp_path):
    port = free_port()
    text = plant_text(bus("line1", "modbus-rtu", device("door-1", "hdlock", "line1", address=3, serial=123456),
                          port=f"socket://127.0.0.1:{port}", simulate=True, timeout=0.3, poll_period=0.1), name=None)
    path = tmp_path / "plant.toml"
    path.write_text(text)
    with sim_process(path) as (_proc, line):
        assert "simulating line1" in line and "door-1" in line
        runtime = Runtime(parse_plant(text), simulate=False)  # the GUI side: no twins of its own
        await runtime.start()
        try:
            state = runtime.store.devices["door-1"]
            assert await wait_for(lambda: state.value("SerialNumber") == 123456, timeout=10)
            adapter = runtime.worker.adapters["door-1"]
            from devices.hdlock.params import PARAMS

            await adapter.write_param(PARAMS.by_name["LockRequestDelay"], 250)
            assert state.value("LockRequestDelay") == 250
        finally:
            await runtime.stop()


def test_headless_backup_and_restore(tmp_path, capsys):
    plant = _sim_plant(tmp_path, free_port())
    data = ["--data-dir", str(tmp_path / "data")]
    assert main(["backup", "--plant", str(plant), "--out", str(tmp_path / "out"), *data]) == 0
    files = list((tmp_path / "out").glob("door-1-*.json"))
    assert len(files) == 1 and "door-1:" in capsys.readouterr().out
    # the simulated lock starts at factory values again, so the restore finds nothing to write
    assert main(["restore", "--plant", str(plant), "--device", "door-1", str(files[0]), "--yes", *data]) == 0
    assert "nothing to write" in capsys.readouterr().out
    broken = tmp_path / "broken.json"
    broken.write_text(files[0].read_text()[:100])
    assert main(["restore", "--plant", str(plant), "--device", "door-1", str(broken), "--yes", *data]) == 2
    assert "truncated or not JSON" in capsys.readouterr().err


def test_restore_yes_refuses_risky_values_unless_named(tmp_path, capsys):
    plant = _sim_plant(tmp_path, free_port())
    data = ["--data-dir", str(tmp_path / "data")]
    assert main(["backup", "--plant", str(plant), "--out", str(tmp_path / "out"), *data]) == 0
    path = next((tmp_path / "out").glob("door-1-*.json"))
    document = json.loads(path.read_text())
    entry = next(e for e in document["parameters"] if e["key"] == "holding:3005")
    entry.update(raw=1, value=1)
    path.write_text(json.dumps(document))
    capsys.readouterr()
    assert main(["restore", "--plant", str(plant), "--device", "door-1", str(path), "--yes", *data]) == 2
    out = capsys.readouterr()
    assert "SettingsRemoveMagnet" in out.out and "needs confirmation" in out.out
    assert "--accept-risk SettingsRemoveMagnet" in out.err and "nothing written" in out.err
    assert main(["restore", "--plant", str(plant), "--device", "door-1", str(path), "--yes",
                 "--accept-risk", "SettingsRemoveMagnet", *data]) == 0
    assert "1 written" in capsys.readouterr().out


def _listener():
    import socket

    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen()
    return sock, sock.getsockname()[1]


def _sim_plant(tmp_path, port):
    plant = tmp_path / "plant.toml"
    plant.write_text(plant_text(modbus_line(port=port, timeout=0.3, poll_period=0.1, retries=None), name=None))
    return plant


def _missing_port_plant() -> str:
    """A lock on a serial port that does not exist."""
    return plant_text(modbus_line((("d", 1),), "/dev/ttyNOPE", "l", timeout=0.1, poll_period=0.1, retries=None,
                                  simulate=None), name=None)


def test_gui_port_in_use_is_named_and_no_url_printed(tmp_path, capsys):
    sock, port = _listener()
    with sock:
        assert main(["--plant", str(_sim_plant(tmp_path, free_port())), "--port", str(port), "--data-dir", str(tmp_path / "d")]) == 2
    out = capsys.readouterr()
    assert "http://" not in out.out
    assert f"port {port}" in out.err and "--port" in out.err


@pytest.mark.parametrize("command", [[], ["backup", "--out", "OUT"]])
def test_simulated_port_taken_refuses_to_start(tmp_path, capsys, command):
    """A second copy of a simulated plant must not poll the first copy's twins as its own."""
    sock, port = _listener()
    args = [a.replace("OUT", str(tmp_path / "out")) for a in command]
    with sock:
        code = main([*args[:1], "--plant", str(_sim_plant(tmp_path, port)), *args[1:], "--data-dir", str(tmp_path / "d")]
                    + ([] if command else ["--port", str(free_port())]))
    assert code == 2
    err = capsys.readouterr().err
    assert f"127.0.0.1:{port}" in err and "line1" in err and "taken" in err


def test_backup_skips_a_device_with_nothing_to_back_up(tmp_path, capsys):
    """An M3IO in simple mode (SW1 switch 8 off) has no stored data: skipped with the reason, the run succeeds."""
    plant = tmp_path / "plant.toml"
    plant.write_text(plant_text(can_bus(device("heater", "m3io", "can3", variant="HM", sw1=0x1A), name="can3",
                                        bitrate=500000), name=None))
    assert main(["backup", "--plant", str(plant), "--out", str(tmp_path / "out"), "--data-dir", str(tmp_path / "d")]) == 0
    out = capsys.readouterr()
    assert "heater: skipped" in out.out and "addressed mode" in out.out
    assert "waiting up to" not in out.out  # a silent module with nothing to back up is not waited for (15 s)
    assert not list((tmp_path / "out").glob("heater-*.json"))


def _interrupted(args, ready: str, tmp_path) -> subprocess.CompletedProcess:
    import os
    import signal
    import sys
    import time

    env = {k: v for k, v in os.environ.items() if k != "PYTEST_CURRENT_TEST"}  # NiceGUI would take it for its own test mode
    # as at a terminal, where Ctrl-C is not ignored: a program started with SIGINT ignored keeps ignoring it (a
    # shell's background job), and a test process can have come to ignore it through a library an earlier test used
    proc = subprocess.Popen([sys.executable, "-m", "app.cli", *args, "--data-dir", str(tmp_path / "d")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT, env=env,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        end = time.monotonic() + 20
        seen = ""
        while ready not in seen and time.monotonic() < end and proc.poll() is None:
            seen += proc.stdout.readline()
        assert ready in seen, seen + (proc.stderr.read() if proc.poll() is not None else "")
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)  # the runtime stops its lines and twins first: slow on a busy machine
    finally:
        if proc.poll() is None:
            proc.kill()
    return subprocess.CompletedProcess(args, proc.returncode, seen + out, err)


def test_ctrl_c_stops_the_gui_with_one_line(tmp_path):
    port = free_port()
    done = _interrupted(["--plant", str(_sim_plant(tmp_path, free_port())), "--port", str(port)], f"http://127.0.0.1:{port}/", tmp_path)
    assert "Traceback" not in done.stderr and "KeyboardInterrupt" not in done.stderr
    assert "commission: stopped (Ctrl-C)" in done.stderr
    assert done.returncode == 130


def test_ctrl_c_stops_a_backup_with_one_line(tmp_path):
    plant = tmp_path / "plant.toml"
    plant.write_text(_missing_port_plant())
    done = _interrupted(["backup", "--plant", str(plant), "--out", str(tmp_path / "out")], "waiting", tmp_path)
    assert "Traceback" not in done.stderr and "KeyboardInterrupt" not in done.stderr
    assert "commission: stopped (Ctrl-C)" in done.stderr
    assert done.returncode == 130
