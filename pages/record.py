"""The commissioning record page: checkouts with progress and abort, the approved set and its
drift, the timeline with a diff of any two entries, sign-off, the as-left report downloads and the
check of the record (or of an archive) for alterations.

Every action goes through ``runtime.record`` (app/record.py), which checks the role: a viewer
reads the record and downloads reports, never runs a checkout, approves or signs. An approval and a
sign-off name an engineer account: a session without one (the loopback address) is asked to log in
at that moment.

The page's own words are in the catalogs (docs/i18n.md); a checkout's texts (its title, step names, reasons,
questions, measured names and values) in the page's language too: a run of this process carries its messages, a
stored one the table its record row keeps beside the English (``worded``, app/checkout.py). What else the record
holds (timeline titles of other rows, parameter names) is shown as it was written.
"""

from __future__ import annotations

import asyncio
import tempfile
from pathlib import Path

from nicegui import background_tasks, ui

from app import backup, i18n
from app import runtime as rt
from app.checkout import checkout_module
from app.i18n import N_, NP_, Lang
from app.record_cli import SIGNER_ROLE
from app.record_sets import diff_sets
from app.report import (
    appendix_html,
    device_content,
    device_html,
    plant_content,
    recorded,
    sign_gaps,
    signoff_of,
    with_unit,
)
from app.report_archive import write_plant
from app.message import Message, reworded, said
from app.verify import check_archive
from pages.command_client import VIEWER_REASON, enable_unless
from pages.frame import ACTION_ERRORS, fmt_time, frame
from pages.overview import drift_of
from pages.session import current_user
from pages.widgets import columns, follow, upload_button

STATUS_COLOUR = {"passed": "positive", "failed": "negative", "aborted": "negative", "running": "primary", "pending": "grey",
                 "skipped": "grey", "error": "negative"}
# the statuses of a run and of its steps (app/checkout.py) that app/report.py's WORDS leave out, shown in the page's language
STATUS_WORDS = (N_("ready"), N_("running"), N_("pending"), N_("error"))
# the kinds of record rows (app/record.py), shown in the timeline in the page's language
KIND = "record kind"
KIND_WORDS = (NP_("record kind", "approved"), NP_("record kind", "snapshot"), NP_("record kind", "checkout"),
              NP_("record kind", "signoff"), NP_("record kind", "integrity"))
TIMELINE_COLUMNS = [{"name": "id", "label": "#", "field": "id"},
                    {"name": "time", "label": N_("Time"), "field": "time", "align": "left"},
                    {"name": "kind", "label": N_("Kind"), "field": "kind", "align": "left"},
                    {"name": "title", "label": N_("What"), "field": "title", "align": "left"},
                    {"name": "user", "label": N_("By"), "field": "user", "align": "left"}]
DIFF_COLUMNS = [{"name": "name", "label": N_("Name"), "field": "name", "align": "left"},
                {"name": "old", "label": N_("Old"), "field": "old", "align": "left"},
                {"name": "new", "label": N_("New"), "field": "new", "align": "left"}]


def content(name: str | None = None) -> None:
    runtime = rt.current()
    devices = list(runtime.plant.devices)
    name = name if name in devices else (devices[0] if devices else None)
    user, role = current_user()
    engineer = role == "engineer"
    lang = i18n.page_language()
    _ = lang.gettext
    with frame(N_("Commissioning record")):
        with ui.row().classes("items-center gap-3 w-full"):
            ui.select(devices, value=name, label=_("Device"),
                      on_change=lambda e: ui.navigate.to(f"/record/{e.value}")).props("dense outlined").classes("w-56").mark("record-device")
            ui.space()
            _downloads(runtime, user, role, lang)
        if name is None:
            ui.label(_("The plant has no devices."))
            return
        state = runtime.store.devices[name]
        drift = ui.label().classes("text-body1").mark("record-drift")

        def show_drift() -> None:
            d = drift_of(state)
            if not d.get("approved"):
                drift.text, cls = _("No approved set for this device yet."), "text-grey-8"
            elif d["changed"]:
                drift.text = _("Changed since approved: {changes}").format(
                    changes=", ".join(f"{r['name']} {r['approved']} → {r['now']}" for r in d["changed"]))
                cls = "text-negative"
            else:
                drift.text, cls = _("Equal to the approved set."), "text-positive"
            drift.classes(replace=f"text-body1 {cls}")

        show_drift()
        watch = runtime.store.watch(name, show_drift, slow=True)
        ui.context.client.on_disconnect(watch.cancel)
        # side by side from 1024 px; one above the other on a tablet, where the timeline would hide its titles
        with ui.row().classes("w-full gap-4 items-start"):
            with ui.card().classes("flex-1 min-w-[360px]"):
                _checkout_card(runtime, name, user, role, engineer, lang)
            with ui.card().classes("flex-1 min-w-[360px]"):
                timeline = _timeline_card(runtime, name, user, role, engineer, lang)
        with ui.card().classes("w-full"):
            _signoff_card(runtime, name, user, role, engineer, timeline, lang)
        with ui.card().classes("w-full"):
            _check_card(runtime, lang)


