"""The plant view and the login in German (issue 47), with NiceGUI's simulated user against twins on a real Modbus
RTU line: no text of the English catalog on the page, numbers and Quasar's components in German, and the
header's switch keeps a browser's language."""

from __future__ import annotations

import contextlib
import functools
import re
from html import unescape
from pathlib import Path

import pytest
from babel.messages.pofile import read_po
from nicegui import ui
from plants import modbus_plant
from webutil import eventually, simulated_user

from app import i18n
from app.message import Message
from app.runtime import Runtime
from app.users import UserStore

pytestmark = pytest.mark.timeout(60)

LOCALE = Path(__file__).resolve().parents[2] / "locale"
GERMAN = "de-DE,de;q=0.9,en;q=0.5"
TAG = re.compile(r"<[^>]+>")


@functools.cache
def english_patterns() -> list[tuple[str, re.Pattern]]:
    """Every English text of the catalog whose German differs, as a pattern of a whole shown text (a field
    ``{...}`` stands for anything); texts of 12 or more letters without fields are also looked for inside texts,
    but for a word of the device vocabulary (an entry with its context, ``NP_``): the parameter model's and the
    document's English descriptions use the same words ("strong magnet at the sensors")."""
    with open(LOCALE / "de" / "LC_MESSAGES" / "messages.po", "rb") as f:
        german = read_po(f)
    patterns = []
    for message in german:
        if not message.id or message.string == message.id:
            continue
        ids = message.id if isinstance(message.id, tuple) else (message.id,)  # a plural: each English form
        strings = message.string if isinstance(message.string, tuple) else (message.string,)
        for text in ids:
            if text in strings or not i18n.has_words(text):
                continue
            parts = re.split(r"\{[^{}]*\}", text.strip())
            whole = ".+?".join(re.escape(part) for part in parts)
            inside = len(parts) == 1 and len(text) >= 12 and not message.context
            patterns.append((text, re.compile(f".*{whole}.*" if inside else whole, re.S)))
    return patterns


def shown_texts(user, skip: tuple[str, ...] = ()) -> list[str]:
    """Every text the page shows or says: labels, HTML, buttons', inputs' and toggles' labels, tooltips, ARIA labels;
    none of the parts whose data-testid is in ``skip`` (and their contents)."""
    texts = []
    skipped = {id(d) for e in user.client.elements.values() if e.props.get("data-testid") in skip for d in [e, *e.descendants()]}
    for element in user.client.elements.values():
        if not element.visible or id(element) in skipped:
            continue
        for text in (getattr(element, "text", None), element.props.get("label"), element.props.get("aria-label"),
                     element.props.get("title")):
            if isinstance(text, str) and text.strip():
                texts.append(text.strip())
        content = getattr(element, "content", None)
        if isinstance(content, str) and content.strip():
            texts += [piece.strip() for piece in unescape(TAG.sub("\n", content)).split("\n") if piece.strip()]
    return texts


def english_on(user, skip: tuple[str, ...] = ()) -> list[tuple[str, str]]:
    patterns = english_patterns()
    texts = shown_texts(user, skip)
    header = [(text, "the catalog's header (gettext of an empty text)") for text in texts if "Project-Id-Version" in text]
    return header + [(text, message) for text in texts for message, pattern in patterns if pattern.fullmatch(text)]


@contextlib.asynccontextmanager
async def german_user(runtime: Runtime):
    async with simulated_user(runtime) as user:
        user.http_client.headers["Accept-Language"] = GERMAN
        yield user


@contextlib.asynccontextmanager
async def german_page(tmp_path, plant, device: str, title: str):
    """``device``'s page on ``plant`` (its twins simulated) for a German browser, once the device answers and its page
    shows ``title``: yields ``(runtime, user)``."""
    runtime = Runtime(plant, simulate=True, data_dir=tmp_path)
    async with german_user(runtime) as user:
        await eventually(lambda: runtime.store.devices[device].status == "online", timeout=15, what=f"{device} online")
        await user.open(f"/device/{device}")
        await user.should_see(title, retries=50)
        yield runtime, user


def lock_plant():
    return modbus_plant(locks=(("door-1", 1), ("door-2", 2)))


@contextlib.asynccontextmanager
async def german_locks(tmp_path, *online: str):
    """The two-lock plant with a German browser, once the ``online`` devices (every device: ``"*"``) answer."""
    runtime = Runtime(lock_plant(), simulate=True, data_dir=tmp_path)
    async with german_user(runtime) as user:
        names = list(runtime.store.devices) if online == ("*",) else list(online)
        if names:
            await eventually(lambda: all(runtime.store.devices[n].status == "online" for n in names), timeout=15,
                             what=" and ".join(names) + " online")
        yield runtime, user


def english_but(user, descriptions=frozenset(), skip=(), suffixed: bool = False) -> list[tuple[str, str]]:
    """The English texts on the page but the parameter model's own descriptions (devices/*/params.py, English; with
    ``suffixed`` also after a name, ``Name: description``); the simulation card is looked at too (its words are
    declared by devices/*/sim.py and shown in the catalogs' words by pages/simcontrols.py)."""
    return [(text, message) for text, message in english_on(user, skip=skip)
            if text not in descriptions and not (suffixed and any(text.endswith(f": {d}") for d in descriptions))]


def descriptions_of(runtime, device: str) -> set[str]:
    """The parameter model's own words a German page shows as they are: descriptions not in the catalogs (a marked one
    is a Message, shown in German) and the enum values German shows as the document prints them (the HD-Lock's
    MotorResult ``None``, section 3.1's names), which the check would otherwise take for the same word worded elsewhere
    (Parity's ``None``: ``keine``)."""
    de = i18n.get("de")
    params = runtime.store.devices[device].params.by_name.values()
    return ({p.description for p in params if not isinstance(p.description, Message)}
            | {v for p in params for v in (p.enum or {}).values() if de.value_word(p.name, v) == v})


