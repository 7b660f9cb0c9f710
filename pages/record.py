"""The commissioning record page: checkouts with progress and abort, the approved set and its
drift, the timeline with a diff of any two entries, sign-off, the as-left report downloads and the
check of the record (or of an archive) for alterations.

Every action goes through ``runtime.record`` (app/record.py), which checks the role: a viewer
reads the record and downloads reports, never runs a checkout, approves or signs. An approval and a
sign-off name an engineer account: a session without one (the loopback address) is asked to log in
at that moment.
"""

from __future__ import annotations

import asyncio
import tempfile
from pathlib import Path

from nicegui import ui

from app import backup, i18n
from app import runtime as rt
from app.checkout import checkout_module
from app.record_sets import diff_sets
from app.report import (
    appendix_html,
    device_content,
    device_html,
    plant_content,
    sign_gaps,
    signoff_of,
    with_unit,
)
from app.report_archive import write_plant
from app.verify import check_archive
from pages.command_client import VIEWER_REASON, enable_unless
from pages.frame import ACTION_ERRORS, fmt_time, frame
from pages.overview import drift_of
from pages.session import current_user
from pages.widgets import upload_button

STATUS_COLOUR = {"passed": "positive", "failed": "negative", "aborted": "negative", "running": "primary", "pending": "grey",
                 "skipped": "grey", "error": "negative"}


def content(name: str | None = None) -> None:
    runtime = rt.current()
    devices = list(runtime.plant.devices)
    name = name if name in devices else (devices[0] if devices else None)
    user, role = current_user()
    engineer = role == "engineer"
    with frame("Commissioning record"):
        with ui.row().classes("items-center gap-3 w-full"):
            ui.select(devices, value=name, label="Device",
                      on_change=lambda e: ui.navigate.to(f"/record/{e.value}")).props("dense outlined").classes("w-56").mark("record-device")
            ui.space()
            _downloads(runtime, user, role)
        if name is None:
            ui.label("The plant has no devices.")
            return
        state = runtime.store.devices[name]
        drift = ui.label().classes("text-body1").mark("record-drift")

        def show_drift() -> None:
            d = drift_of(state)
            if not d.get("approved"):
                drift.text, cls = "No approved set for this device yet.", "text-grey-8"
            elif d["changed"]:
                drift.text = "Changed since approved: " + ", ".join(f"{r['name']} {r['approved']} → {r['now']}" for r in d["changed"])
                cls = "text-negative"
            else:
                drift.text, cls = "Equal to the approved set.", "text-positive"
            drift.classes(replace=f"text-body1 {cls}")

        show_drift()
        watch = runtime.store.watch(name, show_drift, slow=True)
        ui.context.client.on_disconnect(watch.cancel)
        with ui.row().classes("w-full gap-4 items-start"):
            with ui.card().classes("flex-1 min-w-[320px]"):
                _checkout_card(runtime, name, user, role, engineer)
            with ui.card().classes("flex-1 min-w-[320px]"):
                timeline = _timeline_card(runtime, name, user, role, engineer)
        with ui.card().classes("w-full"):
            _signoff_card(runtime, name, user, role, engineer, timeline)
        with ui.card().classes("w-full"):
            _check_card(runtime)


def _downloads(runtime, user: str, role: str) -> None:
    # the report's language is chosen when it is made: the page's, or the other one for a reader who needs it
    language = ui.toggle({code: code.upper() for code in sorted(i18n.LANGUAGES)}, value=i18n.page_language().code).props(
        "dense no-caps").tooltip("language of the report").mark("record-report-language")

    async def download(kind: str) -> None:
        folder = Path(tempfile.mkdtemp(prefix="commission-report-"))
        try:
            paths = await write_plant(runtime, folder, user=user or "viewer", role=role, lang=i18n.get(language.value))
        except ACTION_ERRORS as exc:  # said to the engineer
            ui.notify(f"report: {exc}", type="negative", multi_line=True)
            return
        ui.download(paths[kind].read_bytes(), paths[kind].name)

    for kind, label in (("html", "HTML"), ("pdf", "PDF"), ("zip", "Archive")):
        ui.button(label, icon="download", on_click=lambda k=kind: download(k)).props("outline dense").mark(f"record-download-{kind}")


