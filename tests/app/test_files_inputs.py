"""Odd file inputs on the command line (issue 41, items 5 and 9): an empty device selection is an
error, and only regular files are read, with their size checked before reading; /dev/zero, a FIFO
and a folder are refused with a message that says what the path is."""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import free_port

from app import files
from app.cli import main
from plants import modbus_line, plant_text

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.timeout(240)
MEMORY = 1 << 30  # the command under test gets this much address space: /dev/zero must not take the machine


def _plant(tmp_path, project: str | None = None) -> Path:
    text = plant_text(modbus_line(port=free_port(), timeout=0.3, poll_period=0.1, retries=None), name=None)
    if project is not None:
        text = text.replace('name = "door-1"', f'name = "door-1"\nproject = "{project}"', 1)
        assert f'project = "{project}"' in text
    path = tmp_path / "plant.toml"
    path.write_text(text)
    return path


def _limit():
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY, MEMORY))


def _cli(*args: str, timeout: float = 30) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    try:
        return subprocess.run([sys.executable, "-m", "app.cli", *args], cwd=ROOT, env=env, capture_output=True, text=True,
                              timeout=timeout, stdin=subprocess.DEVNULL, preexec_fn=_limit, check=False)
    except subprocess.TimeoutExpired as exc:
        raise AssertionError(f"commission {' '.join(args)} hung for {timeout} s") from exc


@pytest.fixture
def fifo(tmp_path):
    path = tmp_path / "pipe"
    os.mkfifo(path)
    return path


@pytest.mark.parametrize("devices", ["", ",,,", " , "])
def test_apply_to_an_empty_selection_is_an_error(tmp_path, capsys, devices):
    source = tmp_path / "set.json"
    source.write_text(json.dumps({"not": "used"}))
    code = main(["apply", "--plant", str(_plant(tmp_path)), "--from", str(source), "--devices", devices, "--yes",
                 "--data-dir", str(tmp_path / "data")])
    assert code == 2
    err = capsys.readouterr().err
    assert "no device named" in err and "--devices" in err


def test_read_regular_refuses_what_is_not_a_regular_file(tmp_path, fifo):
    for path, kind in ((Path("/dev/zero"), "character device"), (fifo, "FIFO"), (tmp_path, "folder")):
        with pytest.raises(files.FileRefused) as refused:
            files.read_regular(path, what="backup file")
        assert kind in str(refused.value) and "not a regular file" in str(refused.value)
    big = tmp_path / "big.json"
    big.write_bytes(b" " * 2000)
    with pytest.raises(files.FileRefused, match="2000 bytes"):
        files.read_regular(big, limit=1000)
    link = tmp_path / "link.json"
    link.symlink_to(big)
    assert files.read_regular(link) == b" " * 2000


def test_restore_refuses_dev_zero_and_a_fifo(tmp_path, fifo):
    plant = str(_plant(tmp_path))
    for source, kind in (("/dev/zero", "character device"), (str(fifo), "FIFO"), (str(tmp_path), "folder")):
        out = _cli("restore", "--plant", plant, "--device", "door-1", source, "--yes", "--data-dir", str(tmp_path / "data"))
        assert out.returncode == 2, (source, out.returncode, out.stderr[-500:])
        assert kind in out.stderr and "Traceback" not in out.stderr, out.stderr[-500:]


def test_apply_from_says_what_the_source_is(tmp_path, fifo):
    plant = str(_plant(tmp_path))
    for source, kind in (("/dev/zero", "character device"), (str(fifo), "FIFO"), (str(tmp_path), "folder")):
        out = _cli("apply", "--plant", plant, "--from", source, "--devices", "door-1", "--yes", "--data-dir", str(tmp_path / "d"))
        assert out.returncode == 2 and kind in out.stderr and "no such file" not in out.stderr, out.stderr[-500:]


def test_check_refuses_a_project_that_is_no_file(tmp_path, fifo):
    for project, kind in (("/dev/zero", "character device"), (str(fifo), "FIFO")):
        out = _cli("check", "--plant", str(_plant(tmp_path, project)))
        assert out.returncode == 1, (project, out.returncode, out.stderr[-500:])
        assert kind in out.stdout + out.stderr and "Traceback" not in out.stderr, (out.stdout + out.stderr)[-500:]