async def test_the_plant_view_in_german_shows_no_english(tmp_path):
    async with german_locks(tmp_path, "*") as (runtime, user):
        await user.open("/plant")
        await user.should_see("Anlage plant", retries=50)
        await user.should_see("Tür geöffnet", retries=100)  # the twins' doors start open, bolt in
        await user.should_see("Bolzen eingefahren (entriegelt)")
        await user.should_see("Bolzen 0 % aus")
        assert user.client.page.resolve_language() == "de-DE"  # Quasar's own components in German too
        assert english_on(user) == []
        assert not i18n.get("de").missing, i18n.get("de").missing


async def test_the_login_in_german_shows_no_english(tmp_path):
    store = UserStore(tmp_path / "users.toml")
    store.add("anna", "engineer", "correct horse")
    runtime = Runtime(modbus_plant(locks=(("door-1", 1),)), simulate=True, data_dir=tmp_path, auth_required=True)
    async with german_user(runtime) as user:
        await user.open("/login")
        await user.should_see("Anmelden")
        await user.should_see("Anlage plant")
        assert english_on(user) == []
        user.find(kind=ui.input, content="Benutzer").type("anna")
        user.find(kind=ui.input, content="Passwort").type("wrong horse")
        user.find(kind=ui.button, content="Anmelden").click()
        await user.should_see("Falscher Benutzername oder falsches Passwort", retries=100)  # argon2 on a loaded machine
        assert english_on(user) == []
        user.find(kind=ui.input, content="Passwort").type("correct horse")
        user.find(kind=ui.button, content="Anmelden").click()
        await user.should_see("Übersicht", retries=100)  # the header's link, in German as the login


async def test_the_switch_keeps_the_browsers_language(tmp_path):
    async with german_locks(tmp_path) as (runtime, user):
        await user.open("/plant")
        await user.should_see("Anlage plant")
        links = {e.props.get("data-lang"): e for e in user.client.elements.values() if isinstance(e, ui.link) and e.props.get("data-lang")}
        assert set(links) == {"de", "en"} and links["de"].props.get("aria-current") == "true"
        assert links["en"].props["href"] == "?lang=en"  # the page itself in English: links, nothing to press
        await user.open("/plant?lang=en")  # the browser chooses English: kept in its storage, whatever it accepts
        await user.should_see("Plant plant")
        assert user.client.page.resolve_language() == "en-GB"
        assert english_on(user), "the English page is seen as English (the check of the German pages sees)"
        await user.open("/")
        await user.should_see("Plant view")  # every page's header follows the choice
        await user.open("/plant")
        await user.should_see("Plant plant")
        await user.open("/plant?lang=de")
        await user.should_see("Anlage plant")


async def test_a_device_page_in_german_has_its_frame_events_and_badge_in_german(tmp_path):
    """The parts every device page shares (pages/device_page.py, widgets, command client): status badge, the
    event log's title and columns, the disabled reasons of the write guard."""
    async with german_locks(tmp_path, "door-1") as (runtime, user):
        await user.open("/device/door-1")
        await user.should_see("Ereignisse", retries=100)
        await user.should_see("online", retries=100)
        shown = shown_texts(user)
        for english in ("Events", "Time", "Level", "Event", "waiting"):
            assert english not in shown, english
        events = next(e for e in user.client.elements.values() if isinstance(e, ui.table) and "events" in str(e.props))
        assert [c["label"] for c in events.columns] == ["Zeit", "Stufe", "Ereignis"]


async def test_the_overview_in_german_shows_no_english(tmp_path):
    async with german_locks(tmp_path, "*") as (runtime, user):
        await user.open("/")
        await user.should_see("Alle Geräte (2)", retries=50)
        await user.should_see("Tür geöffnet", retries=100)  # the tiles in the documents' words, as on the plant view
        await user.should_see("Busmonitor")
        await eventually(lambda: any("letzte Antwort" in t for t in shown_texts(user)), timeout=5, what="the counters' line")
        assert english_on(user) == []
        assert not i18n.get("de").missing, i18n.get("de").missing


async def test_the_backup_page_in_german_shows_no_english(tmp_path):
    async with german_locks(tmp_path, "*") as (runtime, user):
        await user.open("/backup")
        await user.should_see("Backup und Wiederherstellung", retries=50)
        await user.should_see("Backups im Ordner")
        user.find(content="Auswahl sichern").click()
        await user.should_see("2 Backup-Datei(en) geschrieben", retries=200)
        await eventually(lambda: any(t.endswith("door-1.json") or "door-1" in t for t in shown_texts(user)), timeout=5,
                         what="the files listed")
        assert english_on(user) == []
        files = next(e for e in user.client.elements.values() if isinstance(e, ui.table))
        assert [c["label"] for c in files.columns] == ["Datei", "Gerät", "Typ", "Erstellt (Ortszeit)", "Von", "Größe", ""]


async def test_a_project_in_german_shows_no_english(tmp_path):
    """The project card of the backup page, its comparison with the device and the reconciling buttons."""
    from test_project_page import plant_file

    from app.plant import load_plant

    runtime = Runtime(load_plant(plant_file(tmp_path)), simulate=True, data_dir=tmp_path / "data")
    async with german_user(runtime) as user:
        await eventually(lambda: runtime.store.devices["door-1"].status == "online", timeout=15, what="door-1 online")
        await user.open("/backup")
        await user.should_see("Projekt gegen die Geräte", retries=50)
        user.find(content="Projekt mit dem Gerät vergleichen").click()
        await user.should_see("door-1: 1 der 1 Projekteintrag weicht vom Gerät ab", retries=100)
        assert english_on(user) == []
        table = next(e for e in user.client.elements.values()
                     if isinstance(e, ui.table) and any(c["name"] == "state" for c in e.columns))
        assert [c["label"] for c in table.columns] == ["Parameter", "Projekt", "Gerät jetzt", "", "Abgleichen"]
        assert table.rows[0]["state_text"] == "weicht ab" and table.rows[0]["state"] == "differs"