def _checkout_card(runtime, name: str, user: str, role: str, engineer: bool) -> None:
    module = checkout_module(runtime.store.devices[name].type)
    ui.label("Checkout" + (f": {module.TITLE}" if module else "")).classes("text-h6")
    if module is None:
        ui.label("This device type declares no checkout yet.").classes("text-grey-8")
        return
    progress = ui.linear_progress(value=0, show_value=False).classes("w-full")
    status = ui.label("Not run in this session.").mark("checkout-status")
    steps = ui.column().classes("w-full gap-1")
    with ui.row():
        start = ui.button("Run checkout", icon="play_arrow").mark("checkout-run")
        abort = ui.button("Abort", icon="stop", color="negative").mark("checkout-abort")
    abort.set_visibility(False)
    if not engineer:
        start.disable()
        ui.label("Viewers read the record; checkouts are run by an engineer.").classes("text-caption")

    def draw(run) -> None:
        progress.value = run.progress
        status.text = f"{run.status}" + (f": {run.as_dict()['reason']}" if run.status in ("failed", "aborted") else "")
        abort.set_visibility(run.status == "running")
        start.set_enabled(engineer and run.status != "running")
        steps.clear()
        with steps:
            for r in run.results:
                with ui.row().classes("items-center gap-2 no-wrap"):
                    ui.badge(r.status, color=STATUS_COLOUR.get(r.status, "grey"))
                    ui.label(r.name).classes("font-medium")
                    if r.reason:
                        ui.label(r.reason).classes("text-negative text-caption")
                    elif r.values:
                        ui.label("; ".join(f"{v['name']} {with_unit(v['value'], v['unit'])}" for v in r.values[:3])).classes("text-caption")

    async def ask(question: str) -> bool:
        twin_action = _twin_action(runtime, name, question)
        with ui.dialog().props("persistent") as dialog, ui.card():
            ui.label(question).classes("text-body1")
            ui.label(f"Your answer is recorded with your name ({user}).").classes("text-caption")
            if twin_action:  # a simulated device: its inputs are on the twin, offered here so one tab is enough
                async def act() -> None:
                    from app.record_cli import sim_action

                    try:
                        ui.notify(await sim_action(runtime, f"{name}:{twin_action}", user=user, role=role), type="info")
                    except (*ACTION_ERRORS, ValueError) as exc:  # said (no such twin or action: a ValueError)
                        ui.notify(f"simulation: {exc}", type="negative")

                ui.button(f"{twin_action.capitalize()} on the simulated device", icon="smart_toy",
                          on_click=act).props("outline").mark("checkout-twin-action")
            with ui.row():
                ui.button("Yes", on_click=lambda: dialog.submit(True)).mark("checkout-yes")
                ui.button("No", color="negative", on_click=lambda: dialog.submit(False)).mark("checkout-no")
        try:
            return bool(await dialog)
        finally:
            dialog.delete()  # one question on the page at a time

    async def run_it() -> None:
        try:
            run = runtime.record.new_run(name, user=user, role=role, ask=ask, session=_session_id())
        except ACTION_ERRORS as exc:  # a checkout running already, a role
            ui.notify(str(exc), type="negative")
            return
        run.listeners.append(lambda: draw(run))
        abort.on_click(lambda: run.abort(f"aborted by {user}"))
        try:
            result = await run.run()
        except PermissionError as exc:
            ui.notify(str(exc), type="negative")
            return
        ui.notify(f"checkout {result['status']}" + (f": {result['reason']}" if result["reason"] else ""),
                  type="positive" if result["status"] == "passed" else "negative", multi_line=True)

    start.on_click(run_it)
    last = runtime.record.runs.get(name)
    if last is not None:
        last.listeners.append(lambda: draw(last))
        draw(last)


async def ask_account(runtime, user: str, what: str) -> str | None:
    """The engineer account that approves or signs: the session's own when it is one (logged in beyond
    the loopback address), else asked now with a login (throttled and audited as the login page's).
    None when the person cancels or no account could be checked (said)."""
    from app.auth import check_login
    from pages.session import client_address

    known = runtime.users.users.get(user)
    if known is not None and known.role == "engineer":
        return known.name
    if not runtime.users.has_engineer():
        ui.notify(f"{what} needs a named engineer account and this installation has none yet: create one with "
                  "'commission user add NAME --role engineer', then try again", type="warning", multi_line=True)
        return None
    address = client_address() or "unknown address"
    with ui.dialog().props("persistent") as dialog, ui.card().classes("w-96").mark("account-dialog"):
        ui.label(f"{what}: who is it?").classes("text-h6")
        ui.label("An approval and a sign-off name an engineer account: log in with yours. The record keeps the "
                 "account beside the name you type.").classes("text-body2")
        name = ui.input("Account").props("outlined autofocus maxlength=64").classes("w-full").mark("account-name")
        password = ui.input("Password", password=True, password_toggle_button=True).props("outlined").classes("w-full").mark(
            "account-password")
        message = ui.label().classes("text-negative text-body2").mark("account-message")

        async def attempt() -> None:
            account, words = await check_login(throttle=runtime.login_throttle, users=runtime.users, audit=runtime.audit,
                                               typed=(name.value or "").strip(), secret=password.value or "", address=address,
                                               via="record page")
            if account is None:
                message.set_text(words)
                password.set_value("")
                return
            if account.role != "engineer":
                message.set_text(f"{account.name} has the {account.role} role: an engineer account approves and signs")
                return
            dialog.submit(account.name)

        password.on("keydown.enter", attempt)
        with ui.row():
            ui.button("Log in and continue", icon="login", on_click=attempt).mark("account-ok")
            ui.button("Cancel", on_click=lambda: dialog.submit(None)).props("flat").mark("account-cancel")
    try:
        return await dialog
    finally:
        dialog.delete()  # asked again next time, with empty fields


