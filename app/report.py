"""The as-left report of a device and of a plant: HTML, PDF (ReportLab) and one archive per plant.

One content dictionary (:func:`device_content`, :func:`plant_content`) feeds every format, so the
HTML in the browser, the HTML file, the PDF and ``commission report`` say the same. A sign-off
stores that content frozen in the record (``app/record.py``); a signed report is shown as signed.
"""

from __future__ import annotations

import argparse
import asyncio
import html
import io
import json
import os
import tempfile
import time
import zipfile
from datetime import datetime
from pathlib import Path
from typing import Any

from app.record import LIVE_VALUE, compare_with_approved, device_updated, live_params, live_set, param_set

AUDIT_ROWS = 200


def _when(t: float | None) -> str:
    return "" if not t else datetime.fromtimestamp(t).strftime("%Y-%m-%d %H:%M:%S")


def _address(options: dict) -> str:
    for key in ("address", "device_id", "sw1", "safety_id"):
        if key in options:
            value = options[key]
            return f"{key} {value}" if key != "sw1" else f"SW1 0x{value:02X}"
    return ""


async def device_content(runtime, device: str, *, read: bool = True, user: str = "local", role: str = "engineer") -> dict:
    """Everything the as-left report of one device says. ``read``: read every parameter fresh
    (else the last snapshot stands for the device's values)."""
    record = runtime.record
    state = runtime.store.devices[device]
    config = runtime.plant.devices[device]
    identity: dict = {}
    current: dict[str, dict] = {}
    source = "no parameters read"
    if read:
        try:
            identity, entries = await record.read_set(device, user=user, role=role)
            current, source = param_set(entries), f"read from the device at {_when(time.time())}"
        except Exception as exc:  # noqa: BLE001 - the report says why
            source = f"not read: {exc}"
    approved_entry = await record.store.run(record.store.latest, record.plant, device, "approved")
    approved = approved_entry.data["parameters"] if approved_entry else None
    if not current:
        snap = await record.store.run(record.store.latest, record.plant, device, "snapshot")
        if not identity:  # as the device page shows it (the adapter reads it from the live store)
            try:
                identity = runtime.worker.adapters[device].backup_identity()
            except Exception:  # noqa: BLE001 - a device without one: the last snapshot's below
                identity = {}
        if snap is not None:
            identity = identity or snap.data.get("identity", {})
        # what the device page shows: the live store's values (its last poll) first, the last snapshot
        # for whatever the live store does not hold (parameters read on demand, a device offline)
        live = {**live_params(state), **live_set(state, {**(snap.data["parameters"] if snap else {}), **(approved or {})})}
        if snap is not None:
            current = {k: {**v, **live.get(k, {})} for k, v in snap.data["parameters"].items()}
            current.update((k, v) for k, v in live.items() if k not in current)
        else:
            current = live
        if live and state.last_seen:
            source = (f"as the device showed them at {_when(state.last_seen)}" + (f" (else the last snapshot of {_when(snap.time)})" if snap else "")
                      + (f"; {source}" if read else ""))
        elif snap is not None:
            source = f"of the last snapshot of {_when(snap.time)} ({source})"
    if not current and not read:
        source = "not read yet: the device has not answered (snapshot or approve to read it)"
    state = runtime.store.devices[device]
    current = {k: {**v, "device_updates": device_updated(state, k)} for k, v in current.items()}
    rows = compare_with_approved(current, approved)
    checkouts = await record.timeline(device, ("checkout",))
    latest_checkouts: dict[str, Any] = {}
    for entry in checkouts:  # newest first: the latest run of each checkout stands, older ones are listed as superseded
        latest_checkouts.setdefault(entry.data.get("title", ""), entry)
    entries = await record.timeline(device)
    since = min((e.time for e in entries), default=time.time() - 86400) - 60
    audit = await runtime.audit.aquery(device=device, since=since, limit=AUDIT_ROWS) if runtime.audit else []
    signoff = await record.store.run(record.store.latest, record.plant, device, "signoff")
    people = sorted({e.user for e in entries if e.kind in ("checkout", "approved", "snapshot")})
    return {
        "device": device, "type": state.type, "bus": config.bus, "address": _address(config.options),
        "identity": {k: v for k, v in identity.items() if v is not None},
        "status": state.status, "parameters_source": source,
        "approved": None if approved_entry is None else {"id": approved_entry.id, "time": approved_entry.time,
                                                          "by": approved_entry.user, "title": approved_entry.title},
        "parameters": rows,
        "counts": {v: sum(r["verdict"] == v for r in rows) for v in ("equal", "changed", "not approved", "updated by the device", LIVE_VALUE)},
        "drift": (getattr(state, "drift", None) or {}).get("changed", []),
        "checkouts": [{"id": e.id, "time": e.time, **{k: e.data[k] for k in ("title", "status", "reason", "user", "duration_s", "steps")}}
                      for e in latest_checkouts.values()],
        "audit": [{"time": a.time, "user": a.user, "role": a.role, "action": a.action, "parameter": a.parameter,
                   "old": a.old, "new": a.new, "result": a.result} for a in audit],
        "commissioned_by": people,
        "commissioned": [_when(min((e.time for e in entries), default=None)), _when(max((e.time for e in entries), default=None))],
        "signoff": None if signoff is None else {"id": signoff.id, **{k: signoff.data[k] for k in ("name", "role", "comment", "time", "sha256")}},
    }