async def test_the_audit_log_in_german_shows_no_english_but_its_records(tmp_path):
    async with german_locks(tmp_path) as (runtime, user):
        await user.open("/audit")
        await user.should_see("Audit-Log", retries=50)
        await user.should_see("Einträge", retries=50)
        assert english_on(user) == []
        table = next(e for e in user.client.elements.values() if isinstance(e, ui.table))
        assert [c["label"] for c in table.columns][:3] == ["Zeit", "Benutzer", "Rolle"]


async def test_the_fleet_page_in_german_shows_no_english(tmp_path):
    async with german_locks(tmp_path, "*") as (runtime, user):
        await user.open("/fleet")
        await user.should_see("Auf mehrere Geräte anwenden", retries=50)
        await user.should_see("Prüfen und vergleichen")
        assert english_on(user) == []
        source = next(e for e in user.client.elements.values() if e.props.get("data-testid") == "fleet-source")
        await eventually(lambda: source.options, timeout=5, what="the sources")
        assert "door-1, wie es jetzt ist (Geschwistergerät)" in source.options.values()


async def test_the_replacement_assistant_in_german_shows_no_english(tmp_path):
    async with german_locks(tmp_path, "door-1") as (runtime, user):
        await user.open("/replace/door-1")
        await user.should_see("door-1 austauschen", retries=50)
        await user.should_see("1. Identität")
        await user.should_see("Identität wie bekannt", retries=50)
        assert english_but(user) == []


async def test_the_project_editor_in_german_shows_no_english_but_the_parameters_own_words(tmp_path):
    """Parameter names are the documents' names and their descriptions are English in devices/*/params.py: the
    editor's own words are German."""
    async with german_locks(tmp_path) as (runtime, user):
        await user.open("/project/door-1")
        await user.should_see("Projekt von door-1", retries=50)
        await user.should_see("Projekt speichern")
        assert english_but(user, descriptions_of(runtime, "door-1"), skip=()) == []


async def test_the_plant_wide_view_in_german_shows_no_english(tmp_path):
    """``commission view``'s page (pages/site_view.py) on a store fed as the broker would feed it."""
    from test_faces_site_view import _good, _store

    from pages import site_view

    store = _store()
    _good(store)
    async with german_locks(tmp_path) as (runtime, user):
        ui.page("/site-view-de")(lambda: site_view.content(store))
        await user.open("/site-view-de")
        await user.should_see("Anlagenweite Ansicht", retries=50)
        await user.should_see("Standort hall")
        await user.should_see("Bolzen ausgefahren (verriegelt)")  # the plant view's words on the remote tile
        await user.should_see("Broker startet")  # not connected to any broker here
        assert english_on(user) == []
        assert not i18n.get("de").missing, i18n.get("de").missing


def mo64_descriptions(runtime, name: str) -> set[str]:
    """The parameter model's own English (devices/mo64/params.py): each description, also with its assumption."""
    from devices.mo64.params import PARAMS

    return {p.description for p in PARAMS} | {f"{p.description} Annahme: {p.assumed}" for p in PARAMS if p.assumed}


async def test_the_mo64_page_in_german_shows_no_english(tmp_path):
    """The barrier's page in the words of its document (003): Torzustand, Schrankenstatus, Fehlerspeicher, Pegel."""
    from plants import mo64_tcp, plant

    runtime = Runtime(plant(mo64_tcp()), simulate=True, data_dir=tmp_path)
    async with german_user(runtime) as user:
        await eventually(lambda: {"Gate state", "Serial number"} <= set(runtime.store.devices["gate"].points), timeout=15,
                         what="the barrier's first answers")
        await user.open("/device/gate")
        await user.should_see("Torzustand: Schranke ist geschlossen", retries=100)
        await user.should_see("Schrankenstatus (40 Bits, Kapitel 5.1.7)")
        await user.should_see("Seriennummer: 6400001", retries=50)
        await user.should_see("Schleife A belegt")
        await user.should_see("Fehlerspeicher (10 Ebenen, neueste zuerst, Kapitel 5.1.23)")
        await user.should_see("Ein Fahrzeug durchfahren lassen")  # the twin's card
        found = english_but(user, mo64_descriptions(runtime, "gate"))
        assert found == [], "\n".join(map(str, found))
        errors = next(e for e in user.client.elements.values() if e.props.get("data-testid") == "error-memory")
        assert [c["label"] for c in errors.columns] == ["Ebene", "Fehlerflaggen", "Roh (für den Hersteller)",
                                                        "Betriebsstunden bei der Änderung"]


async def test_the_m3io_page_in_german_shows_no_english(tmp_path):
    """The I/O module's page in the words of its document (001): Ausgänge, Last, Si, Triac, Drehstromausgang, Watchdog."""
    from plants import can_bus, m3io_can, plant

    runtime = Runtime(plant(can_bus(m3io_can("io", variant="HMR", sw1=0x9A), name="can3")), simulate=True, data_dir=tmp_path)
    async with german_user(runtime) as user:
        await user.open("/device/io")
        await user.should_see("CAN-M3IO io (HMR)", retries=50)
        await user.should_see("Digitale Eingänge")
        await user.should_see("Pt100-Temperaturen (0,1 °C)")
        await user.should_see("Drehstromausgang: ein Fehler an SSR1, SSR2 oder SSR3 schaltet alle drei ab.")
        await user.should_see("Adressierte Daten (SW1 Schalter 8 ein)")
        await eventually(lambda: any(t.startswith("Watchdog nicht bedient") for t in shown_texts(user)), timeout=5,
                         what="the watchdog's words")
        found = english_but(user)
        assert found == [], "\n".join(map(str, found))
        assert not i18n.get("de").missing, i18n.get("de").missing