def _downloads(runtime, user: str, role: str, lang: Lang) -> None:
    _ = lang.gettext
    # the report's language is chosen when it is made: the page's, or the other one for a reader who needs it
    language = ui.toggle({code: code.upper() for code in sorted(i18n.LANGUAGES)}, value=lang.code).props(
        "dense no-caps").tooltip(_("language of the report")).mark("record-report-language")

    async def download(kind: str) -> None:
        folder = Path(tempfile.mkdtemp(prefix="commission-report-"))
        try:
            paths = await write_plant(runtime, folder, user=user or "viewer", role=role, lang=i18n.get(language.value))
        except ACTION_ERRORS as exc:  # said to the engineer
            ui.notify(_("report: {error}").format(error=said(exc, lang)), type="negative", multi_line=True)
            return
        ui.download(paths[kind].read_bytes(), paths[kind].name)

    for kind, label in (("html", "HTML"), ("pdf", "PDF"), ("zip", _("Archive"))):
        ui.button(label, icon="download", on_click=lambda k=kind: download(k)).props("outline dense").mark(f"record-download-{kind}")


def _status_text(status: str, reason: str, lang: Lang) -> str:
    """A run's status in ``lang``, with its reason: ``failed: ...``."""
    return lang.gettext(status) + (f": {said(reason, lang)}" if reason else "")


def _checkout_card(runtime, name: str, user: str, role: str, engineer: bool, lang: Lang) -> None:
    _ = lang.gettext
    module = checkout_module(runtime.store.devices[name].type)
    ui.label(_("Checkout") + (f": {said(module.TITLE, lang)}" if module else "")).classes("text-h6")
    if module is None:
        ui.label(_("This device type declares no checkout yet.")).classes("text-grey-8")
        return
    progress = ui.linear_progress(value=0, show_value=False).classes("w-full")
    status = ui.label(_("Not run in this session.")).mark("checkout-status")
    steps = ui.column().classes("w-full gap-1")
    with ui.row():
        start = ui.button(_("Run checkout"), icon="play_arrow").mark("checkout-run")
        abort = ui.button(_("Abort"), icon="stop", color="negative").mark("checkout-abort")
    abort.set_visibility(False)
    if not engineer:
        start.disable()
        ui.label(_("Viewers read the record; checkouts are run by an engineer.")).classes("text-caption")

    def draw(run) -> None:
        progress.value = run.progress
        status.text = _status_text(run.status, run.as_dict()["reason"] if run.status in ("failed", "aborted") else "", lang)
        abort.set_visibility(run.status == "running")
        start.set_enabled(engineer and run.status != "running")
        steps.clear()
        with steps:
            for r in run.results:
                with ui.row().classes("items-center gap-2 no-wrap"):
                    ui.badge(_(r.status), color=STATUS_COLOUR.get(r.status, "grey"))
                    ui.label(said(r.name, lang)).classes("font-medium")
                    if r.reason:
                        ui.label(said(r.reason, lang)).classes("text-negative text-caption")
                    elif r.values:
                        ui.label("; ".join(f"{said(v['name'], lang)} {with_unit(recorded(v['value'], {}, lang), v['unit'], lang)}"
                                           for v in r.values[:3])).classes("text-caption")

    async def ask(question: str) -> bool:
        twin_action = _twin_action(runtime, name, question)
        with ui.dialog().props("persistent") as dialog, ui.card():
            ui.label(said(question, lang)).classes("text-body1")
            ui.label(_("Your answer is recorded with your name ({user}).").format(user=user)).classes("text-caption")
            if twin_action:  # a simulated device: its inputs are on the twin, offered here so one tab is enough
                async def act() -> None:
                    from app.record_cli import sim_action

                    try:
                        ui.notify(said(await sim_action(runtime, f"{name}:{twin_action}", user=user, role=role), lang), type="info")
                    except (*ACTION_ERRORS, ValueError) as exc:  # said (no such twin or action: a ValueError)
                        ui.notify(_("simulation: {error}").format(error=said(exc, lang)), type="negative")

                ui.button(_("Toggle {input} on the simulated device").format(input=twin_action.split()[1]), icon="smart_toy",
                          on_click=act).props("outline").mark("checkout-twin-action")
            with ui.row():
                ui.button(_("Yes"), on_click=lambda: dialog.submit(True)).mark("checkout-yes")
                ui.button(_("No"), color="negative", on_click=lambda: dialog.submit(False)).mark("checkout-no")
        try:
            return bool(await dialog)
        finally:
            dialog.delete()  # one question on the page at a time

    async def run_it() -> None:
        try:
            run = runtime.record.new_run(name, user=user, role=role, ask=ask, session=_session_id())
        except ACTION_ERRORS as exc:  # a checkout running already, a role
            ui.notify(said(exc, lang), type="negative")
            return
        run.listeners.append(lambda: draw(run))
        abort.on_click(lambda: run.abort(Message(N_("aborted by {user}"), user=user)))
        try:
            result = await run.run()
        except PermissionError as exc:
            ui.notify(said(exc, lang), type="negative")
            return
        ui.notify(_("checkout {status}").format(status=_status_text(result["status"], result["reason"], lang)),
                  type="positive" if result["status"] == "passed" else "negative", multi_line=True)

    start.on_click(run_it)
    last = runtime.record.runs.get(name)
    if last is not None:
        last.listeners.append(lambda: draw(last))
        draw(last)