async def plant_content(runtime, *, read: bool = True, user: str = "local", role: str = "engineer") -> dict:
    devices = list(await asyncio.gather(*(device_content(runtime, name, read=read, user=user, role=role)
                                          for name in runtime.plant.devices)))  # buses read side by side
    signoff = await runtime.record.store.run(runtime.record.store.latest, runtime.record.plant, "", "signoff")
    return {"plant": runtime.plant.name, "generated": time.time(), "devices": devices,
            "signoff": None if signoff is None else {"id": signoff.id, **{k: signoff.data[k] for k in ("name", "role", "comment", "time", "sha256")}}}


# -- HTML ------------------------------------------------------------------------------------------
CSS = """
body{font-family:system-ui,sans-serif;margin:24px;color:#222;max-width:1100px}
h1{font-size:22px}h2{font-size:18px;border-bottom:2px solid #444;margin-top:32px}h3{font-size:15px}
table{border-collapse:collapse;margin:6px 0 12px;font-size:12px;width:100%}
td,th{border:1px solid #bbb;padding:2px 6px;text-align:left;vertical-align:top}th{background:#eee}
.equal{color:#1b5e20}.changed,.failed,.aborted{color:#b71c1c;font-weight:600}.passed{color:#1b5e20;font-weight:600}
.notapproved,.skipped{color:#8d6e00}.notavailable,.updatedbythedevice,.livevalue{color:#555}.sig{border:2px solid #1b5e20;padding:8px;margin:8px 0}.unsigned{border-color:#b71c1c}
"""


def _with_unit(value: Any, unit: str) -> str:
    """A parameter's shown value with its unit once (the model's text often carries the unit already)."""
    text = "" if value is None else str(value)
    return text if not unit or text.endswith(unit) else f"{text} {unit}".strip()


def _e(value: Any) -> str:
    return html.escape("" if value is None else str(value))


def commissioned_text(d: dict, plant_signed: bool = False) -> str:
    """Who commissioned the device and when, saying what is missing rather than leaving a blank."""
    who = ", ".join(d["commissioned_by"]) or "nobody yet (no checkout, approved set or snapshot recorded)"
    first, last = d["commissioned"]
    when = "" if not first else f" on {first}" if first == last or not last else f" from {first} to {last}"
    signed = "" if d.get("signoff") or plant_signed else ", not signed yet"
    return f"Commissioned by {who}{when}{signed}."


def values_text(d: dict) -> str:
    """Where the parameter values come from and how they compare, one sentence."""
    counts = ", ".join(f"{n} {k}" for k, n in d["counts"].items() if n) or "no parameters"
    return f"Values {d['parameters_source']}: {counts}."


