"""`commission dbc` from the command line: the DBC of one CAN bus of a plant file."""

from __future__ import annotations

import cantools

from app.cli import main
from app.plant import DEMO_PLANT


def test_dbc_command_writes_a_database_cantools_loads(tmp_path, capsys):
    out = tmp_path / "can3.dbc"
    assert main(["dbc", "--plant", str(DEMO_PLANT), "--bus", "can3", "--out", str(out)]) == 0
    db = cantools.database.load_file(str(out))
    assert db.messages and all(m.frame_id < 0x800 for m in db.messages)  # the M3IO frames use 11-bit IDs
    assert "wrote" in capsys.readouterr().out


def test_dbc_command_names_an_unknown_bus(tmp_path, capsys):
    assert main(["dbc", "--plant", str(DEMO_PLANT), "--bus", "nope", "--out", str(tmp_path / "x.dbc")]) == 2
    err = capsys.readouterr().err
    assert "no bus named 'nope'" in err and "can1" in err
    assert not (tmp_path / "x.dbc").exists()