async def ask_account(runtime, user: str, what: str, lang: Lang) -> str | None:
    """The engineer account that approves or signs: the session's own when it is one (logged in beyond
    the loopback address), else asked now with a login (throttled and audited as the login page's).
    None when the person cancels or no account could be checked (said). ``what``: the act, in ``lang``."""
    from app.auth import check_login
    from pages.session import client_address

    _ = lang.gettext
    known = runtime.users.users.get(user)
    if known is not None and known.role == "engineer":
        return known.name
    if not runtime.users.has_engineer():
        ui.notify(_("{what} needs a named engineer account and this installation has none yet: create one with "
                    "'commission user add NAME --role engineer', then try again").format(what=what), type="warning", multi_line=True)
        return None
    address = client_address() or "unknown address"
    with ui.dialog().props("persistent") as dialog, ui.card().classes("w-96").mark("account-dialog"):
        ui.label(_("{what}: who is it?").format(what=what)).classes("text-h6")
        ui.label(_("An approval and a sign-off name an engineer account: log in with yours. The record keeps the "
                   "account beside the name you type.")).classes("text-body2")
        name = ui.input(_("Account")).props("outlined autofocus maxlength=64").classes("w-full").mark("account-name")
        password = ui.input(_("Password"), password=True, password_toggle_button=True).props("outlined").classes("w-full").mark(
            "account-password")
        message = ui.label().classes("text-negative text-body2").mark("account-message")

        async def attempt() -> None:
            account, words = await check_login(throttle=runtime.login_throttle, users=runtime.users, audit=runtime.audit,
                                               typed=(name.value or "").strip(), secret=password.value or "", address=address,
                                               via="record page")
            if account is None:
                message.set_text(said(words, lang))  # the login's words (app/auth.py), as the login page says them
                password.set_value("")
                return
            if account.role != "engineer":
                message.set_text(_("{name} has the {role} role: an engineer account approves and signs").format(
                    name=account.name, role=_(account.role)))
                return
            dialog.submit(account.name)

        password.on("keydown.enter", attempt)
        with ui.row():
            ui.button(_("Log in and continue"), icon="login", on_click=attempt).mark("account-ok")
            ui.button(_("Cancel"), on_click=lambda: dialog.submit(None)).props("flat").mark("account-cancel")
    try:
        return await dialog
    finally:
        dialog.delete()  # asked again next time, with empty fields