def _signoff_html(sig: dict | None, what: str, plant: dict | None = None) -> str:
    if not sig and plant:  # a device of a signed plant: the plant's sign-off covers it
        return f'<div class="sig">{_e(what)}: no sign-off of its own; signed with the plant (record #{plant["id"]})</div>'
    if not sig:
        return f'<div class="sig unsigned">{_e(what)}: not signed</div>'
    return (f'<div class="sig">{_e(what)} signed by <b>{_e(sig["name"])}</b> ({_e(sig["role"])}) on {_when(sig["time"])}'
            f'<br>Comment: {_e(sig["comment"])}<br><small>record #{sig["id"]}, content SHA-256 {sig["sha256"][:16]}…</small></div>')


def device_html(d: dict, plant_signoff: dict | None = None) -> str:
    out = [f'<h2 id="{_e(d["device"])}">{_e(d["device"])} <small>({_e(d["type"])})</small></h2>',
           _signoff_html(d["signoff"], d["device"], plant_signoff)]
    ident = {"type": d["type"], "bus": d["bus"], "address": d["address"], **d["identity"], "status": d["status"]}
    out.append("<table>" + "".join(f"<tr><th>{_e(k)}</th><td>{_e(v)}</td></tr>" for k, v in ident.items()) + "</table>")
    out.append(f"<p>{_e(commissioned_text(d, bool(plant_signoff)))}</p>")
    if d["drift"]:
        out.append('<p class="changed">Changed since approved: ' + _e(", ".join(f"{r['name']} {r['approved']} → {r['now']}" for r in d["drift"])) + "</p>")
    ap = d["approved"]
    out.append("<h3>Parameters against the approved set</h3><p>" + (
        f"Approved set #{ap['id']} ({_e(ap['title'])}) by {_e(ap['by'])} on {_when(ap['time'])}. " if ap else "No approved set. ")
        + _e(values_text(d)) + "</p>")
    if d["parameters"]:
        out.append("<table><tr><th>Parameter</th><th>As left</th><th>Approved</th><th></th></tr>" + "".join(
            f'<tr><td>{_e(r["name"])}</td><td>{_e(_with_unit(r["value"], r["unit"]))}</td><td>{_e(r["approved"])}</td>'
            f'<td class="{r["verdict"].replace(" ", "")}">{_e(r["verdict"])}</td></tr>' for r in d["parameters"]) + "</table>")
    out.append("<h3>Checkouts</h3>")
    if not d["checkouts"]:
        out.append("<p>No checkout run.</p>")
    for c in d["checkouts"]:
        out.append(f'<p><b>{_e(c["title"])}</b>: <span class="{c["status"].replace(" ", "")}">{_e(c["status"])}</span> '
                   f'{_e(c["reason"])} — {_e(c["user"])}, {_when(c["time"])}, {c["duration_s"]} s (record #{c["id"]})</p>')
        rows = []
        for s in c["steps"]:
            values = "; ".join(f'{v["name"]} = {v["value"]} {v["unit"]} ({v["limit"] or "recorded"}: {"ok" if v["ok"] else "FAIL"})'
                               for v in s["values"])
            answers = "; ".join(f'{a["question"]} {a["answer"]} ({a["by"]})' for a in s["answers"])
            ev = s.get("evidence") or {}
            n = len(ev.get("frames") or ev.get("transactions") or [])
            rows.append(f'<tr><td>{_e(s["name"])}</td><td class="{s["status"].replace(" ", "")}">{_e(s["status"])}</td><td>{_e(s["limits"])}</td>'
                        f'<td>{_e(values)}{"<br>" if values and answers else ""}{_e(answers)}{"<br>" + _e(s["reason"]) if s["reason"] else ""}</td>'
                        f'<td>{n} {"frames" if ev.get("kind") == "can" else "transactions"}</td></tr>')
        out.append("<table><tr><th>Step</th><th>Result</th><th>Limits</th><th>Measured, answers</th><th>Evidence</th></tr>"
                   + "".join(rows) + "</table>")
    out.append(f"<h3>Audit rows ({len(d['audit'])})</h3>")
    if d["audit"]:
        out.append("<table><tr><th>Time</th><th>User</th><th>Action</th><th>Parameter</th><th>Old → new</th><th>Result</th></tr>" + "".join(
            f'<tr><td>{_when(a["time"])}</td><td>{_e(a["user"])} ({_e(a["role"])})</td><td>{_e(a["action"])}</td><td>{_e(a["parameter"])}</td>'
            f'<td>{_e(a["old"])} → {_e(a["new"])}</td><td>{_e(a["result"])}</td></tr>' for a in d["audit"]) + "</table>")
    return "\n".join(out)


