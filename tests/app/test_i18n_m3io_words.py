"""The CAN-M3IO's own words in German (docs/i18n.md): the HMR's check of its three-phase output SSR1-3 (point
``SSR1-3 load check``, devices/m3io/adapter.py) and the states of its channels, as a checkout measures them, in the
words of the document (001, section 4.3: Drehstromausgang, Lastfehler; 7.2.3: Si, Triac) on the record page and in the
as-left report; the record keeps the English and the point its key."""

from __future__ import annotations

import re
from html import unescape

import pytest

from app import i18n
from app.message import Message, reworded, said
from app.report import measured_text, plant_content, plant_html
from devices.m3io.adapter import P_LOAD_CHECK
from devices.message import N_, Word
from tests.recordutil import demo_runtime, run_checkout

pytestmark = pytest.mark.timeout(120)

DE, EN = i18n.get("de"), i18n.get("en")
TAG = re.compile(r"<[^>]+>")


def test_the_load_checks_name_and_states_are_the_documents_words():
    assert P_LOAD_CHECK == "SSR1-3 load check"  # the point's key, as the API, MQTT and the record have it
    assert DE.phrase(P_LOAD_CHECK) == "SSR1-3 Lastfehlerprüfung"
    assert said(Message("{state}", state=Word("fault", P_LOAD_CHECK)), DE) == "Lastfehler"
    assert said(Message("{state}", state=Word("ok", P_LOAD_CHECK)), DE) == "ok"
    assert said(Message("{state}", state=Word("blown", "SSR2 Si")), DE) == "defekt"  # as the module's page words a fuse
    value = {
        "name": Message(N_("SSR1-3 load check")),
        "value": Message("{state}", state=Word("fault", P_LOAD_CHECK)),
        "unit": "",
        "limit": Message("= {expect}", expect=Message("{state}", state=Word("ok", P_LOAD_CHECK))),
        "ok": False,
    }
    assert measured_text(value, EN) == "SSR1-3 load check = fault (= ok: FAIL)"
    assert measured_text(value, DE) == "SSR1-3 Lastfehlerprüfung = Lastfehler (= ok: FEHLER)"


async def ask(question: str) -> bool:
    return not question.startswith("Is a test input wired")  # the loads yes, no test inputs wired


async def test_an_hmr_checkout_names_the_load_check_in_german_and_keeps_the_english(tmp_path):
    async with demo_runtime(tmp_path, ("heater-hmr",)) as runtime:
        await run_checkout(runtime, "heater-hmr", ask=ask)
        entry = (await runtime.record.timeline("heater-hmr", ("checkout",)))[0]
        content = await plant_content(runtime, read=False)
    values = [v for s in entry.data["steps"] for v in s["values"]]
    check = next(v for v in values if v["name"] == "SSR1-3 load check")  # stored as written, in English
    assert check["value"] == "ok" and check["limit"] == "= ok" and check["ok"], check
    table = entry.data["worded"]
    assert said(reworded(check["name"], table), DE) == "SSR1-3 Lastfehlerprüfung"
    assert measured_text(check, DE, {"worded": table}) == "SSR1-3 Lastfehlerprüfung = ok (= ok: ok)"
    german = unescape(TAG.sub("\n", plant_html(content, DE)))
    assert "SSR1-3 Lastfehlerprüfung = ok" in german and "load check" not in german
    english = unescape(TAG.sub("\n", plant_html(content, EN)))
    assert "SSR1-3 load check = ok (= ok: ok)" in english


def test_the_product_and_its_identity_in_the_documents_words():
    """7.2.4.2.2 (Produktcode: Gerät "HMR01 ab 08.11.2013"): the variant check and the identity the module reports, as
    the module's page shows them; the English as before."""
    from devices.m3io import codec

    assert codec.product_name(0x300A) == "HMR01 (from 08.11.2013)" and codec.product_name(0x1234) == "unknown product 0x1234"
    check = codec.check_variant(codec.Variant.HMR, True, 0x300A)
    assert check.text == "The module reports 0x300A HMR01 (from 08.11.2013): variant HMR as in the plant file."
    assert said(check.text, DE) == "Das Modul meldet 0x300A HMR01 ab 08.11.2013: Variante HMR wie in der Anlagendatei."
    DE.missing.clear()
    for code in codec.PRODUCT_CODES:
        said(Message("{product}", product=codec.product_name(code)), DE)
    assert not DE.missing, DE.missing


async def test_the_identity_read_from_the_module_is_worded_on_its_page(tmp_path):
    async with demo_runtime(tmp_path, ("heater-hmr",)) as runtime:
        await runtime.worker.adapters["heater-hmr"].read_identity()
        shown = runtime.store.devices["heater-hmr"].live("Identity").shown
    assert shown == (
        "serial 42120023 · product 0x300A HMR01 (from 08.11.2013) · software 18.1 (assumed decoding) · configuration 0x00"
    )
    assert said(shown, DE) == (
        "Seriennummer 42120023 · Produkt 0x300A HMR01 ab 08.11.2013 · Software 18.1 (angenommene "
        "Entschlüsselung) · Konfiguration 0x00"
    )