async def confirm_gaps(gaps: list[str], what: str, lang: Lang) -> bool:
    """Before a sign-off: the devices without a checkout, with a failed one or with settings not approved
    (``gaps`` and ``what`` in ``lang``)."""
    if not gaps:
        return True
    _ = lang.gettext
    with ui.dialog().props("persistent") as dialog, ui.card().mark("gaps-dialog"):
        ui.label(_("Sign {what} although these are open?").format(what=what)).classes("text-h6")
        with ui.column().classes("gap-0"):
            for line in gaps:
                ui.label(line).classes("text-body2")
        ui.label(_("The list is kept in the signed report. Run the missing checkouts and approve the sets first, "
                   "or sign anyway.")).classes("text-caption")
        with ui.row():
            ui.button(_("Sign anyway"), color="negative", on_click=lambda: dialog.submit(True)).mark("gaps-sign")
            ui.button(_("Cancel"), on_click=lambda: dialog.submit(False)).props("flat").mark("gaps-cancel")
    try:
        return bool(await dialog)
    finally:
        dialog.delete()


def _twin_action(runtime, device: str, question: str) -> str:
    """The twin's declared control a question asks a person to do ("Toggle E1 now ..." -> "toggle E1"),
    where the device is simulated; "" otherwise."""
    controls = runtime.sim_controls(device) if device in runtime.store.devices else None
    words = question.split()
    if controls is None or len(words) < 2 or words[0] != "Toggle":
        return ""
    action = f"toggle {words[1]}"
    return action if any(a.name == action for a in controls.actions) else ""


def _session_id() -> str:
    """The page's session, which confirms it is alive: what the checkout switches on or drives is
    under the dead-man rule of this page (as on the device pages)."""
    return ui.context.client.id


def _timeline_card(runtime, name: str, user: str, role: str, engineer: bool, lang: Lang):
    _ = lang.gettext
    ui.label(_("Timeline")).classes("text-h6")
    with ui.row():
        approve = ui.button(_("Approve current set"), icon="verified").props("outline dense").mark("record-approve")
        snap = ui.button(_("Snapshot now"), icon="photo_camera").props("outline dense").mark("record-snapshot")
    no_set = "" if backup.device_backs_up(runtime, name) else _("{name} has no parameter set to approve or keep").format(name=name)
    for b in (approve, snap):
        enable_unless(b, _(VIEWER_REASON) if not engineer else no_set)

    async def why_no_set() -> None:  # the adapter's own words (e.g. an M3IO in simple mode keeps no records)
        why = said(await backup.why_nothing_to_back_up(runtime, name), lang).removeprefix("nothing to back up: ")
        if why and engineer:
            for b in (approve, snap):
                enable_unless(b, _("{name} has no parameter set to approve or keep: {why}").format(name=name, why=why))

    if no_set:
        ui.timer(0, why_no_set, once=True)
    table = ui.table(columns=columns(TIMELINE_COLUMNS, lang), rows=[], row_key="id", selection="multiple",
                     pagination=8).props("dense flat").classes("w-full").mark("record-timeline")
    diff_box = ui.column().classes("w-full").mark("record-diff")

    async def refresh() -> None:
        entries = await runtime.record.timeline(name)
        table.rows = [{"id": e.id, "time": fmt_time(e.time, lang), "kind": lang.pgettext(KIND, e.kind),
                       "title": said(reworded(e.title, e.data.get("worded")), lang), "user": e.user} for e in entries]
        table.update()

    async def show_diff() -> None:
        diff_box.clear()
        chosen = sorted(r["id"] for r in table.selected)
        if len(chosen) != 2:
            return
        a, b = [await runtime.record.get(i) for i in chosen]
        sets = []
        for e in (a, b):
            params = e.data.get("parameters")
            if params is None and e.kind == "checkout":
                params = {f"{s['name']}/{v['name']}": {"name": f"{recorded(s['name'], e.data, lang)}: {recorded(v['name'], e.data, lang)}",
                                                       "raw": v["value"], "text": f"{recorded(v['value'], e.data, lang)} {v['unit']}".strip()}
                          for s in e.data["steps"] for v in s["values"]}
            sets.append(params or {})
        rows = diff_sets(*sets)
        with diff_box:
            ui.label(_("#{a} {a_kind} → #{b} {b_kind}: {n} difference(s)").format(
                a=a.id, a_kind=lang.pgettext(KIND, a.kind), b=b.id, b_kind=lang.pgettext(KIND, b.kind), n=len(rows))).classes("font-medium")
            if rows:
                ui.table(columns=columns(DIFF_COLUMNS, lang), rows=rows, row_key="name").props("dense flat").classes("w-full")

    table.on("selection", lambda _e: show_diff())

    async def act(what: str) -> None:
        try:
            if what == "approve":
                account = await ask_account(runtime, user, _("Approving the set of {name}").format(name=name), lang)
                if account is None:
                    return
                await runtime.record.approve(name, user=user, role=role, account=account)
                ui.notify(_("approved set stored (account {account})").format(account=account), type="positive")
            else:
                await runtime.record.snapshot(name, user=user, role=role)
                ui.notify(_("snapshot stored"), type="positive")
        except ACTION_ERRORS as exc:  # said to the engineer
            ui.notify(_("{action}: {error}").format(action=_(ACTIONS[what]), error=said(exc, lang)), type="negative", multi_line=True)
        await refresh()

    approve.on_click(lambda: act("approve"))
    snap.on_click(lambda: act("snapshot"))
    ui.timer(0.1, refresh, once=True)
    shown = {"rows": runtime.record.rows_added.get(name, 0)}

    def follow_record() -> None:  # a checkout run here or elsewhere, an automatic snapshot: the new row shows up
        rows = runtime.record.rows_added.get(name, 0)
        if rows != shown["rows"]:
            shown["rows"] = rows
            background_tasks.create(refresh(), name=f"record timeline {name}")

    follow(runtime.store.devices[name], follow_record)  # on every change of the device, and once a second
    return refresh