def _checkout_summary(d: dict) -> str:
    return ", ".join(f"{c['title']}: {c['status']}" for c in d["checkouts"]) or "none"


def _signed_word(d: dict, p: dict) -> str:
    return "signed" if d["signoff"] else "with the plant" if p.get("signoff") else "not signed"


def plant_html(p: dict) -> str:
    summary = "".join(
        f'<tr><td><a href="#{_e(d["device"])}">{_e(d["device"])}</a></td><td>{_e(d["type"])}</td>'
        f'<td>{_e(_checkout_summary(d))}</td>'
        f'<td>{d["counts"]["changed"]} changed, {d["counts"]["not approved"]} not approved</td>'
        f'<td>{_signed_word(d, p)}</td></tr>' for d in p["devices"])
    return (f"<!doctype html><html><head><meta charset='utf-8'><title>As-left report {_e(p['plant'])}</title><style>{CSS}</style></head><body>"
            f"<h1>As-left report: plant {_e(p['plant'])}</h1><p>Generated {_when(p['generated'])} by commission.</p>"
            + _signoff_html(p["signoff"], f"Plant {p['plant']}")
            + "<table><tr><th>Device</th><th>Type</th><th>Checkouts</th><th>Parameters</th><th>Sign-off</th></tr>" + summary + "</table>"
            + "".join(device_html(d, p["signoff"]) for d in p["devices"]) + "</body></html>")