async def test_the_electrak_page_in_german_shows_no_english(tmp_path):
    """The actuators' page in the words of their document (004): Bewegungs-Flags, Fehler-Flags, Steuertelegramm, Hub."""
    from plants import electrak_bus, plant

    async with german_page(tmp_path, plant(electrak_bus()), "lift", "Electrak-HD-Netzwerk lift") as (runtime, user):
        await user.should_see("Bewegungs-Flags")
        await user.should_see("Serviceparameter (0x0A / 0x0B)")
        await user.should_see("niemand steuert das Netzwerk: Steuertelegramme sind aus", retries=50)
        await eventually(lambda: any(t.startswith("gehörte Aktuatoren pro 100 ms: 2 von 2") for t in shown_texts(user)),
                         timeout=5, what="the actuators heard")
        found = english_but(user, descriptions_of(runtime, "lift"))
        assert found == [], "\n".join(map(str, found))


async def test_the_hdlock_page_in_german_shows_no_english_but_the_parameters_own_words(tmp_path):
    """The lock's page (document 000): its cards, the LockStatus and the states in German, register and bit names as the
    document prints them, descriptions the parameter model's."""
    async with german_locks(tmp_path, "door-1") as (runtime, user):
        await user.open("/device/door-1")
        await user.should_see("HD-Lock door-1", retries=50)
        await user.should_see("Parameter (RW-Holding-Register)")
        await user.should_see("Set Modbus Address an jedes Schloss von line1 (Broadcast 255)")
        await user.should_see("Tür geöffnet", retries=100)  # DoorState in the document's words
        tables = [e for e in user.client.elements.values() if isinstance(e, ui.table)]
        await eventually(lambda: any(r.get("name") == "DoorState" and r.get("value") == "Tür geöffnet (1)"
                                     for t in tables for r in t.rows), timeout=10,
                         what="DoorState in the register table as the tiles word it, with its number")
        await user.should_see("Simuliertes Schloss")  # the twin's card in the catalogs' words
        await user.should_see("Starker Magnet")
        found = english_but(user, descriptions_of(runtime, "door-1"), suffixed=True)
        assert found == [], "\n".join(map(str, found))
        assert not i18n.get("de").missing, i18n.get("de").missing  # nothing looked up that the catalog does not have


async def test_the_device_pages_in_german_word_what_the_adapters_say_in_the_documents_words(tmp_path):
    """What the adapters word themselves, in German on their pages: the MO 64's connection, polling and query form,
    the Electrak's control telegram line, the HD-Lock's MotorState."""
    from plants import electrak_bus, mo64_tcp, plant

    def shown(user, *pieces: str) -> bool:
        return any(all(piece in text for piece in pieces) for text in shown_texts(user))

    runtime = Runtime(plant(mo64_tcp()), simulate=True, data_dir=tmp_path / "mo64")
    async with german_user(runtime) as user:
        await eventually(lambda: "Gate state" in runtime.store.devices["gate"].points, timeout=15, what="the barrier")
        await user.open("/device/gate")
        await eventually(lambda: shown(user, ": verbunden", "in jedem Zyklus"), timeout=10,
                         what="the MO 64's connection and polling words")
        assert not shown(user, "every cycle") and not shown(user, "not known yet")
    async with german_page(tmp_path / "electrak", plant(electrak_bus()), "lift", "Electrak-HD-Netzwerk lift") as (runtime, user):
        await eventually(lambda: shown(user, "0x006: ", "(Ziel ", "keine Freigabe)"), timeout=10,
                         what="the control telegram's line")
        assert not shown(user, "(target ")
    async with german_locks(tmp_path / "locks", "door-1") as (runtime, user):
        await user.open("/device/door-1")
        await user.should_see("HD-Lock door-1", retries=50)
        await eventually(lambda: "inaktiv" in shown_texts(user), timeout=10, what="MotorState in the document's words")
        assert "Inactive" not in shown_texts(user)


async def test_the_scu_page_in_german_shows_no_english(tmp_path):
    """The control unit's page (document 002): Remote-Betrieb, NOT-HALT, Netz, Akku, the error codes of table 10; the
    status bits' words of table 6 and the data directory are the parameter model's."""
    from plants import plant, scu_line

    async with german_page(tmp_path, plant(scu_line()), "lift", "Ewellix SCU lift") as (runtime, user):
        await user.should_see("Versorgung und E/A")
        await user.should_see("NOT-HALT (F20, Funktion 19)")
        await eventually(lambda: any(t.startswith("Remote-Betrieb: ") for t in shown_texts(user)), timeout=5,
                         what="the remote session's words")
        await eventually(lambda: any(t.startswith("Strom: ") for t in shown_texts(user)), timeout=5,
                         what="an actuator's current in German")  # the status strip's "current: 0 A" was English
        assert not [t for t in shown_texts(user) if t.startswith(("current: ", "speed: "))]
        found = english_but(user, descriptions_of(runtime, "lift"))
        assert found == [], "\n".join(map(str, found))


async def test_the_scu_page_in_german_words_table_6_and_the_emergency_stop_in_the_documents_words(tmp_path):
    """The status bits of table 6 (Actuator Status 1, the I/O lines) and the emergency stop's details, worded by
    devices/scu, in German on the SCU page."""
    from plants import plant, scu_line

    from devices.scu.control import Estop

    async with german_page(tmp_path, plant(scu_line()), "lift", "Ewellix SCU lift") as (runtime, user):
        await eventually(lambda: "Antrieb vorhanden" in shown_texts(user), timeout=10, what="table 6's status words")
        await eventually(lambda: any(t.startswith("Binärausgänge: Ausgang 1 aus") for t in shown_texts(user)), timeout=10,
                         what="the outputs' line in table 6's words")
        adapter = runtime.worker.adapters["lift"]
        adapter.core.estop = Estop("anna", 0.0, confirmed=True)
        adapter.publish_estop()
        await eventually(lambda: any("EIN seit " in t and "ausgelöst von anna; von der Steuereinheit bestätigt" in t
                                     for t in shown_texts(user)), timeout=10, what="the emergency stop's details")
        texts = shown_texts(user)
        assert not [t for t in texts if "actuator present" in t.lower() or "pressed by" in t], texts


