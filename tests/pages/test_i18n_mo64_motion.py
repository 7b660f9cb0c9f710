"""The MO 64's own motion questions in the page's language (issue 47): the declared risk of a motion and of releasing
an open level (devices/mo64/control.py), of clearing the levels (policy.py) and the adapter's own question when a
motion reaches it unconfirmed (adapter.py), in the words of the barrier's page (Baum, Öffnen-Pegel); nothing is sent
before the answer, and the question keeps its English where it is recorded."""

from __future__ import annotations

import pytest
from nicegui.testing.user_interaction import UserInteraction
from plants import mo64_tcp, plant
from test_i18n_pages import german_user
from webutil import by_testid, dialog_button, eventually

from app import i18n
from app.message import said
from app.runtime import Runtime
from devices.mo64 import codec
from devices.mo64.facts import NeedsConfirmation
from devices.mo64.policy import CLEAR_LEVELS_RISK

pytestmark = pytest.mark.timeout(60)

DE = i18n.get("de")
MOTION_DE = "Der Baum bewegt sich: prüfen, dass niemand darunter steht (der Bereich ist frei)."
OPEN_LEVEL_DE = ("Das Deaktivieren des Öffnen-Pegels lässt den Baum schließen (Seite 33): prüfen, dass niemand darunter "
                 "steht (der Bereich ist frei).")


async def test_the_adapters_own_motion_question_in_german(tmp_path):
    runtime = Runtime(plant(mo64_tcp()), simulate=True, data_dir=tmp_path)
    await runtime.start()
    try:
        adapter = runtime.worker.adapters["gate"]
        with pytest.raises(NeedsConfirmation) as asked:
            await adapter.command("browser-x", codec.Command.OPEN, codec.Function.PULSE)
        assert str(asked.value) == ("The boom moves: check that nobody stands under it (the area is clear). Confirm it for "
                                    "this command (each motion asks again).")
        assert said(asked.value, DE) == f"{MOTION_DE} Für diesen Befehl bestätigen (jede Bewegung fragt erneut)."
        with pytest.raises(NeedsConfirmation) as clearing:
            await adapter.clear_levels("browser-x")
        assert said(clearing.value, DE).startswith("das Löschen der Pegel kann den Baum bewegen")
        assert said(CLEAR_LEVELS_RISK, DE).startswith("Deaktiviert jeden Pegel, den dieses Programm in der Schranke gesetzt hat")
        assert runtime.twins["gate"].position_pct == 0  # nothing sent
    finally:
        await runtime.stop()


async def test_the_barriers_page_asks_its_motion_questions_in_german(tmp_path):
    runtime = Runtime(plant(mo64_tcp()), simulate=True, data_dir=tmp_path)
    async with german_user(runtime) as user:
        await eventually(lambda: "Gate state" in runtime.store.devices["gate"].points, timeout=15, what="the barrier's answer")
        await user.open("/device/gate")
        await user.should_see("Torzustand: Schranke ist geschlossen", retries=100)
        for testid, question in (("pulse-open", MOTION_DE), ("deactivate-open", OPEN_LEVEL_DE)):
            UserInteraction(user, {by_testid(user, testid)}, None).click()
            await user.should_see(question, retries=50)
            dialog_button(user, "Abbrechen").click()
            await user.should_not_see(question, retries=50)
        assert runtime.twins["gate"].position_pct == 0  # nothing sent: each question answered Abbrechen
        assert not [m for m in user.notify.messages if "boom" in m], user.notify.messages
        rows = [r for r in await runtime.audit.aquery(limit=20) if r.device == "gate"]
        assert rows and all("Baum" not in (r.result or "") for r in rows)  # the audit keeps the English