# -- PDF (ReportLab, from the same content) ----------------------------------------------------------
def plant_pdf(p: dict) -> bytes:
    from reportlab.lib import colors
    from reportlab.lib.pagesizes import A4
    from reportlab.lib.styles import getSampleStyleSheet
    from reportlab.lib.units import mm
    from reportlab.platypus import PageBreak, Paragraph, SimpleDocTemplate, Spacer, Table, TableStyle

    styles = getSampleStyleSheet()
    small = styles["BodyText"].clone("small", fontSize=7.5, leading=9)
    buf = io.BytesIO()
    doc = SimpleDocTemplate(buf, pagesize=A4, leftMargin=14 * mm, rightMargin=14 * mm, topMargin=14 * mm, bottomMargin=14 * mm,
                            title=f"As-left report {p['plant']}", author="commission")
    width = A4[0] - 28 * mm

    def para(text: Any, style=small) -> Paragraph:
        return Paragraph(_e(text), style)

    def table(rows: list[list[Any]], widths: list[float]) -> Table:
        t = Table([[para(c) for c in r] for r in rows], colWidths=[w * width for w in widths], repeatRows=1)
        t.setStyle(TableStyle([("GRID", (0, 0), (-1, -1), 0.3, colors.grey), ("BACKGROUND", (0, 0), (-1, 0), colors.whitesmoke),
                               ("VALIGN", (0, 0), (-1, -1), "TOP")]))
        return t

    def sig(s: dict | None, what: str) -> Paragraph:
        if not s and p.get("signoff") and what != f"Plant {p['plant']}":
            return para(f"{what}: no sign-off of its own; signed with the plant (record #{p['signoff']['id']})", styles["BodyText"])
        if not s:
            return para(f"{what}: not signed", styles["BodyText"])
        return para(f"{what} signed by {s['name']} ({s['role']}) on {_when(s['time'])}. Comment: {s['comment']}. "
                    f"Record #{s['id']}, SHA-256 {s['sha256'][:16]}", styles["BodyText"])

    story: list = [Paragraph(_e(f"As-left report: plant {p['plant']}"), styles["Title"]),
                   para(f"Generated {_when(p['generated'])} by commission.", styles["BodyText"]), sig(p["signoff"], f"Plant {p['plant']}"),
                   Spacer(1, 4 * mm)]
    story.append(table([["Device", "Type", "Checkouts", "Parameters", "Sign-off"]] + [
        [d["device"], d["type"], ", ".join(f"{c['title']}: {c['status']}" for c in d["checkouts"]) or "none",
         f"{d['counts']['changed']} changed, {d['counts']['not approved']} not approved", _signed_word(d, p)]
        for d in p["devices"]], [0.18, 0.1, 0.37, 0.22, 0.13]))
    for d in p["devices"]:
        story += [PageBreak(), Paragraph(_e(f"{d['device']} ({d['type']})"), styles["Heading2"]), sig(d["signoff"], d["device"])]
        ident = {"type": d["type"], "bus": d["bus"], "address": d["address"], **d["identity"], "status": d["status"]}
        story.append(table([["Identity", ""]] + [[k, v] for k, v in ident.items()], [0.3, 0.7]))
        story.append(para(commissioned_text(d, bool(p.get("signoff")))))
        if d["drift"]:
            story.append(para("Changed since approved: " + ", ".join(f"{r['name']} {r['approved']} -> {r['now']}" for r in d["drift"])))
        story.append(Paragraph("Parameters against the approved set", styles["Heading3"]))
        story.append(para(values_text(d)))
        if d["parameters"]:
            story.append(table([["Parameter", "As left", "Approved", "Verdict"]] + [
                [r["name"], _with_unit(r["value"], r["unit"]), r["approved"], r["verdict"]] for r in d["parameters"]],
                [0.4, 0.25, 0.2, 0.15]))
        story.append(Paragraph("Checkouts", styles["Heading3"]))
        for c in d["checkouts"]:
            story.append(para(f"{c['title']}: {c['status'].upper()} {c['reason']} - {c['user']}, {_when(c['time'])}, {c['duration_s']} s"))
            story.append(table([["Step", "Result", "Measured, answers", "Evidence"]] + [
                [s["name"], s["status"] + (f": {s['reason']}" if s["reason"] else ""),
                 "; ".join(f"{v['name']} = {v['value']} {v['unit']} ({v['limit'] or 'recorded'}: {'ok' if v['ok'] else 'FAIL'})" for v in s["values"])
                 + "".join(f"; {a['question']} {a['answer']} ({a['by']})" for a in s["answers"]),
                 str(len((s.get("evidence") or {}).get("frames") or (s.get("evidence") or {}).get("transactions") or []))]
                for s in c["steps"]], [0.2, 0.2, 0.5, 0.1]))
        if d["audit"]:
            story.append(Paragraph(f"Audit rows ({len(d['audit'])})", styles["Heading3"]))
            story.append(table([["Time", "User", "Action", "Parameter", "Old -> new", "Result"]] + [
                [_when(a["time"]), a["user"], a["action"], a["parameter"], f"{a['old']} -> {a['new']}", a["result"]] for a in d["audit"]],
                [0.15, 0.1, 0.2, 0.15, 0.2, 0.2]))
    doc.build(story)
    return buf.getvalue()


# -- evidence traces and the archive ----------------------------------------------------------------
def can_trace(frames: list[dict], suffix: str, channel: str) -> bytes:
    """CAN frames of a step in a standard format: ``.log`` (candump) or ``.trc`` (PEAK), by python-can."""
    import can

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"trace{suffix}"
        writer = can.CanutilsLogWriter(path, channel=channel) if suffix == ".log" else can.TRCWriter(path, channel=1)
        with writer:
            for f in frames:
                writer.on_message_received(can.Message(timestamp=f["t"], arbitration_id=f["id"], is_extended_id=f["ext"],
                                                       data=bytes.fromhex(f["data"]), is_rx=f["dir"] == "rx",
                                                       is_error_frame=f.get("err", False), channel=channel))
        return path.read_bytes()


def serial_trace(rows: list[dict]) -> bytes:
    return "".join(f"{_when(r['t'])}.{int(r['t'] * 1000) % 1000:03d} TX {r['tx']} RX {r['rx']} {r['decoded']} {r['error']}\n"
                   for r in rows).encode()