def as_written(text: str, written: set[str]) -> bool:
    """Whether ``text`` is one of the record's texts, alone or after the page's words (``nicht bestanden: <reason>``)."""
    return text in written or any(text.endswith(f": {w}") for w in written)


def record_texts(entries) -> set[str]:
    """What the record holds as it was written (English): the timeline titles of other rows than checkouts (a
    checkout's texts are worded in the page's language)."""
    return {e.title for e in entries if e.kind != "checkout" and e.title}


async def test_the_record_page_in_german_shows_no_english_but_what_the_record_holds(tmp_path):
    """The record page (pages/record.py): its cards, buttons, statuses, columns, the report's preview and the sign-off's
    questions in German; the checkout's title, steps, reasons and questions too, the other rows' titles as written."""
    from tests.recordutil import run_checkout

    async with german_locks(tmp_path, "door-1") as (runtime, user):
        await eventually(lambda: runtime.store.devices["door-1"].value("LockRequestDelay") is not None, timeout=15,
                         what="door-1's parameters")
        await run_checkout(runtime, "door-1", answer=False)  # "is the door closed?" no: failed, with its reason
        await runtime.record.approve("door-1", user="anna", role="engineer")
        await runtime.record.snapshot("door-1", user="anna", role="engineer")
        await user.open("/record/door-1")
        await user.should_see("Inbetriebnahmeprotokoll", retries=50)
        await user.should_see("Übergabebericht und Abzeichnung")
        await user.should_see("Gleich dem abgenommenen Satz.", retries=100)
        await user.should_see("nicht bestanden", retries=100)  # the last run's status
        await user.should_see("Funktionsprüfung: Verriegeln und Entriegeln")  # the run's title, steps and reason in German
        await user.should_see("Tür geschlossen (gefragt)")
        await user.should_see("Ist die Tür geschlossen und steht niemand im Weg des Bolzens? - mit nein beantwortet von anna")
        timeline = next(iter(user.find(marker="record-timeline").elements))
        await eventually(lambda: len(timeline.rows) == 3, timeout=5, what="the timeline's rows")
        assert [c["label"] for c in timeline.columns] == ["#", "Zeit", "Art", "Was", "Von"]
        assert {row["kind"] for row in timeline.rows} == {"Funktionsprüfung", "Abnahme", "Momentaufnahme"}
        user.find(marker="check-record").click()
        await user.should_see("unverändert", retries=100)
        written = record_texts(await runtime.record.timeline("door-1"))
        names = set(runtime.store.devices["door-1"].params.by_name)  # the register names, as the document prints them
        found = [(text, message) for text, message in english_on(user) if not as_written(text, written | names)]
        assert found == [], "\n".join(map(str, found))
        assert not i18n.get("de").missing, i18n.get("de").missing
        role = next(iter(user.find(marker="sign-role").elements))
        assert role.value == "Inbetriebnehmer"  # the signer's role offered in German (the record keeps what is signed)
        user.find(marker="sign-device").click()  # no name yet: said in German
        await user.should_see("eine Abzeichnung braucht einen Namen", retries=50)
        next(iter(user.find(marker="sign-name").elements)).value = "Anna Berg"
        user.find(marker="sign-device").click()  # what is open, asked first
        await user.should_see("door-1 abzeichnen, obwohl diese Punkte offen sind?", retries=100)
        await user.should_see("door-1: letzte ", retries=50)
        found = [(text, message) for text, message in english_on(user) if not as_written(text, written | names)]
        assert found == [], "\n".join(map(str, found))
        user.find(marker="gaps-cancel").click()


@contextlib.asynccontextmanager
async def german_demo(tmp_path, monkeypatch):
    """The demo plant (every bus kind: a Modbus line, CAN buses, an SCU's RS232 line, LogiTed lines) for a German browser."""
    from test_monitor import demo_plant

    from app import recording as rec
    from app.can_bus import CanBusState

    monkeypatch.setenv(rec.DIR_ENV, str(tmp_path / "recordings"))
    runtime = Runtime(demo_plant(), simulate=True, data_dir=tmp_path)
    try:
        async with german_user(runtime) as user:
            yield runtime, user
    finally:
        for state in runtime.store.buses.values():
            if isinstance(state, CanBusState):
                rec.stop_recording(state)


def marked_table(user, name: str) -> ui.table:
    return next(e for e in user.client.elements.values() if isinstance(e, ui.table) and e.props.get("data-monitor") == name)


async def test_the_line_monitors_in_german_show_no_english(tmp_path, monkeypatch):
    """The monitor of a Modbus line, an SCU's RS232 line and a LogiTed line (pages/monitor.py): filters, columns,
    counts; the transactions in the words of their device pages are the adapters' (still English)."""
    async with german_demo(tmp_path, monkeypatch) as (runtime, user):
        await user.open("/monitor/line1")
        await user.should_see("Busmonitor line1", retries=50)
        await user.should_see("Nur Fehler")
        await user.should_see("Modbus-Abfrage")
        table = marked_table(user, "transactions")
        await eventually(lambda: table.rows, timeout=15, what="the line's transactions")
        await eventually(lambda: any("Transaktionen gepuffert" in t for t in shown_texts(user)), timeout=5, what="the counts")
        assert [c["label"] for c in table.columns] == ["Zeit", "Gerät", "Anfrage", "Anfrage hex", "Antwort hex", "Dekodiert",
                                                       "RTT ms", "Fehler"]
        function = next(e for e in user.client.elements.values() if e.props.get("data-monitor") == "filter-function")
        assert function.options[3] == "03 Holding-Register lesen"
        found = english_on(user)
        assert found == [], "\n".join(map(str, found))
        for bus, filter_name, word in (("rs232-1", "filter-command", "RG Daten lesen"), ("gates-485", "filter-telegram", "Abfragen")):
            await user.open(f"/monitor/{bus}")
            await user.should_see(f"Busmonitor {bus}", retries=50)
            chosen = next(e for e in user.client.elements.values() if e.props.get("data-monitor") == filter_name)
            assert word in chosen.options.values(), chosen.options
            found = english_on(user)
            assert found == [], "\n".join(map(str, found))