ACTIONS = {"approve": N_("approve"), "snapshot": N_("snapshot")}  # the timeline's actions, named in a refusal


def _small_headings(text: str) -> str:
    """The report's headings at the size of the page's cards (Quasar styles h2/h3 as display titles)."""
    for tag, cls in (("h2", "text-h6"), ("h3", "text-subtitle1 text-weight-medium")):
        text = text.replace(f"<{tag}", f"<div class='{cls}'").replace(f"</{tag}>", "</div>")
    return text


PREVIEW_CSS = """
.record-preview table{border-collapse:collapse;font-size:12px;margin:4px 0 12px}
.record-preview td,.record-preview th{border:1px solid #ccc;padding:2px 8px;text-align:left;vertical-align:top}
.record-preview th{background:#f3f3f3;font-weight:500}.record-preview td:last-child{white-space:nowrap}
.record-preview p{margin:4px 0 8px}.record-preview .text-subtitle1{margin-top:12px}
.record-preview .sig{border:2px solid #1b5e20;padding:6px 8px;margin:6px 0}.record-preview .unsigned{border-color:#b71c1c}
.record-preview .equal,.record-preview .passed{color:#1b5e20}.record-preview .changed,.record-preview .failed,.record-preview .aborted{color:#b71c1c;font-weight:600}
.record-preview .notapproved,.record-preview .skipped{color:#8d6e00}
.record-preview .sim{background:#fff3cd;border:2px solid #8d6e00;color:#5d4200;padding:4px 8px;font-weight:600;margin:6px 0}
"""