async def confirm_gaps(gaps: list[str], what: str) -> bool:
    """Before a sign-off: the devices without a checkout, with a failed one or with settings not approved."""
    if not gaps:
        return True
    with ui.dialog().props("persistent") as dialog, ui.card().mark("gaps-dialog"):
        ui.label(f"Sign {what} although these are open?").classes("text-h6")
        with ui.column().classes("gap-0"):
            for line in gaps:
                ui.label(line).classes("text-body2")
        ui.label("The list is kept in the signed report. Run the missing checkouts and approve the sets first, "
                 "or sign anyway.").classes("text-caption")
        with ui.row():
            ui.button("Sign anyway", color="negative", on_click=lambda: dialog.submit(True)).mark("gaps-sign")
            ui.button("Cancel", on_click=lambda: dialog.submit(False)).props("flat").mark("gaps-cancel")
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


def _timeline_card(runtime, name: str, user: str, role: str, engineer: bool):
    ui.label("Timeline").classes("text-h6")
    with ui.row():
        approve = ui.button("Approve current set", icon="verified").props("outline dense").mark("record-approve")
        snap = ui.button("Snapshot now", icon="photo_camera").props("outline dense").mark("record-snapshot")
    no_set = "" if backup.device_backs_up(runtime, name) else f"{name} has no parameter set to approve or keep"
    for b in (approve, snap):
        enable_unless(b, VIEWER_REASON if not engineer else no_set)

    async def why_no_set() -> None:  # the adapter's own words (e.g. an M3IO in simple mode keeps no records)
        why = (await backup.why_nothing_to_back_up(runtime, name)).removeprefix("nothing to back up: ")
        if why and engineer:
            for b in (approve, snap):
                enable_unless(b, f"{name} has no parameter set to approve or keep: {why}")

    if no_set:
        ui.timer(0, why_no_set, once=True)
    columns = [{"name": "id", "label": "#", "field": "id"}, {"name": "time", "label": "Time", "field": "time", "align": "left"},
               {"name": "kind", "label": "Kind", "field": "kind", "align": "left"},
               {"name": "title", "label": "What", "field": "title", "align": "left"},
               {"name": "user", "label": "By", "field": "user", "align": "left"}]
    table = ui.table(columns=columns, rows=[], row_key="id", selection="multiple",
                     pagination=8).props("dense flat").classes("w-full").mark("record-timeline")
    diff_box = ui.column().classes("w-full").mark("record-diff")

    async def refresh() -> None:
        entries = await runtime.record.timeline(name)
        table.rows = [{"id": e.id, "time": fmt_time(e.time), "kind": e.kind, "title": e.title, "user": e.user} for e in entries]
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
                params = {f"{s['name']}/{v['name']}": {"name": f"{s['name']}: {v['name']}", "raw": v["value"], "text": f"{v['value']} {v['unit']}".strip()}
                          for s in e.data["steps"] for v in s["values"]}
            sets.append(params or {})
        rows = diff_sets(*sets)
        with diff_box:
            ui.label(f"#{a.id} {a.kind} → #{b.id} {b.kind}: {len(rows)} difference(s)").classes("font-medium")
            if rows:
                ui.table(columns=[{"name": k, "label": k.title(), "field": k, "align": "left"} for k in ("name", "old", "new")],
                         rows=rows, row_key="name").props("dense flat").classes("w-full")

    table.on("selection", lambda _e: show_diff())

    async def act(what: str) -> None:
        try:
            if what == "approve":
                account = await ask_account(runtime, user, f"Approving the set of {name}")
                if account is None:
                    return
                await runtime.record.approve(name, user=user, role=role, account=account)
                ui.notify(f"approved set stored (account {account})", type="positive")
            else:
                await runtime.record.snapshot(name, user=user, role=role)
                ui.notify("snapshot stored", type="positive")
        except ACTION_ERRORS as exc:  # said to the engineer
            ui.notify(f"{what}: {exc}", type="negative", multi_line=True)
        await refresh()

    approve.on_click(lambda: act("approve"))
    snap.on_click(lambda: act("snapshot"))
    ui.timer(0.1, refresh, once=True)
    return refresh


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


