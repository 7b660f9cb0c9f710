"""What ``commission export`` prints of a recording it cannot read, in the command line's language (issue 47): the
recorded file's errors of app/recording (where reading stopped: Zeile, Byte-Offset; a file of no known format), with
python-can's and the operating system's own words inside as they are; in English as before."""

from __future__ import annotations

import pytest

from app import cli

pytestmark = pytest.mark.timeout(60)


def _export(argv: list[str], capsys, lang: str) -> tuple[int, str]:
    try:
        code = cli.main(["--lang", lang, "export", *argv])
    finally:
        cli.set_language("en")
    captured = capsys.readouterr()
    return code, captured.out + captured.err


@pytest.mark.parametrize(("name", "content", "german", "english"), (
    ("bad.log", b"(1700000000.000000) can0 301#01\n(broken line\n",
     "commission export: bad.log: keine gültige .log-Datei bei Zeile 2 (nach 1 Frames): ",
     "commission export: bad.log: not a valid .log file at line 2 (after 1 frames): "),
    ("broken.blf", b"not a blf file" * 10, "commission export: broken.blf: kann nicht als .blf-Datei geöffnet werden (Byte-Offset ",
     "commission export: broken.blf: cannot open as .blf file (byte offset "),
    ("notes.txt", b"hello\n", "commission export: notes.txt: Dateityp .txt wird nicht unterstützt",
     "commission export: notes.txt: unsupported file type .txt"),
))
def test_a_recording_export_cannot_read_is_said_in_german(name, content, german, english, tmp_path, capsys):
    source = tmp_path / name
    source.write_bytes(content)
    code, out = _export([str(source), "--out", str(tmp_path / "out.mcap")], capsys, "de")
    assert code == 1 and out.startswith(german), out
    code, out = _export([str(source), "--out", str(tmp_path / "out.mcap")], capsys, "en")
    assert code == 1 and out.startswith(english), out


def test_a_missing_recording_is_said_in_german(tmp_path, capsys):
    code, out = _export([str(tmp_path / "gone.asc"), "--out", str(tmp_path / "out.mcap")], capsys, "de")
    assert code == 1 and out.startswith("commission export: gone.asc: kann nicht geöffnet werden: "), out


def test_an_output_it_cannot_write_is_said_before_anything_runs(tmp_path, capsys):
    """A folder that does not exist, or a folder named as the file: said at once (for --live before the plant runs
    its seconds), with what to do, and no traceback."""
    source = tmp_path / "one.log"
    source.write_bytes(b"(1700000000.000000) can0 301#01\n")
    code, out = _export([str(source), "--out", str(tmp_path / "gone" / "out.mcap")], capsys, "en")
    assert code == 2 and out.startswith(f"commission export: cannot write {tmp_path / 'gone' / 'out.mcap'}: the folder "), out
    assert "Traceback" not in out
    code, out = _export(["--live", "600", "--out", str(tmp_path)], capsys, "de")
    assert code == 2 and out.startswith(f"commission export: {tmp_path} kann nicht geschrieben werden: "), out
    assert "ein Ordner" in out and "export.mcap" in out
