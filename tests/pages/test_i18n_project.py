"""A project's own refusals (``ProjectError``, app/project.py) and what applying a project's row says, in the page's
language (issue 47): the device page's project card and the project editor word them in German; the refusal keeps its
English as the error's text (what the audit row holds)."""

from __future__ import annotations

import pytest
from nicegui import ui
from test_backup_page import emit
from test_i18n_pages import descriptions_of, english_but, german_user
from test_project_page import plant_file
from webutil import dialog_button, eventually, project_card_table

from app import i18n, project
from app.message import said
from app.plant import load_plant
from app.runtime import Runtime

pytestmark = pytest.mark.timeout(60)

DE = i18n.get("de")


def test_a_projects_refusals_keep_their_english_and_come_in_german(tmp_path):
    plant = load_plant(plant_file(tmp_path))
    with pytest.raises(project.ProjectError) as unknown:
        project.save(plant, "door-1", {"holding:9999": 1})
    assert str(unknown.value) == "'holding:9999' is not a writable parameter of door-1"
    assert said(unknown.value, DE) == "'holding:9999' ist kein beschreibbarer Parameter von door-1"
    project.save(plant, "door-1", {"holding:3000": 410})
    with pytest.raises(project.ProjectError) as moved:
        project.save(plant, "door-1", {"holding:3000": 420}, expected={"holding:3000": 350})
    assert str(moved.value) == ("the project of door-1 was changed meanwhile (LockRequestDelay is now 410): nothing saved; "
                                "reload the project and make the change again")
    assert said(moved.value, DE) == ("das Projekt von door-1 wurde inzwischen geändert (LockRequestDelay ist jetzt 410): "
                                     "nichts gespeichert; das Projekt neu laden und die Änderung erneut vornehmen")
    plant.path.write_text(plant.path.read_text().replace('name = "door-1"', 'name = "door-7"'))
    with pytest.raises(project.ProjectError) as gone:
        project.update_entry(plant, "door-1", "holding:3000", 200)
    assert said(gone.value, DE) == f"{plant.path} nennt das Gerät 'door-1' nicht mehr (inzwischen geändert): neu laden"


async def test_the_project_card_applies_and_refuses_in_german(tmp_path):
    """Apply project: its question and notification; Update project on a plant file changed meanwhile: the refusal."""
    path = plant_file(tmp_path)
    runtime = Runtime(load_plant(path), simulate=True, data_dir=tmp_path / "data")
    async with german_user(runtime) as user:
        await eventually(lambda: runtime.store.devices["door-1"].status == "online", timeout=15, what="door-1 online")
        await user.open("/device/door-1")
        await user.should_see("1 der 1 Projekteintrag weicht vom Gerät ab", retries=100)
        path.write_text(path.read_text().replace('name = "door-1"', 'name = "door-7"'))  # another editor renamed it
        emit(project_card_table(user), "update", "holding:3000")
        await user.should_see(f"Projekt nicht aktualisiert: {path} nennt das Gerät 'door-1' nicht mehr (inzwischen geändert): "
                              "neu laden", retries=50)
        path.write_text(path.read_text().replace('name = "door-7"', 'name = "door-1"'))
        emit(project_card_table(user), "apply", "holding:3000")
        await user.should_see("LockRequestDelay = 350 ms auf door-1 schreiben?", retries=50)
        dialog_button(user, "Schreiben").click()
        await user.should_see("Gerät und Projekt stimmen überein (1 Projekteintrag)", retries=100)
        notes = [m for m in user.notify.messages if m.startswith("LockRequestDelay: ")]
        assert notes == ["LockRequestDelay: 1 geschrieben, 0 unverändert, 0 fehlgeschlagen, 0 übersprungen; Save-Settings ausgeführt"]
        assert english_but(user, descriptions_of(runtime, "door-1"), suffixed=True) == []
        assert not [m for m in user.notify.messages if "changed meanwhile" in m or " written, " in m], user.notify.messages
        rows = await runtime.audit.aquery(limit=50)
        assert any(r.action == "restore" and r.result.startswith("1 written, ") for r in rows)  # the audit keeps the English


async def test_the_project_editor_says_a_save_changed_meanwhile_in_german(tmp_path):
    path = plant_file(tmp_path)
    runtime = Runtime(load_plant(path), simulate=True, data_dir=tmp_path / "data")
    async with german_user(runtime) as user:
        await user.open("/project/door-1")
        await user.should_see("Projekt speichern", retries=50)
        project.save(load_plant(path), "door-1", {"holding:3000": 410})  # another page saved meanwhile
        field = next(e for e in user.client.elements.values() if e.props.get("data-project-field") == "holding:3000")
        field.set_value("420")
        user.find(kind=ui.button, content="Projekt speichern").click()
        await user.should_see("Nicht gespeichert: das Projekt von door-1 wurde inzwischen geändert (LockRequestDelay ist jetzt "
                              "410): nichts gespeichert; das Projekt neu laden und die Änderung erneut vornehmen", retries=50)
        row = next(r for r in await runtime.audit.aquery(limit=20) if r.action == "edit project")
        assert "changed meanwhile" in row.result  # the audit keeps the English