def test_the_monitors_csv_is_in_the_language_of_its_page():
    """The transactions' CSV as German spreadsheets read it (app/csvfile.py): German headings, a semicolon between cells,
    the decimal comma; times ISO and the line's texts as written."""
    import csv
    import io

    from pages.monitor import transactions_csv

    row = {"date": "2026-11-24 10:00:00.000", "device": "door-1", "unit": 1, "function": "03 Holding-Register lesen",
           "request": "read holding 3000+9", "tx": "01 03", "rx": "01 03 12", "decoded": "a = -30", "rtt": "12.5", "error": ""}
    lines = list(csv.reader(io.StringIO(transactions_csv([row], i18n.get("de"))), delimiter=";"))
    assert lines[0] == ["Zeit", "Gerät", "Unit-ID", "Funktion", "Anfrage", "Anfrage hex", "Antwort hex", "dekodiert", "RTT ms",
                        "Fehler"]
    assert lines[1][0] == "2026-11-24 10:00:00.000" and lines[1][8] == "12,5" and lines[1][7] == "a = -30"
    english = list(csv.reader(io.StringIO(transactions_csv([row]))))
    assert english[0][8] == "rtt ms" and english[1][8] == "12.5"


async def test_the_can_monitor_in_german_shows_no_english(tmp_path, monkeypatch):
    """The monitor of a CAN bus (pages/can_monitor.py, can_trace.py, can_files.py): bus state, counters, load, filters,
    the overwrite view and the frame list, a frame's details, recording and a recorded file; the decoded texts are the
    codecs' (the documents' names of messages and fields)."""
    from test_monitor import SmallFileUpload

    from app import recording as rec

    async with german_demo(tmp_path, monkeypatch) as (runtime, user):
        await user.open("/monitor/can1")
        await user.should_see("Busmonitor can1", retries=50)
        await user.should_see("Überschreibansicht: eine Zeile pro ID")
        await user.should_see("fehleraktiv", retries=50)
        await user.should_see(kind=ui.label, content="Error-Frames 0")
        frames, overwrite = marked_table(user, "frames"), marked_table(user, "overwrite")
        await eventually(lambda: frames.rows and overwrite.rows, timeout=15, what="the bus's frames")
        assert [c["label"] for c in frames.columns] == ["Zeit", "Rtg.", "ID", "Gerät", "Δt ms", "DLC", "Daten", "Dekodiert"]
        assert [c["label"] for c in overwrite.columns] == ["ID", "Rtg.", "Gerät", "Anzahl", "Zyklus ms",
                                                           "Daten (geänderte Bytes markiert)", "Dekodiert", "Zuletzt"]
        await eventually(lambda: any(r["age"].endswith("her") or r["age"] == "gerade eben" for r in overwrite.rows),
                         timeout=5, what="the ages in German")
        found = english_on(user)
        assert found == [], "\n".join(map(str, found))
        user.find(marker="frames").trigger("rowClick", [None, frames.rows[0]])  # a frame's full decoding
        await user.should_see("Δt zum vorigen Frame dieser ID", retries=20)
        found = english_on(user)
        assert found == [], "\n".join(map(str, found))
        user.find(marker="record").click()
        await user.should_see(kind=ui.label, content="Aufzeichnung can1-", retries=50)
        state = runtime.store.buses["can1"]
        recording = rec.active_recording(state)
        await eventually(lambda: recording.frames >= 2, timeout=6, what="frames recorded")
        user.find(marker="stop").click()
        await eventually(lambda: rec.active_recording(state) is None and not recording.active, timeout=5)
        await user.should_see(f"{recording.frames} Frames in {recording.path.name} gespeichert", retries=50)
        upload = next(iter(user.find(marker="upload").elements))
        await upload.handle_uploads([SmallFileUpload(recording.path.name, "text/plain", recording.path.read_bytes())])
        await user.should_see(f"{recording.path.name} geöffnet", retries=50)
        await eventually(lambda: any("pro Seite" in t for t in shown_texts(user)), timeout=5, what="the file's line")
        found = english_on(user)
        assert found == [], "\n".join(map(str, found))



def by_testid(user, name: str) -> ui.element:
    return next(e for e in user.client.elements.values() if e.props.get("data-testid") == name)


async def test_the_modbus_poll_in_german_shows_no_english(tmp_path):
    """The Modbus poll of a line (pages/bus_poll.py): a window polling, its counts and table, the write card."""
    from nicegui.testing.user_interaction import UserInteraction

    async with german_locks(tmp_path, "door-1") as (runtime, user):
        await user.open("/monitor/line1/poll")
        await user.should_see("Modbus-Abfrage · line1", retries=50)
        await user.should_see("Fenster 1", retries=50)
        await user.should_see("Holding-Register oder Coils schreiben")
        UserInteraction(user, {by_testid(user, "poll-start")}, None).click()
        await eventually(lambda: "Abfragen · " in by_testid(user, "poll-status").text and "aktualisiert" in by_testid(user, "poll-status").text,
                         timeout=10, what="the window's answers")
        table = by_testid(user, "poll-table")
        await eventually(lambda: table.rows, timeout=5, what="the values")
        assert [c["label"] for c in table.columns][:6] == ["Adresse (ab 0)", "Bekanntes Register", "Ohne Vorzeichen",
                                                           "Mit Vorzeichen", "Hex", "Binär"]
        assert by_testid(user, "poll-summary").text.startswith("Unit-ID 1 · 03 Holding-Register lesen · 1000+10 · alle 1 s")
        found = english_on(user)
        assert found == [], "\n".join(map(str, found))