def _signoff_card(runtime, name: str, user: str, role: str, engineer: bool, refresh_timeline) -> None:
    lang = i18n.page_language()  # the preview speaks the page's language
    ui.label("As-left report and sign-off").classes("text-h6")
    # in the head of the page: the preview's HTML is sanitized, which drops a <style> of its own (its
    # tables and labels then ran together: "addressaddress 1")
    ui.add_css(PREVIEW_CSS)
    preview = ui.html("").classes("w-full").mark("record-report")
    with ui.expansion("Full listings: settings, live values, every step with its evidence file, audit rows").classes(
            "w-full").mark("record-listings"):
        listings = ui.html("").classes("w-full")
    with ui.row().classes("items-end gap-3 w-full"):
        signer = ui.input("Name", value=user if user != "local" else "").props("dense outlined").mark("sign-name")
        signer_role = ui.input("Role", value="commissioning engineer").props("dense outlined").mark("sign-role")
        comment = ui.input("Comment").props("dense outlined").classes("flex-1").mark("sign-comment")
    with ui.row():
        sign_device = ui.button(f"Sign {name}", icon="draw").mark("sign-device")
        sign_plant = ui.button(f"Sign plant {runtime.plant.name}", icon="draw").props("outline").mark("sign-plant")
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
            ui.notify("a sign-off needs a name", type="warning")
            return
        what = f"plant {runtime.plant.name}" if plant else name
        try:
            content = await (plant_content(runtime, user=user, role=role) if plant else device_content(runtime, name, user=user, role=role))
        except ACTION_ERRORS as exc:  # said to the engineer
            ui.notify(f"sign-off: the report could not be made: {exc}", type="negative", multi_line=True)
            return
        if not await confirm_gaps(sign_gaps(content), what):
            return
        account = await ask_account(runtime, user, f"Signing {what}")
        if account is None:
            return
        try:
            await runtime.record.sign("" if plant else name, user=user, role=role, name=signer.value.strip(),
                                      signer_role=signer_role.value.strip(), comment=comment.value, content=content,
                                      account=account)
        except ACTION_ERRORS as exc:  # said to the engineer
            ui.notify(f"sign-off: not signed: {exc}", type="negative", multi_line=True)
            return
        ui.notify(f"signed by {signer.value.strip()} with account {account}: the record is frozen; a later sign-off "
                  "supersedes it", type="positive")
        await show()
        await refresh_timeline()

    sign_device.on_click(lambda: sign(False))
    sign_plant.on_click(lambda: sign(True))
    ui.timer(0.2, show, once=True)
    ui.timer(5.0, show)  # checkouts, approvals and snapshots of this page or another one show up


def _check_card(runtime) -> None:
    """Whether the record (or an as-left archive someone hands over) was altered: the chain of row
    hashes, the sign-offs, every file against the archive's manifest (app/verify.py)."""
    ui.label("Check for alterations").classes("text-h6")
    ui.label("Every record row carries the hash of the row before it; an archive carries the chain and a manifest of "
             "every file's SHA-256. The same check runs as 'commission verify ARCHIVE'.").classes("text-body2 text-grey-8")
    result = ui.column().classes("w-full gap-0").mark("check-result")

    def show(check) -> None:
        result.clear()
        with result:
            ui.label(check.summary()).classes("text-body1 " + ("text-positive" if check.ok else "text-negative text-weight-bold"))
            for line in check.problems[1:] + [f"note: {n}" for n in check.notes]:
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
        ui.button("Check the record", icon="fact_check", on_click=check_record).props("outline").mark("check-record")
        upload = ui.upload(auto_upload=True, max_file_size=500_000_000, on_upload=uploaded).props(
            "accept=.zip flat bordered hide-upload-btn").classes("w-72").mark("check-archive")
        upload.add_slot("header", upload_button("Check an archive (.zip)", "check-archive-upload"))