async def write_plant(runtime, out_dir: Path, content: dict | None = None, *, user: str = "local", role: str = "engineer") -> dict[str, Path]:
    """report.html, report.pdf and the archive (reports, approved sets and snapshots as backup files,
    evidence traces) of the plant into ``out_dir``; returns the paths."""
    content = content or await plant_content(runtime, user=user, role=role)
    snapshots = {}
    for d in content["devices"]:
        for kind in ("approved", "snapshot"):
            entry = await runtime.record.store.run(runtime.record.store.latest, runtime.record.plant, d["device"], kind)
            if entry is not None:
                snapshots[f"backups/{d['device']}-{kind}.json"] = json.dumps(_as_backup(runtime, d, entry), indent=1, ensure_ascii=False)
    return await asyncio.to_thread(_write_files, out_dir, content, snapshots)


def _as_backup(runtime, d: dict, entry) -> dict:
    from app.backup import make_document

    params = [{"key": k, "name": v["name"], "raw": v["raw"], "value": v["raw"], "text": v["text"], "unit": v.get("unit", ""),
               "writable": v.get("writable", False)} for k, v in entry.data["parameters"].items()]
    return make_document(runtime.plant.name, d["device"], d["type"], d["bus"], entry.data.get("identity", {}), params, entry.time,
                         user=entry.user, role=entry.role)


def _write_files(out_dir: Path, content: dict, backups: dict[str, str]) -> dict[str, Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    name = f"{content['plant']}-as-left"
    html_text = plant_html(content)
    pdf = plant_pdf(content)
    paths = {"html": out_dir / f"{name}.html", "pdf": out_dir / f"{name}.pdf", "zip": out_dir / f"{name}.zip"}
    _atomic(paths["html"], html_text.encode())
    _atomic(paths["pdf"], pdf)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(f"{name}.html", html_text)
        archive.writestr(f"{name}.pdf", pdf)
        archive.writestr(f"{name}.json", json.dumps(content, indent=1, ensure_ascii=False, default=str))
        for path, text in backups.items():
            archive.writestr(path, text)
        for d in content["devices"]:
            for c in d["checkouts"]:
                for n, s in enumerate(c["steps"], 1):
                    ev = s.get("evidence") or {}
                    stem = f"evidence/{d['device']}/checkout-{c['id']}-step{n}"
                    if ev.get("kind") == "can" and ev.get("frames"):
                        archive.writestr(f"{stem}.log", can_trace(ev["frames"], ".log", d["bus"]))
                        archive.writestr(f"{stem}.trc", can_trace(ev["frames"], ".trc", d["bus"]))
                    elif ev.get("transactions"):
                        archive.writestr(f"{stem}.txt", serial_trace(ev["transactions"]))
    _atomic(paths["zip"], buf.getvalue())
    return paths


def _atomic(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    with os.fdopen(fd, "wb") as handle:
        handle.write(data)
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(tmp, path)


# -- CLI: commission report --plant P --out DIR ----------------------------------------------------------
def add_parser(sub) -> None:
    parser = sub.add_parser("report", help="write the as-left report (HTML, PDF) and archive of a plant, headless")
    parser.add_argument("--plant", type=Path, default=None, help="plant file (default: the built-in demo plant)")
    parser.add_argument("--out", type=Path, required=True, help="folder for the report files")
    parser.add_argument("--no-sim", action="store_true", help="do not start simulated devices")
    parser.add_argument("--wait", type=float, default=20.0, help="seconds to wait for the devices to come online (default 20)")
    parser.add_argument("--data-dir", type=Path, default=None, help="data folder with the record (default: ~/.local/share/commission)")
    parser.set_defaults(func=run_cli)


def run_cli(args: argparse.Namespace) -> int:
    from app.headless import _load
    from app.runtime import Runtime
    from app.users import default_data_dir

    plant = _load(args.plant)
    runtime = Runtime(plant, simulate=not args.no_sim, data_dir=args.data_dir or default_data_dir())

    async def main() -> dict:
        await runtime.start()
        try:
            end = time.monotonic() + args.wait
            while time.monotonic() < end and not all(s.status == "online" for s in runtime.store.devices.values()):
                await asyncio.sleep(0.2)
            return await write_plant(runtime, args.out)
        finally:
            await runtime.stop()

    paths = asyncio.run(main())
    for kind, path in paths.items():
        print(f"{kind}: {path} ({path.stat().st_size} bytes)")
    return 0
