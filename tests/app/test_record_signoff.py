"""Who signed is known, every run stays, and the as-left report reads as a site's document (issue 43,
"The record"): a sign-off names an engineer account, the report's first page is a summary, settings
stand apart from live values, each step names its evidence file and SHA-256, a report made on
simulated devices says so on every page, and the cover names the version and the plant file."""

from __future__ import annotations

import asyncio
import hashlib
import io
import zipfile
from pathlib import Path

import pytest

from app import i18n
from app.plant import load_plant
from app.record_store import RecordError
from app.report import (
    SIMULATED_MARK,
    _with_unit,
    plant_content,
    plant_html,
    sign_gaps,
)
from app.report_archive import write_plant
from app.report_pdf import plant_pdf
from tests.recordutil import DEMO, demo_plant, run_checkout

pytestmark = pytest.mark.timeout(120)


def test_a_value_with_its_unit_in_a_remark_gets_no_second_unit():
    assert _with_unit("65535 ms (at its top: 65.5 s or more)", "ms") == "65535 ms (at its top: 65.5 s or more)"
    assert _with_unit("200", "ms") == "200 ms"


async def test_sign_off_needs_an_engineer_account_and_every_run_stays_in_the_report(tmp_path):
    from app.runtime import Runtime
    from tests.conftest import wait_for

    source = demo_plant(("door-2",))
    path = tmp_path / "plant.toml"
    path.write_text(DEMO.read_text())  # the demo's file; the runtime below uses the free ports of ``source``
    runtime = Runtime(source, simulate=True, data_dir=tmp_path / "data")
    runtime.plant.path = path
    await runtime.start()
    try:
        state = runtime.store.devices["door-2"]
        assert await wait_for(lambda: state.status == "online" and state.value("LockRequestDelay") is not None, 20)
        content = await plant_content(runtime, read=False)
        assert sign_gaps(content) == ["door-2: no checkout run, no approved set"]

        await asyncio.to_thread(runtime.users.add, "anna", "engineer", "anna-password")  # argon2: off the event loop
        await asyncio.to_thread(runtime.users.add, "vera", "viewer", "vera-password")
        await runtime.record.approve("door-2", user="local", role="engineer", account="anna")
        # two runs, whatever the second's result (the family's own steps are not under test here)
        failed = await run_checkout(runtime, "door-2", answer=False, user="anna")  # "is the door closed?" no
        second = await run_checkout(runtime, "door-2", user="anna", act=True)
        assert failed["status"] == "failed"
        content = await plant_content(runtime, read=False)
        assert sign_gaps(content) == ([] if second["status"] == "passed" else ["door-2: last Lock and unlock cycle failed"])

        for account, words in (("", "needs a named account"), ("local", "needs a named account"),
                               ("cli:anna", "needs a named account"), ("vera", "no engineer account"),
                               ("nobody", "no engineer account")):
            with pytest.raises(RecordError, match=words):
                await runtime.record.sign("", user="local", role="engineer", name="Anna Berg", signer_role="engineer",
                                          comment="", content=content, account=account)
        entry_id = await runtime.record.sign("", user="local", role="engineer", name="Anna Berg", signer_role="commissioning engineer",
                                             comment="door-2 cycled", content=content, account="anna")
        entry = await runtime.record.get(entry_id)
        assert entry.user == "anna" and entry.data["account"] == "anna"

        content = await plant_content(runtime, read=False)
        paths = await write_plant(runtime, tmp_path / "out", content)
    finally:
        await runtime.stop()

    door = content["devices"][0]
    assert [c["status"] for c in door["checkouts"]] == [second["status"], "failed"]  # every run, newest first
    summary = door["checkout_summary"][0]
    ok = second["status"] == "passed"
    assert (summary["runs"], summary["passed"], summary["failed"], summary["last"], summary["by"]) == \
        (2, int(ok), 2 - int(ok), second["status"], ["anna"])
    assert content["signoff"]["account"] == "anna"

    # settings apart from live values
    settings = {r["name"] for r in door["settings"]}
    live = {r["name"] for r in door["live_values"]}
    assert {"LockRequestDelay", "LockMaximumTime"} <= settings and not settings & live  # MFR: the factory's configuration
    assert {"LockState", "BoltPosition", "LockStatus", "BoltPosition (HR1001)", "MaximumTimeLock"} <= live

    # each step names its evidence file and its SHA-256, the same as the file in the archive
    archive = zipfile.ZipFile(io.BytesIO(paths["zip"].read_bytes()))
    named = [s["evidence_file"] for c in door["checkouts"] for s in c["steps"] if s.get("evidence_file")]
    assert named
    for f in named:
        assert hashlib.sha256(archive.read(f["name"])).hexdigest() == f["sha256"]

    html = plant_html(content)
    assert "account anna" in html and named[0]["name"] in html and named[0]["sha256"] in html
    assert SIMULATED_MARK in html
    assert f"Plant file {path}, SHA-256 {hashlib.sha256(path.read_bytes()).hexdigest()}" in html
    assert content["tool"].startswith("commission ") and content["tool"] in html
    assert "Record check: intact" in html

    from pypdf import PdfReader

    pages = [page.extract_text() for page in PdfReader(paths["pdf"]).pages]
    assert all("SIMULATED DEVICES" in text for text in pages), [t[:80] for t in pages]
    first = " ".join(pages[0].split())  # table cells wrap
    assert "door-2" in first and f"2 runs ({int(ok)} passed, {2 - int(ok)} not)" in first and "by anna" in first
    assert "LockRequestDelay" not in first, "page 1 is the summary: the listings are in the appendix"
    assert "account anna" in first and "SHA-256" in first
    appendix = "\n".join(pages[pages.index(next(t for t in pages if "Appendix" in t)):])
    assert "LockRequestDelay" in appendix and named[0]["name"].split("/")[-1] in appendix.replace("\n", "")

    # the same content in German, chosen when the report is made: none of the report's own English texts
    german_html = plant_html(content, i18n.get("de"))
    german_pdf = " ".join(" ".join(page.extract_text().split()) for page in PdfReader(io.BytesIO(plant_pdf(content, i18n.get("de")))).pages)
    english = _report_texts()
    assert [f for f in english if f in " ".join(html.split())], "the check must see the English report's texts"
    for made in (" ".join(german_html.split()), german_pdf):
        assert not [f for f in english if f in made], [f for f in english if f in made]
        assert "SIMULIERTE GERÄTE" in made and "Übergabebericht" in made and "Konto anna" in made
        assert "Läufe" in made and "Anhang" in made and "Prüfung des Protokolls: unverändert" in made
    assert "<html lang='de'>" in german_html and "Seite 1" in german_pdf


