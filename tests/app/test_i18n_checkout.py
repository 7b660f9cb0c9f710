"""A checkout's texts in the reader's language (docs/i18n.md): the record keeps the English it stored (hashed, checked
by ``commission verify``) and beside it the template of each text (``worded``), so that after a restart the record
page, the as-left report (HTML and PDF) and the command line word a run in German; a row written without that table reads as
before."""

from __future__ import annotations

import functools
import io
import re
from html import unescape
from pathlib import Path

import pytest
from babel.messages.pofile import read_po
from pypdf import PdfReader

from app import cli_lang, i18n
from app.message import Message, reworded, said, worded_table
from app.record_cli import checkout_devices
from app.report import measured_text, plant_content, plant_html
from app.report_pdf import plant_pdf
from devices.message import N_, Word
from tests.conftest import wait_for
from tests.recordutil import demo_runtime, run_checkout

pytestmark = pytest.mark.timeout(120)

DE = i18n.get("de")
LOCALE = Path(__file__).resolve().parents[2] / "locale"
CHECKOUT_MODULES = ("app/checkout.py", "devices/hdlock/checkout.py", "devices/m3io/checkout.py", "devices/mo64/checkout.py",
                    "devices/electrak/checkout.py", "devices/scu/checkout.py")
TAG = re.compile(r"<[^>]+>")


def test_a_stored_text_is_its_message_again_and_anything_else_stays_as_stored():
    state = Message(N_("state {value}"), value=5)
    inner = Message(N_("{input} reads {celsius:.1f} °C"), input="TEMP1", celsius=250.25)
    text = Message(N_("{readings}: outside the measuring range 0 .. 200 °C (7.2.2), the Pt100 is broken or not connected; "
                      "check its wiring and the sensor"), readings=inner)
    word = Message("{state}", state=Word("open", "Gate state"))
    table = worded_table({"reason": text, "values": [{"name": state, "value": word}], "evidence": {"x": Message(N_("all"))}},
                         leave_out=("evidence",))
    assert set(table) == {str(text), str(state), str(word)}  # what is left out is not kept
    assert table[str(word)] == {"t": "{state}", "f": {"state": {"w": "open", "c": "Gate state"}}}
    assert table[str(text)]["f"]["readings"] == {"t": inner.template, "f": {"input": "TEMP1", "celsius": 250.25}}
    again = reworded(str(text), table)
    assert isinstance(again, Message) and again == text  # the English as stored
    assert said(again, DE).startswith("TEMP1 liest 250,2 °C: außerhalb des Messbereichs"), said(again, DE)
    assert said(reworded(str(word), table), DE) == "Schranke ist geöffnet"  # the plant view's word for the gate state
    assert reworded("as written", table) == "as written" and reworded(str(text), None) == str(text)  # before this table
    broken = {str(state): {"t": "level {value}", "f": {"value": 5}}}  # a template that no longer gives the English
    assert reworded(str(state), broken) == str(state) and not isinstance(reworded(str(state), broken), Message)


def test_a_measured_flag_is_ja_or_nein_in_german_and_true_or_false_as_stored():
    limit = Message("= {expect}", expect=True)
    assert limit == "= True" and said(limit, DE) == "= ja" and said(limit, i18n.get("en")) == "= True"
    value = {"name": Message(N_("LS after freeing")), "value": False, "unit": "", "limit": Message("= {expect}", expect=False),
             "ok": True}
    run = {"worded": worded_table({"values": [value]})}
    assert measured_text(value, DE, run) == "LS nach dem Freigeben = nein (= nein: ok)", measured_text(value, DE, run)
    assert measured_text(value, i18n.get("en"), run) == "LS after freeing = False (= False: ok)"


@functools.cache
def checkout_patterns() -> list[tuple[str, re.Pattern]]:
    """Every English text of the checkouts and of their runner whose German differs: its words between its fields
    (12 letters or more, so that a word of the documents kept in German, ``Triac``, is no finding)."""
    with open(LOCALE / "de" / "LC_MESSAGES" / "messages.po", "rb") as f:
        german = read_po(f)
    patterns = []
    for message in german:
        if not message.id or message.string == message.id or not any(path in CHECKOUT_MODULES for path, _ in message.locations):
            continue
        for part in re.split(r"\{[^{}]*\}", message.id):
            if len(part.strip()) >= 12 and part.strip() not in message.string:
                patterns.append((message.id, re.compile(re.escape(part.strip()))))
    return patterns


def english_in(html: str) -> list[tuple[str, str]]:
    texts = [piece.strip() for piece in unescape(TAG.sub("\n", html)).split("\n") if piece.strip()]
    return [(text, message) for text in texts for message, pattern in checkout_patterns() if pattern.search(text)]