async def test_the_transmit_list_in_german_shows_no_english(tmp_path, monkeypatch):
    """The transmit list of a CAN bus (pages/bus_transmit.py): the raw and the named frame cards, the rows and their
    buttons, the device messages by name."""
    from nicegui.testing.user_interaction import UserInteraction

    async with german_demo(tmp_path, monkeypatch) as (runtime, user):
        await user.open("/monitor/can1/transmit")
        await user.should_see("Sendeliste · can1", retries=50)
        await user.should_see("Frame als Bytes")
        await user.should_see("Gerätebotschaft nach Namen")
        await user.should_see("Noch keine Zeilen: oben einen Frame hinzufügen.", retries=50)
        UserInteraction(user, {by_testid(user, "transmit-add")}, None).click()
        table = by_testid(user, "transmit-table")
        await eventually(lambda: table.rows, timeout=5, what="the row added")
        assert table.rows[0]["mode"] == "einmal"
        assert [c["label"] for c in table.columns][:6] == ["ID", "DLC", "Daten", "Botschaft", "Senden", "Gesendet"]
        assert 'label="Senden"' in table.slots["body-cell-actions"].template
        await user.should_see("gate-1 Register")  # a lock's request by name
        found = english_on(user)
        assert found == [], "\n".join(map(str, found))


async def test_the_replay_page_in_german_shows_no_english(tmp_path):
    """Replaying a recording (pages/bus_replay.py): the recording, speeds (decimal comma), start, the question and
    the outcome; what app/replay.py words itself (the question's body, the replay's summary) in German too."""
    from test_replay_page import replay_runtime

    runtime = replay_runtime(tmp_path, "replay-de")
    async with german_user(runtime) as user:
        await user.open("/monitor/can9/replay")
        await user.should_see("Wiedergabe auf can9", retries=50)
        await user.should_see("keine Datei geladen")
        speed = next(e for e in user.client.elements.values() if isinstance(e, ui.select) and e.props.get("label") == "Geschwindigkeit")
        assert speed.options[0.5] == "0,5 x" and speed.options[1.0] == "1 x (Original)"
        assert english_on(user) == []
        choice = next(e for e in user.client.elements.values() if e.props.get("label") == "Aufzeichnungen im Datenordner")
        choice.set_value("can9-test.log")
        await user.should_see("can9-test.log: 20 Frames", retries=50)
        user.find("Wiedergabe starten").click()
        await user.should_see("Auf can9 wiedergeben?", retries=50)
        await user.should_see("20 aufgezeichnete(n) Frame(s) von can9-test.log auf can9 wiedergeben (ein echter Bus: "
                              "reale Geräte empfangen sie), über 0,2 s bei 1 x.")
        found = english_on(user)
        assert found == [], "\n".join(map(str, found))
        user.find("20 Frames senden").click()
        status = by_testid(user, "replay-status")
        await eventually(lambda: "fertig: 20 von 20 Frames gesendet" in status.text, timeout=10, what="the replay's end")
        found = english_on(user)
        assert found == [], "\n".join(map(str, found))


async def test_the_discover_dialog_in_german_shows_no_english(tmp_path):
    """The address scan of an RS485 line (pages/discover.py, opened from the overview): its text, range, progress and
    the locks found."""
    async with german_locks(tmp_path, "*") as (runtime, user):
        await user.open("/")
        await user.should_see("Schlösser suchen", retries=50)
        user.find(kind=ui.button, content="Schlösser suchen").click()
        await user.should_see("Schlösser an line1 suchen", retries=20)
        to = next(e for e in user.client.elements.values() if isinstance(e, ui.number) and e.props.get("label") == "Bis")
        to.value = 2
        user.find(kind=ui.button, content="Starten").click()
        await user.should_see("2 Schlösser gefunden", retries=200)
        await user.should_see(kind=ui.label, content="in der Anlage als door-2")
        found = english_on(user)
        assert found == [], "\n".join(map(str, found))
async def test_the_record_page_in_german_says_why_a_checkout_does_not_start_and_a_login_refusal(tmp_path):
    """What app/ refuses (app/record.py, app/auth.py) said in the page's language: a checkout already running, and
    the account dialog's wrong password."""
    import asyncio

    asked, answered = asyncio.Event(), asyncio.Event()

    async def ask(question: str) -> bool:  # the first question waits until the test has pressed start
        asked.set()
        await answered.wait()
        return False

    UserStore(tmp_path / "users.toml").add("anna", "engineer", "correct horse")
    async with german_locks(tmp_path, "door-1") as (runtime, user):
        await user.open("/record/door-1")
        await user.should_see("Inbetriebnahmeprotokoll", retries=50)
        run = runtime.record.new_run("door-1", user="anna", role="engineer", ask=ask)  # from another tab, meanwhile
        task = asyncio.create_task(run.run())
        try:
            await eventually(asked.is_set, timeout=30, what="the checkout's first question")
            user.find(marker="checkout-run").click()
            await user.should_see("door-1: eine Funktionsprüfung läuft bereits", retries=50)
        finally:
            answered.set()
            await asyncio.wait_for(task, 30)
        assert not [m for m in user.notify.messages if "a checkout is running already" in m], user.notify.messages
        user.find(marker="record-approve").click()
        await user.should_see("Konto", retries=50)
        next(iter(user.find(marker="account-name").elements)).value = "anna"
        next(iter(user.find(marker="account-password").elements)).value = "wrong"
        user.find(marker="account-ok").click()
        await user.should_see("Falscher Benutzername oder falsches Passwort", retries=100)
        user.find(marker="account-cancel").click()