def _report_texts() -> list[str]:
    """The English texts the report writes itself (the catalog entries of app/report*.py), each cut at its fields into
    the pieces of two words or more (a field's value is the content's: names, times, hashes)."""
    import re

    from babel.messages.pofile import read_po

    with open(Path(__file__).resolve().parents[2] / "locale" / "messages.pot", "rb") as f:
        template = read_po(f)
    pieces = set()
    for m in template:
        ids = m.id if isinstance(m.id, tuple) else (m.id,)
        if not m.id or not any(path.startswith("app/report") for path, _line in m.locations):
            continue
        for text in ids:
            for piece in re.split(r"\{\w*\}", text):
                piece = " ".join(piece.split()).strip(" ,;:.()#")
                if len(piece.split()) >= 2 and "SHA-256" not in piece:
                    pieces.add(piece)
    return sorted(pieces)


def test_sign_gaps_name_each_missing_piece():
    device = {"device": "m1", "checkouts": [{"id": 1}], "checkout_summary": [{"title": "SSR", "last": "failed"}],
              "approved": {"id": 2}, "counts": {"not approved": 95, "changed": 1}}
    assert sign_gaps({"devices": [device]}) == ["m1: last SSR failed, 95 parameters not approved, 1 parameter changed since approved"]
    assert sign_gaps(device) == sign_gaps({"devices": [device]})


def test_load_plant_keeps_its_path():
    assert load_plant(DEMO).path is not None