async def test_a_checkout_run_is_worded_in_german_after_a_restart(tmp_path):
    async with demo_runtime(tmp_path, ("door-2",)) as runtime:
        state = runtime.store.devices["door-2"]
        assert await wait_for(lambda: None not in (state.value("LockMaximumTime"), state.value("UnlockMaximumTime"),
                                                   state.value("LockRequestDelay")), 20), "door-2's settings"
        passed = await run_checkout(runtime, "door-2", act=True)  # the twin's door is opened and closed as asked
        failed = await run_checkout(runtime, "door-2", answer=False)  # "is the door closed?" no: its reason
    assert passed["status"] == "passed", passed
    assert failed["reason"] == "Is the door closed and is nobody in the way of the bolt? - answered no by anna"  # as ever

    async with demo_runtime(tmp_path, ("door-2",), online=False) as runtime:  # the record read again
        check = await runtime.record.check()
        assert check.ok, check.problems  # the rows with their tables are chained and hashed as every row
        newest, first = await runtime.record.timeline("door-2", ("checkout",))
        table = first.data["worded"]
        assert first.title == "Lock and unlock cycle: passed"
        assert said(reworded(first.title, table), DE) == "Verriegeln und Entriegeln: bestanden"
        steps = first.data["steps"]
        assert steps[0]["name"] == "Door closed (asked)" and said(reworded(steps[0]["name"], table), DE) == "Tür geschlossen (gefragt)"
        question = steps[0]["answers"][0]["question"]
        assert said(reworded(question, table), DE) == "Ist die Tür geschlossen und steht niemand im Weg des Bolzens?"
        assert "Aufräumen ausgeführt" in [said(reworded(n, table), DE) for n in steps[-1]["notes"]]
        shown = [said(reworded(v["name"], table), DE) for s in steps for v in s["values"]]
        assert "Bolzen bei offener Tür und IrsAlways" in shown, shown
        worded = said(reworded(newest.data["reason"], newest.data["worded"]), DE)
        assert worded == "Ist die Tür geschlossen und steht niemand im Weg des Bolzens? - mit nein beantwortet von anna"

        content = await plant_content(runtime, read=False)
        german = plant_html(content, DE)
        assert english_in(german) == [], english_in(german)
        assert "Verriegeln und Entriegeln" in german and "Tür in Position, Näherungssensor" in german
        assert "mit nein beantwortet von anna" in german and "Ist die Tür geschlossen" in german
        assert "StateMachineState = 4 verriegelt" in german  # the lock's state named as its pages name it
        pdf = " ".join(" ".join(page.extract_text() for page in PdfReader(io.BytesIO(plant_pdf(content, DE))).pages).split())
        assert "Verriegeln und Entriegeln" in pdf and [m for m, pattern in checkout_patterns() if pattern.search(pdf)] == []
        english = plant_html(content, i18n.get("en"))
        assert english_in(english), "the English report is seen as English (the check of the German one sees)"
        assert "Is the door closed and is nobody in the way of the bolt? yes (anna)" in english


async def test_a_checkout_row_without_its_table_reads_as_written(tmp_path):
    async with demo_runtime(tmp_path, ("door-2",), online=False) as runtime:
        data = {"device": "door-2", "title": "Lock and unlock cycle", "status": "failed", "reason": "no LockStatus from the lock",
                "user": "anna", "role": "engineer", "started": 1.0, "ended": 2.0, "duration_s": 1.0, "settings": {},
                "steps": [{"name": "Lock", "limits": "", "status": "failed", "reason": "no LockStatus from the lock",
                           "values": [], "answers": [], "notes": [], "started": 1.0, "ended": 2.0, "evidence": {}}]}
        await runtime.record.add("door-2", "checkout", user="anna", role="engineer", data=data,
                                 title="Lock and unlock cycle: failed")
        german = plant_html(await plant_content(runtime, read=False), DE)
        assert "no LockStatus from the lock" in german and "Lock and unlock cycle" in german  # as written
        assert (await runtime.record.check()).ok


async def test_commission_checkout_says_a_runs_steps_and_reasons_in_german(tmp_path):
    out: list[str] = []
    cli_lang.set_language("de")
    try:
        async with demo_runtime(tmp_path, ("door-2",)) as runtime:  # nobody at the terminal: the first question fails
            assert await checkout_devices(runtime, ["door-2"], user="cli:anna", role="engineer", answer=None, out=out.append) == 1
            entry = (await runtime.record.timeline("door-2", ("checkout",)))[0]
    finally:
        cli_lang.set_language("en")
    reason = ("Ist die Tür geschlossen und steht niemand im Weg des Bolzens? - niemand zu fragen (die Standardeingabe ist kein "
              "Terminal: --answer ask oder --answer yes verwenden)")
    assert any("Verriegeln und Entriegeln" in line for line in out), out
    assert any(line.startswith("  [nicht bestanden] Tür geschlossen (gefragt) (") and line.endswith(f"s): {reason}") for line in out), out
    assert out[-1] == f"  door-2: nicht bestanden: {reason}", out
    assert entry.data["reason"].startswith("Is the door closed and is nobody in the way of the bolt? - nobody to ask")  # as stored