async def test_a_restore_in_german_says_its_warnings_and_summary_in_german(tmp_path):
    """What app/backup.py hands the backup page (a restore's warnings, its report's summary) in the page's language;
    the audit row keeps the English."""
    import json

    from test_backup_page import _wait_table, emit

    from app import backup
    from devices.hdlock.params import PARAMS
    from devices.params import backup_entry

    entries = [backup_entry(p, 250 if p.name == "LockRequestDelay" else p.default if p.default is not None else 0)
               for p in PARAMS]
    document = backup.make_document("other", "door-9", "hdlock", "line1", {}, entries)
    async with german_locks(tmp_path, "door-1") as (runtime, user):
        runtime.backups_dir.mkdir(parents=True, exist_ok=True)
        (runtime.backups_dir / "door-9.json").write_text(json.dumps(document))
        await user.open("/backup")
        files = next(t for t in user.client.elements.values() if isinstance(t, ui.table) and any(c["name"] == "by" for c in t.columns))
        await eventually(lambda: [r["name"] for r in files.rows] == ["door-9.json"], what="the file listed")
        emit(files, "restore", "door-9.json")
        await user.should_see("Mit dem Gerät vergleichen", retries=50)
        user.find(content="Mit dem Gerät vergleichen").click()
        table = await _wait_table(user)
        await user.should_see("das Backup stammt von Gerät 'door-9' der Anlage 'other'", retries=50)
        table.selected = [r for r in table.rows if r["name"] == "LockRequestDelay"]
        user.find(content="Auswahl schreiben").click()
        await user.should_see(marker="restore-confirm-ok", retries=50)
        user.find(marker="restore-confirm-ok").click()
        await user.should_see("1 geschrieben, ", retries=100)
        assert english_but(user, descriptions_of(runtime, "door-1")) == []
        rows = runtime.audit.query(device="door-1")
        assert any(r.action == "restore" and r.result.startswith("1 written, ") for r in rows), rows


async def test_the_gates_refusals_in_the_command_clients_notifications_in_german(tmp_path):
    """What the gate refuses reaches a page as the command client's notification (pages/command_client.py): the parameter
    model's refusal of a write and a command the device type does not declare, in the page's language."""
    from devices.commands import WRITE_PARAMETER
    from devices.hdlock.params import PARAMS
    from pages.command_client import run_command

    low, high = PARAMS.by_name["LockRequestDelay"].limits()
    async with german_locks(tmp_path) as (runtime, user):
        await user.open("/device/door-1")
        await user.should_see("HD-Lock door-1", retries=50)
        with user.client:
            assert await run_command("door-1", WRITE_PARAMETER, args={"param": "LockRequestDelay", "value": 70000}) == (False, None)
            assert await run_command("door-1", "fly") == (False, None)
        await user.should_see(f"write parameter: LockRequestDelay: 70000 liegt außerhalb von {low} .. {high} ms", retries=20)
        await user.should_see("fly: 'fly' ist kein Befehl von door-1", retries=20)
        assert not [m for m in user.notify.messages if "is outside" in m or "is not a command" in m], user.notify.messages


async def test_the_record_page_in_german_names_the_identity_from_the_catalog(tmp_path):
    """The record page's preview names the identity's keys from the catalog (Firmware-Version for FirmwareVersion)."""
    async with german_locks(tmp_path, "door-1") as (runtime, user):
        await eventually(lambda: runtime.store.devices["door-1"].value("FirmwareVersion") is not None, timeout=15,
                         what="door-1's identity")
        await user.open("/record/door-1")
        await user.should_see("Inbetriebnahmeprotokoll", retries=50)
        await eventually(lambda: "Firmware-Version" in shown_texts(user), timeout=10, what="the preview's identity")
        assert "Hardware-Version" in shown_texts(user)  # the listings below name the registers as the document prints them


async def test_the_record_page_in_german_says_a_twin_actions_answer(tmp_path):
    """The M3IO checkout asks to toggle an input; the twin's control offered with the question answers in German, and
    the audit row keeps the English."""
    import asyncio

    from tests.recordutil import demo_plant

    runtime = Runtime(demo_plant(("heater-hmr",)), simulate=True, data_dir=tmp_path / "data")
    async with german_user(runtime) as user:
        await eventually(lambda: runtime.store.devices["heater-hmr"].status == "online", timeout=15, what="the heater")
        await user.open("/record/heater-hmr")
        await user.should_see("Inbetriebnahmeprotokoll", retries=50)
        user.find(marker="checkout-run").click()
        for _ in range(300):  # the steps run (questions answered yes) until one asks a person to toggle an input
            runtime.worker.heartbeat(user.client.id)  # the page's browser is alive (the simulated user sends no beats)
            try:
                user.find(marker="checkout-twin-action")
                break
            except AssertionError:
                try:
                    user.find(marker="checkout-yes").click()
                except AssertionError:
                    pass
                await asyncio.sleep(0.1)
        user.find(marker="checkout-twin-action").click()
        await eventually(lambda: any(re.fullmatch(r"heater-hmr: Simulation: E\d umgeschaltet", m) for m in user.notify.messages),
                         timeout=10, what="the twin's answer in German")
        user.find(marker="checkout-no").click()
        await eventually(lambda: runtime.record.runs["heater-hmr"].status not in ("ready", "running"), timeout=30,
                         what="the run's end")
        audit = await runtime.audit.aquery(device="heater-hmr", text="simulation: toggle E")
        assert audit, "the audit row keeps the English"