def _signoff_card(runtime, name: str, user: str, role: str, engineer: bool, refresh_timeline, lang: Lang) -> None:
    _ = lang.gettext  # the preview speaks the page's language too
    ui.label(_("As-left report and sign-off")).classes("text-h6")
    # in the head of the page: the preview's HTML is sanitized, which drops a <style> of its own (its
    # tables and labels then ran together: "addressaddress 1")
    ui.add_css(PREVIEW_CSS)
    preview = ui.html("").classes("w-full").mark("record-report")
    with ui.expansion(_("Full listings: settings, live values, every step with its evidence file, audit rows")).classes(
            "w-full").mark("record-listings"):
        listings = ui.html("").classes("w-full")
    with ui.row().classes("items-end gap-3 w-full"):
        signer = ui.input(_("Name"), value=user if user != "local" else "").props("dense outlined").mark("sign-name")
        # offered in the page's language (as the command line's default in its own); the record keeps what is signed
        signer_role = ui.input(_("Role"), value=_(SIGNER_ROLE)).props("dense outlined").mark("sign-role")
        comment = ui.input(_("Comment")).props("dense outlined").classes("flex-1").mark("sign-comment")
    plant_words = _("plant {plant}").format(plant=runtime.plant.name)
    with ui.row():
        sign_device = ui.button(_("Sign {what}").format(what=name), icon="draw").mark("sign-device")
        sign_plant = ui.button(_("Sign {what}").format(what=plant_words), icon="draw").props("outline").mark("sign-plant")
    for b in (sign_device, sign_plant):
        b.set_enabled(engineer)

    async def show() -> None:
        content = await device_content(runtime, name, read=False)
        plant = await runtime.record.store.run(runtime.record.store.latest, runtime.record.plant, "", "signoff")
        preview.content = "<div class='record-preview'>" + _small_headings(
            device_html(content, signoff_of(plant), appendix=False, lang=lang)) + "</div>"
        listings.content = "<div class='record-preview'>" + _small_headings(appendix_html(content, lang)) + "</div>"

    async def sign(plant: bool) -> None:
        if not signer.value.strip():
            ui.notify(_("a sign-off needs a name"), type="warning")
            return
        what = plant_words if plant else name
        try:
            content = await (plant_content(runtime, user=user, role=role) if plant else device_content(runtime, name, user=user, role=role))
        except ACTION_ERRORS as exc:  # said to the engineer
            ui.notify(_("sign-off: the report could not be made: {error}").format(error=said(exc, lang)), type="negative",
                      multi_line=True)
            return
        if not await confirm_gaps(sign_gaps(content, lang), what, lang):
            return
        account = await ask_account(runtime, user, _("Signing {what}").format(what=what), lang)
        if account is None:
            return
        try:
            await runtime.record.sign("" if plant else name, user=user, role=role, name=signer.value.strip(),
                                      signer_role=signer_role.value.strip(), comment=comment.value, content=content,
                                      account=account)
        except ACTION_ERRORS as exc:  # said to the engineer
            ui.notify(_("sign-off: not signed: {error}").format(error=said(exc, lang)), type="negative", multi_line=True)
            return
        ui.notify(_("signed by {name} with account {account}: the record is frozen; a later sign-off supersedes it").format(
            name=signer.value.strip(), account=account), type="positive")
        await show()
        await refresh_timeline()

    sign_device.on_click(lambda: sign(False))
    sign_plant.on_click(lambda: sign(True))
    ui.timer(0.2, show, once=True)
    # checkouts, approvals, snapshots and sign-offs of this page or another one show up: the report is made again when
    # the record gained a row for this device or the plant (looked at once a second, a dict lookup), and once a minute
    # for what it reads besides (a replaced device's identity), not every 5 s whatever happened
    added = runtime.record.rows_added
    seen = {"rows": (added.get(name, 0), added.get("", 0))}

    def follow_report() -> None:
        rows = (added.get(name, 0), added.get("", 0))
        if rows != seen["rows"]:
            seen["rows"] = rows
            background_tasks.create(show(), name=f"record report {name}")

    ui.timer(1.0, follow_report)
    ui.timer(60.0, show)


def _check_card(runtime, lang: Lang) -> None:
    """Whether the record (or an as-left archive someone hands over) was altered: the chain of row
    hashes, the sign-offs, every file against the archive's manifest (app/verify.py)."""
    _ = lang.gettext
    ui.label(_("Check for alterations")).classes("text-h6")
    ui.label(_("Every record row carries the hash of the row before it; an archive carries the chain and a manifest of "
               "every file's SHA-256. The same check runs as 'commission verify ARCHIVE'.")).classes("text-body2 text-grey-8")
    result = ui.column().classes("w-full gap-0").mark("check-result")

    def show(check) -> None:
        result.clear()
        with result:
            ui.label(said(check.summary(), lang)).classes("text-body1 " + ("text-positive" if check.ok else "text-negative text-weight-bold"))
            for line in [said(p, lang) for p in check.problems[1:]] + [_("note: {note}").format(note=said(n, lang)) for n in check.notes]:
                ui.label(line).classes("text-body2")

    async def check_record() -> None:
        show(await runtime.record.check())

    async def uploaded(event) -> None:
        data = await event.file.read()
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / Path(event.file.name).name
            path.write_bytes(data)
            show(await asyncio.to_thread(check_archive, path))
        upload.reset()

    with ui.row().classes("items-center gap-3"):
        ui.button(_("Check the record"), icon="fact_check", on_click=check_record).props("outline").mark("check-record")
        upload = ui.upload(auto_upload=True, max_file_size=500_000_000, on_upload=uploaded).props(
            "accept=.zip flat bordered hide-upload-btn").classes("w-72").mark("check-archive")
        upload.add_slot("header", upload_button(_("Check an archive (.zip)"), "check-archive-upload"))
