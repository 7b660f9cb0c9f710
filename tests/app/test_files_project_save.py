"""Saving a project into the plant file (issue 41, items 6 and 8): saves are serialised and each one
re-reads the file it changes, a page that shows values changed meanwhile is refused with "changed
meanwhile, reload"; the file is written where a symlink points, keeps its mode, and a read-only
file is refused with the reason."""

from __future__ import annotations

import os
import stat
import threading
import time

import pytest

from app import project
from app.plant import load_plant
from devices.hdlock.params import PARAMS
from plants import device, modbus_line, plant_text

DELAY = next(p for p in PARAMS if p.name == "LockRequestDelay").key
LEFT = next(p for p in PARAMS if p.name == "SettingsProximityOffsetLeft").key
MAXLOCK = next(p for p in PARAMS if p.name == "MaximumTimeLock").key


def _plant_file(folder, name="plant.toml"):
    path = folder / name
    door = device("door-1", "hdlock", "line1", address=1, project={"LockRequestDelay": 300, "SettingsProximityOffsetLeft": -5})
    path.write_text(plant_text(modbus_line(locks=()) + door, name="offline"))
    return path


def _values(path) -> dict:
    return {e.key: e.value for e in project.entries(load_plant(path), "door-1")}


def test_two_saves_at_the_same_moment_keep_both(tmp_path, monkeypatch):
    path = _plant_file(tmp_path)
    plant = load_plant(path)
    real_parse = project.parse_plant

    def slow_parse(*args, **kwargs):  # a save takes a moment between reading the file and writing it
        time.sleep(0.05)  # a save takes a moment between reading and writing (the race under test)
        return real_parse(*args, **kwargs)

    monkeypatch.setattr(project, "parse_plant", slow_parse)
    lost = 0
    for round_ in range(6):
        barrier = threading.Barrier(2)
        errors = []

        def save(changes, barrier=barrier, errors=errors):
            barrier.wait()
            try:
                project.save(plant, "door-1", changes)
            except Exception as exc:  # noqa: BLE001
                errors.append(exc)

        a = threading.Thread(target=save, args=({DELAY: 400 + round_},))
        b = threading.Thread(target=save, args=({MAXLOCK: 5000 + round_},))
        a.start(), b.start(), a.join(), b.join()
        assert not errors, errors
        values = _values(path)
        lost += values.get(DELAY) != 400 + round_ or values.get(MAXLOCK) != 5000 + round_
    assert lost == 0, f"{lost} of 6 rounds lost an update"
    assert {e.key: e.value for e in project.entries(plant, "door-1")} == _values(path), "the running plant follows the file"


def test_a_page_showing_values_changed_meanwhile_is_refused(tmp_path):
    path = _plant_file(tmp_path)
    plant = load_plant(path)
    project.save(plant, "door-1", {DELAY: 410}, expected={DELAY: 300})  # the first page saw 300
    with pytest.raises(project.ProjectError, match="changed meanwhile.*reload"):
        project.save(plant, "door-1", {DELAY: 420}, expected={DELAY: 300})  # the second page saw 300 too
    assert _values(path)[DELAY] == 410


def test_a_save_re_reads_the_file_edited_outside(tmp_path):
    path = _plant_file(tmp_path)
    plant = load_plant(path)
    path.write_text(path.read_text().replace("SettingsProximityOffsetLeft = -5", "SettingsProximityOffsetLeft = -7"))
    project.save(plant, "door-1", {DELAY: 450})
    values = _values(path)
    assert values[DELAY] == 450 and values[LEFT] == -7, "the edit made outside is kept"


def test_a_symlinked_plant_file_is_written_where_it_points_with_its_mode(tmp_path):
    (tmp_path / "real").mkdir()
    target = _plant_file(tmp_path / "real")
    os.chmod(target, 0o644)
    link = tmp_path / "plant.toml"
    link.symlink_to(target)
    plant = load_plant(link)
    project.save(plant, "door-1", {DELAY: 470})
    assert link.is_symlink(), "the link stays a link"
    assert _values(target)[DELAY] == 470
    assert stat.S_IMODE(os.stat(target).st_mode) == 0o644


def test_a_read_only_plant_file_is_refused_with_the_reason(tmp_path):
    path = _plant_file(tmp_path)
    os.chmod(path, 0o444)
    before = path.read_text()
    plant = load_plant(path)
    with pytest.raises(project.ProjectError, match="read-only"):
        project.save(plant, "door-1", {DELAY: 480})
    assert path.read_text() == before and stat.S_IMODE(os.stat(path).st_mode) == 0o444
