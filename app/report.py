"""The as-left report of a device and of a plant: HTML, PDF (ReportLab) and one archive per plant.

One content dictionary (:func:`device_content`, :func:`plant_content`) feeds every format, so the
HTML in the browser, the HTML file, the PDF and ``commission report`` say the same. A sign-off
stores that content frozen in the record (``app/record.py``); a signed report is shown as signed.
"""

from __future__ import annotations

import asyncio
import html
import re
import time
from datetime import datetime
from pathlib import Path
from typing import Any

from app import i18n
from app.i18n import N_, NP_
from app.message import reworded, said
from app.record_sets import (
    LIVE_VALUE,
    compare_with_approved,
    device_updated,
    live_params,
    live_set,
    param_set,
)
from app.report_evidence import evidence_named
from app.verify import sha256
from devices.adapter import BackupAdapter
from devices.errors import CommissionError
from devices.params import Access

AUDIT_ROWS = 200
SIMULATED_MARK = N_("SIMULATED DEVICES - made on the built-in twins, not on site equipment")


def tool_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return f"commission {version('commission')}"
    except PackageNotFoundError:
        return "commission (version unknown)"


def plant_file(plant) -> dict:
    """The plant file the report was made with and its SHA-256 (None: a plant given without a file)."""
    path = plant.path
    if path is None:
        return {"path": None, "sha256": None}
    try:
        return {"path": str(path), "sha256": sha256(Path(path).read_bytes())}
    except OSError as exc:
        return {"path": str(path), "sha256": None, "error": exc.strerror or str(exc)}


def _run_summary(runs: list[dict]) -> list[dict]:
    """Per checkout: its last run's result, how many runs and how they ended, who ran them."""
    by_title: dict[str, dict] = {}
    for run in sorted(runs, key=lambda r: r["time"]):
        s = by_title.setdefault(run["title"], {"title": run["title"], "runs": 0, "passed": 0, "failed": 0, "by": []})
        s["runs"] += 1
        s["passed" if run["status"] == "passed" else "failed"] += 1
        table = run.get("worded") or {}
        s.update(last=run["status"], last_reason=run["reason"], last_time=run["time"], last_id=run["id"],
                 worded={text: table[text] for text in (run["title"], run["reason"]) if text in table})
        if run["user"] not in s["by"]:
            s["by"].append(run["user"])
    return list(by_title.values())


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
        except CommissionError as exc:  # not answering, refused: the report says why
            source = f"not read: {exc}"
    approved_entry = await record.store.run(record.store.latest, record.plant, device, "approved")
    approved = approved_entry.data["parameters"] if approved_entry else None
    if not current:
        snap = await record.store.run(record.store.latest, record.plant, device, "snapshot")
        if not identity:  # as the device page shows it (the adapter reads it from the live store)
            adapter = runtime.worker.adapters[device]
            identity = adapter.backup_identity() if isinstance(adapter, BackupAdapter) else {}  # without one: the snapshot's
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
    params = state.params
    for r in rows:  # a setting or a live value: the parameter model says, else what the set was read with
        param = params.by_key.get(r["key"]) if params is not None else None
        if param is not None:  # configuration (also the factory's, MFR) is a setting; states and measurements (R, RO) are not
            r["setting"] = param.access in (Access.RW, Access.MFR) and not param.device_updates
        else:
            r["setting"] = bool(r.get("writable") if r.get("writable") is not None else
                                ((approved or {}).get(r["key"]) or current.get(r["key"]) or {}).get("writable"))
    checkouts = await record.timeline(device, ("checkout",))  # every run stays in the report with its result
    runs = []
    for entry in checkouts:
        steps = []
        for n, step in enumerate(entry.data.get("steps", []), 1):
            named = evidence_named(entry.hash, device, config.bus, entry.id, n, step.get("evidence") or {})
            steps.append({**step, "evidence_file": named})
        runs.append({"id": entry.id, "time": entry.time, "settings": entry.data.get("settings", {}), "steps": steps,
                     **{k: entry.data.get(k) for k in ("title", "status", "reason", "user", "duration_s")},
                     "worded": entry.data.get("worded") or {}})
    entries = await record.timeline(device)
    since = min((e.time for e in entries), default=time.time() - 86400) - 60
    audit = await runtime.audit.aquery(device=device, since=since, limit=AUDIT_ROWS) if runtime.audit else []
    signoff = await record.store.run(record.store.latest, record.plant, device, "signoff")
    people = sorted({e.user for e in entries if e.kind in ("checkout", "approved", "snapshot")})
    from app.headless import simulated

    return {
        "device": device, "type": state.type, "bus": config.bus, "address": _address(config.options),
        "identity": {k: v for k, v in identity.items() if v is not None},
        "status": state.status, "parameters_source": source, "simulated": simulated(runtime, device),
        "approved": None if approved_entry is None else {"id": approved_entry.id, "time": approved_entry.time,
                                                          "by": approved_entry.user, "title": approved_entry.title},
        "parameters": rows,
        "settings": [r for r in rows if r["setting"]],
        "live_values": [r for r in rows if not r["setting"]],
        "counts": {v: sum(r["verdict"] == v for r in rows) for v in ("equal", "changed", "not approved", "updated by the device", LIVE_VALUE)},
        "drift": (state.drift or {}).get("changed", []),
        "checkouts": runs,
        "checkout_summary": _run_summary(runs),
        "audit": [{"time": a.time, "user": a.user, "role": a.role, "action": a.action, "parameter": a.parameter,
                   "old": a.old, "new": a.new, "result": a.result} for a in audit],
        "commissioned_by": people,
        "commissioned": [_when(min((e.time for e in entries), default=None)), _when(max((e.time for e in entries), default=None))],
        "signoff": signoff_of(signoff),
    }


def sign_gaps(content: dict, lang: i18n.Lang | None = None) -> list[str]:
    """What a signer is asked about before signing (a plant's or one device's content): devices with
    no checkout, whose last checkout did not pass, without an approved set or with settings not
    approved or changed since; in ``lang`` (checkout titles as the record holds them)."""
    _ = language(lang).gettext
    gaps = []
    for d in content.get("devices", [content]):
        said = []
        if not d["checkouts"]:
            said.append(_("no checkout run"))
        said += [_("last {title} {status}").format(title=recorded(c["title"], c, lang), status=word(c["last"], lang))
                 for c in d.get("checkout_summary", []) if c["last"] != "passed"]
        if d["approved"] is None:
            said.append(_("no approved set"))
        elif d["counts"].get("not approved"):
            said.append(count_text("not approved", d["counts"]["not approved"], lang))
        if d["counts"].get("changed"):
            said.append(count_text("changed", d["counts"]["changed"], lang))
        if said:
            gaps.append(f"{d['device']}: {', '.join(said)}")
    return gaps


def signoff_of(entry) -> dict | None:
    if entry is None:
        return None
    return {"id": entry.id, "account": entry.data.get("account") or entry.user, "row_hash": entry.hash,
            **{k: entry.data.get(k) for k in ("name", "role", "comment", "time", "sha256")}}


async def plant_content(runtime, *, read: bool = True, user: str = "local", role: str = "engineer") -> dict:
    devices = list(await asyncio.gather(*(device_content(runtime, name, read=read, user=user, role=role)
                                          for name in runtime.plant.devices)))  # buses read side by side
    signoff = await runtime.record.store.run(runtime.record.store.latest, runtime.record.plant, "", "signoff")
    check = await runtime.record.check()
    return {"plant": runtime.plant.name, "generated": time.time(), "devices": devices, "tool": tool_version(),
            "plant_file": plant_file(runtime.plant), "simulated": [d["device"] for d in devices if d["simulated"]],
            "record_check": {"ok": check.ok, "summary": check.summary(), "problems": check.problems, "notes": check.notes,
                             "head": None if check.head is None else {"id": check.head[0], "hash": check.head[1]}},
            "signoff": signoff_of(signoff)}


# -- HTML ------------------------------------------------------------------------------------------
CSS = """
body{font-family:system-ui,sans-serif;margin:24px;color:#222;max-width:1100px}
h1{font-size:22px}h2{font-size:18px;border-bottom:2px solid #444;margin-top:32px}h3{font-size:15px}
table{border-collapse:collapse;margin:6px 0 12px;font-size:12px;width:100%}
td,th{border:1px solid #bbb;padding:2px 6px;text-align:left;vertical-align:top}th{background:#eee}
.equal{color:#1b5e20}.changed,.failed,.aborted{color:#b71c1c;font-weight:600}.passed{color:#1b5e20;font-weight:600}
.notapproved,.skipped{color:#8d6e00}.notavailable,.updatedbythedevice,.livevalue{color:#555}.sig{border:2px solid #1b5e20;padding:8px;margin:8px 0}.unsigned{border-color:#b71c1c}
.sim{background:#fff3cd;border:2px solid #8d6e00;color:#5d4200;padding:4px 8px;font-weight:600;margin:6px 0}
.altered{background:#fdecea;border:2px solid #b71c1c;color:#b71c1c;padding:6px 8px;font-weight:600;margin:6px 0}
.hash{font-family:monospace;font-size:11px;word-break:break-all}
@media print{.sim.every{position:fixed;top:0;left:0;right:0}}
"""


def with_unit(value: Any, unit: str, lang: i18n.Lang | None = None) -> str:
    """A value with its unit once (the model's text often carries the unit already, also before a remark); with
    ``lang`` its numbers and its unit as the language writes them (the SCU's ``counts``: ``Flanken``)."""
    text = "" if value is None else str(value)
    if unit and not (text.endswith(unit) or re.search(rf"(?<![\w]){re.escape(unit)}(?![\w])", text)):
        text = f"{text} {unit}".strip()
    return lang.with_unit(text, unit) if lang is not None else text


_with_unit = with_unit  # the older name


def _e(value: Any) -> str:
    return html.escape("" if value is None else str(value))


# The words the content carries as data (a verdict, a run's result) and the report shows in its language;
# the content itself, frozen in a sign-off, keeps them in English.
WORDS = (N_("equal"), N_("changed"), N_("not approved"), N_("updated by the device"), N_("live value"), N_("passed"),
         N_("failed"), N_("aborted"), N_("skipped"), N_("not available"), N_("online"), N_("offline"), N_("stale"),
         N_("type"), N_("bus"), N_("address"), N_("status"), N_("serial"), N_("firmware"), N_("hardware"), N_("variant"))
# the sentences of ``parameters_source`` (content data, English), shown phrase by phrase in the report's language
SOURCE_PHRASES = (N_("read from the device at "), N_("as the device showed them at "), N_(" (else the last snapshot of "),
                  N_("of the last snapshot of "), N_("not read: "), N_("no parameters read"),
                  N_("not read yet: the device has not answered (snapshot or approve to read it)"))


def language(lang: i18n.Lang | None) -> i18n.Lang:
    return i18n.english(lang)


def when(t: float | None, lang: i18n.Lang | None = None) -> str:
    """A date and time as the report writes it: ISO in English (``2026-11-28 14:05:09``), the language's own
    form otherwise (``28.11.2026, 14:05:09``)."""
    if not t:
        return ""
    return _when(t) if lang is None or lang.code == "en" else lang.datetime(t)


def _recorded_when(text: str, lang: i18n.Lang | None) -> str:
    """A date and time the content holds as :func:`_when` wrote it (ISO), as :func:`when` writes it in ``lang``."""
    if not text or lang is None or lang.code == "en":
        return text
    return lang.datetime(datetime.strptime(text, "%Y-%m-%d %H:%M:%S").timestamp())


def word(text: Any, lang: i18n.Lang | None) -> str:
    """A word of the content (a verdict, a result, an identity's key) in the report's language."""
    return "" if text is None else language(lang).gettext(str(text)) if isinstance(text, str) else str(text)


def recorded(text: Any, run: dict, lang: i18n.Lang | None) -> Any:
    """A text of a checkout ``run`` (a title, a step's name, a reason, a question) as the record holds it, in ``lang``
    where the run keeps its template (``worded``, app/checkout.py); else, and in English, as it was written. A
    measured flag (stored ``True``/``False``) in the language's words (``ja``/``nein``)."""
    if isinstance(text, bool):
        return language(lang).gettext(str(text))
    if not isinstance(text, str) or lang is None or lang.code == "en":
        return text
    return said(reworded(text, run.get("worded")), lang)


def answer_word(answer: str, lang: i18n.Lang | None) -> str:
    """A recorded answer (``yes``, ``no``) in ``lang``."""
    return language(lang).pgettext("answer", answer)


ANSWERS = (NP_("answer", "yes"), NP_("answer", "no"))


def source_text(source: str, lang: i18n.Lang | None) -> str:
    """Where the values come from (content data, English) in the report's language, phrase by phrase, and its times
    (ISO, as :func:`_when` wrote them) as :func:`when` writes them (``29.11.2026, 07:30:43`` in German)."""
    lang = language(lang)
    for phrase in SOURCE_PHRASES:
        source = source.replace(phrase, lang.gettext(phrase))
    return _ISO_TIME.sub(lambda m: _recorded_when(m.group(0), lang), source)


_ISO_TIME = re.compile(r"\b\d{4}-\d{2}-\d{2} \d{2}:\d{2}:\d{2}\b")


def seconds(value: Any, lang: i18n.Lang | None) -> str:
    """A duration as recorded (``12.5 s``), with the language's decimal mark."""
    return f"{value} s" if lang is None else f"{lang.numbers_in(str(value))} s"


def commissioned_text(d: dict, plant_signed: bool = False, lang: i18n.Lang | None = None) -> str:
    """Who commissioned the device and when, saying what is missing rather than leaving a blank."""
    _ = language(lang).gettext
    who = ", ".join(d["commissioned_by"]) or _("nobody yet (no checkout, approved set or snapshot recorded)")
    first, last = (_recorded_when(t, lang) for t in d["commissioned"])
    when_text = "" if not first else (_(" on {first}").format(first=first) if first == last or not last
                                      else _(" from {first} to {last}").format(first=first, last=last))
    signed = "" if d.get("signoff") or plant_signed else _(", not signed yet")
    return _("Commissioned by {who}{when}{signed}.").format(who=who, when=when_text, signed=signed)


DIFFERING = ("changed", "not approved")  # settings the summary lists (a value the device measures itself is no difference)


def count_text(verdict: str, n: int, lang: i18n.Lang | None = None) -> str:
    """How many parameters of a set have a verdict, as a phrase of the language (``95 parameters not approved``)."""
    ngettext = language(lang).ngettext
    if verdict == "equal":
        text = ngettext("{n} parameter equal to the approved set", "{n} parameters equal to the approved set", n)
    elif verdict == "changed":
        text = ngettext("{n} parameter changed since approved", "{n} parameters changed since approved", n)
    elif verdict == "not approved":
        text = ngettext("{n} parameter not approved", "{n} parameters not approved", n)
    elif verdict == "updated by the device":
        text = ngettext("{n} parameter updated by the device", "{n} parameters updated by the device", n)
    elif verdict == LIVE_VALUE:
        text = ngettext("{n} live value", "{n} live values", n)
    else:
        return f"{n} {word(verdict, lang)}"
    return text.format(n=n)


def values_text(d: dict, lang: i18n.Lang | None = None) -> str:
    """Where the parameter values come from and how they compare, one sentence."""
    lang = language(lang)
    _ = lang.gettext
    counts = ", ".join(count_text(k, n, lang) for k, n in d["counts"].items() if n) or _("no parameters")
    return _("Values {source}: {counts}.").format(source=source_text(d["parameters_source"], lang), counts=counts)


def measured_text(v: dict, lang: i18n.Lang | None = None, run: dict | None = None) -> str:
    """A measured value against its limit; its name, value and limit in ``lang`` where ``run`` keeps their templates."""
    _ = language(lang).gettext
    run = run or {}
    value = with_unit(recorded(v["value"], run, lang), v["unit"], lang)
    return "{name} = {value} ({limit}: {verdict})".format(
        name=recorded(v["name"], run, lang), value=value,
        limit=recorded(v["limit"], run, lang) or _("recorded"), verdict=_("ok") if v["ok"] else _("FAIL"))


def evidence_text(s: dict, lang: i18n.Lang | None = None) -> str:
    _ = language(lang).gettext
    f = s.get("evidence_file")
    if not f:
        return _("no bus traffic")
    return _("{name} ({items} {what}), SHA-256 {sha256}").format(name=f["name"], items=f["items"], what=_(f["what"]), sha256=f["sha256"])


def signoff_text(sig: dict | None, what: str, plant: dict | None = None, lang: i18n.Lang | None = None) -> str:
    _ = language(lang).gettext
    if not sig and plant:  # a device of a signed plant: the plant's sign-off covers it
        return _("{what}: no sign-off of its own; signed with the plant (record #{id})").format(what=what, id=plant["id"])
    if not sig:
        return _("{what}: not signed").format(what=what)
    return (_("{what} signed by {name} ({role}), account {account}, on {time}. Comment: {comment}. Record #{id}, content "
              "SHA-256 {sha256}").format(what=what, name=sig["name"], role=sig["role"], account=sig.get("account") or "?",
                                         time=when(sig["time"], lang), comment=sig["comment"] or "-", id=sig["id"], sha256=sig["sha256"])
            + (_(", row hash {hash}").format(hash=sig["row_hash"]) if sig.get("row_hash") else ""))


def _signoff_html(sig: dict | None, what: str, plant: dict | None = None, lang: i18n.Lang | None = None) -> str:
    cls = "sig" if sig or plant else "sig unsigned"
    return f'<div class="{cls}">{_e(signoff_text(sig, what, plant, lang))}</div>'


def summary_rows(d: dict, p: dict | None = None, lang: i18n.Lang | None = None) -> list[str]:
    """The summary of one device a site manager reads: per checkout its last result and runs, the
    approved set, drift and the sign-off."""
    lang = language(lang)
    _ = lang.gettext
    runs = "; ".join(
        f"{recorded(c['title'], c, lang)}: {word(c['last'], lang)}"
        + (f" ({recorded(c['last_reason'], c, lang)})" if c["last"] != "passed" and c["last_reason"] else "")
        + ", " + lang.ngettext("{n} run ({passed} passed, {failed} not)", "{n} runs ({passed} passed, {failed} not)",
                               c["runs"]).format(n=c["runs"], passed=c["passed"], failed=c["failed"])
        + ", " + _("by {people}").format(people=", ".join(c["by"])) for c in d.get("checkout_summary", [])) or _("no checkout run")
    ap = d["approved"]
    approved = _("#{id} by {by}, {time}").format(id=ap["id"], by=ap["by"], time=when(ap["time"], lang)) if ap else _("none")
    drift = (_("no approved set") if not ap else
             _("{n} changed: ").format(n=len(d["drift"])) + ", ".join(f"{r['name']} {r['approved']} -> {r['now']}" for r in d["drift"])
             if d["drift"] else _("none"))
    signed = _signed_word(d, p or {}, lang)
    return [d["device"] + (_(" (simulated)") if d.get("simulated") else ""), d["type"], runs, approved, drift, signed]


SUMMARY_HEAD = [N_("Device"), N_("Type"), N_("Checkouts: last result, runs, who ran them"), N_("Approved set"), N_("Drift"),
                N_("Sign-off")]
SETTING_HEAD = [N_("Setting"), N_("As left"), N_("Approved"), N_("Verdict")]
LIVE_HEAD = [N_("Value"), N_("As read"), N_("At approval"), N_("Verdict")]
RUNS_HEAD = [N_("Run"), N_("Checkout"), N_("Result"), N_("Run by"), N_("Time"), N_("Duration")]
AUDIT_HEAD = [N_("Time"), N_("User"), N_("Action"), N_("Parameter"), N_("Old → new"), N_("Result")]


def head(words: list[str], lang: i18n.Lang | None) -> list[str]:
    return [language(lang).gettext(w) for w in words]


def _rows_html(head_words: list[str], rows: list[list[Any]], classes: dict[int, Any] | None = None) -> str:
    out = "<table><tr>" + "".join(f"<th>{_e(h)}</th>" for h in head_words) + "</tr>"
    for r in rows:
        out += "<tr>" + "".join(
            f'<td class="{_e(classes[i](r))}">{_e(c)}</td>' if classes and i in classes else f"<td>{_e(c)}</td>"
            for i, c in enumerate(r)) + "</tr>"
    return out + "</table>"


class Shown(str):
    """A cell's text in the report's language that keeps the English word it shows (its CSS class)."""

    word: str

    def __new__(cls, text: str, english: str):
        made = super().__new__(cls, text)
        made.word = english
        return made


def param_rows(rows: list[dict], lang: i18n.Lang | None = None) -> list[list[Any]]:
    def approved(text: Any, unit: str) -> Any:  # 12.5 s -> 12,5 s in German; "-" where there is none
        return lang.with_unit(text, unit) if lang is not None and isinstance(text, str) else text

    return [[r["name"], with_unit(r["value"], r["unit"], lang), approved(r["approved"], r["unit"]),
             Shown(word(r["verdict"], lang), r["verdict"])] for r in rows]


def _verdict_class(r: list[Any]) -> str:
    cell = r[-1]
    return (cell.word if isinstance(cell, Shown) else str(cell)).replace(" ", "")


def _result_class(r: list[Any], column: int) -> str:
    cell = r[column]
    return (cell.word if isinstance(cell, Shown) else str(cell)).split(":")[0].replace(" ", "")


def result_cell(status: str, reason: str | None, lang: i18n.Lang | None) -> Shown:
    return Shown(word(status, lang) + (f": {reason}" if reason else ""), status)


def identity_rows(d: dict, lang: i18n.Lang | None = None) -> list[tuple[str, Any]]:
    key, _sep, number = d["address"].partition(" ")  # "address 1": the plant file's key and its value
    address = f"{word(key, lang)} {number}" if key == "address" else d["address"]
    ident = {"type": d["type"], "bus": d["bus"], "address": address, **d["identity"], "status": word(d["status"], lang)}
    return [(word(k, lang), product(v, lang) if k == "product" else v) for k, v in ident.items()]


def product(name: Any, lang: i18n.Lang | None) -> Any:
    """A product's name as the snapshot stored it (``HMR01 (from 08.11.2013)``), as its document names it in ``lang``
    where the device vocabulary has it (``HMR01 ab 08.11.2013``, context ``Product``)."""
    return lang.value_word("Product", name) if lang is not None and isinstance(name, str) else name


def differ_text(d: dict, changed: list, lang: i18n.Lang | None) -> str:
    _ = language(lang).gettext
    return (_(" Settings that differ:") if changed else _(" Every setting equals the approved set.") if d["approved"] else
            _(" The settings read are listed in the appendix."))


def device_html(d: dict, plant_signoff: dict | None = None, *, appendix: bool = True, lang: i18n.Lang | None = None) -> str:
    """One device: its summary (identity, sign-off, drift, every checkout run); ``appendix``: its full
    listings (settings, live values, each step with its evidence file, the audit rows) below."""
    _ = language(lang).gettext
    out = [f'<h2 id="{_e(d["device"])}">{_e(d["device"])} <small>({_e(d["type"])})</small></h2>']
    if d.get("simulated"):
        out.append(f'<div class="sim">{_e(_(SIMULATED_MARK))}</div>')
    out.append(_signoff_html(d["signoff"], d["device"], plant_signoff, lang))
    out.append("<table>" + "".join(f"<tr><th>{_e(k)}</th><td>{_e(v)}</td></tr>" for k, v in identity_rows(d, lang)) + "</table>")
    out.append(f"<p>{_e(commissioned_text(d, bool(plant_signoff), lang))}</p>")
    if d["drift"]:
        out.append('<p class="changed">' + _e(_("Changed since approved: ")
                                              + ", ".join(f"{r['name']} {r['approved']} → {r['now']}" for r in d["drift"])) + "</p>")
    ap = d["approved"]
    changed = [r for r in d.get("settings", d["parameters"]) if r["verdict"] in DIFFERING] if ap else []
    out.append("<h3>" + _e(_("Settings against the approved set")) + "</h3><p>" + _e(
        _("Approved set #{id} ({title}) by {by} on {time}. ").format(id=ap["id"], title=ap["title"], by=ap["by"], time=when(ap["time"], lang))
        if ap else _("No approved set. ")) + _e(values_text(d, lang)) + _e(differ_text(d, changed, lang)) + "</p>")
    if changed:
        out.append(_rows_html(head(SETTING_HEAD[:3], lang) + [""], param_rows(changed, lang), {3: _verdict_class}))
    out.append("<h3>" + _e(_("Checkout runs")) + "</h3>")
    if not d["checkouts"]:
        out.append("<p>" + _e(_("No checkout run.")) + "</p>")
    else:
        out.append(_rows_html(head(RUNS_HEAD, lang), [
            [f"#{c['id']}", recorded(c["title"], c, lang), result_cell(c["status"], recorded(c["reason"], c, lang), lang), c["user"],
             when(c["time"], lang), seconds(c["duration_s"], lang)] for c in d["checkouts"]], {2: lambda r: _result_class(r, 2)}))
    if appendix:
        out.append(appendix_html(d, lang))
    return "\n".join(out)


def measured_answers(s: dict, lang: i18n.Lang | None = None, run: dict | None = None) -> list[str]:
    """A step's measured values and the answers given to it, in ``lang`` where ``run`` keeps their templates."""
    run = run or {}
    return [measured_text(v, lang, run) for v in s["values"]] + [
        f'{recorded(a["question"], run, lang)} {answer_word(a["answer"], lang)} ({a["by"]})' for a in s["answers"]]


def step_detail(s: dict, lang: i18n.Lang | None = None, run: dict | None = None) -> str:
    return "; ".join(measured_answers(s, lang, run) + ([recorded(s["reason"], run or {}, lang)] if s["reason"] else []))


def appendix_html(d: dict, lang: i18n.Lang | None = None) -> str:
    _ = language(lang).gettext
    device = d["device"]
    out = ["<h3>" + _e(_("Appendix {device}: settings").format(device=device)) + "</h3>"]
    out.append(_rows_html(head(SETTING_HEAD[:3], lang) + [""], param_rows(d.get("settings", []), lang), {3: _verdict_class})
               if d.get("settings") else "<p>" + _e(_("No settings read.")) + "</p>")
    out.append("<h3>" + _e(_("Appendix {device}: live values (read with the set; states and measurements, no settings)").format(device=device))
               + "</h3>")
    out.append(_rows_html(head(LIVE_HEAD[:3], lang) + [""], param_rows(d.get("live_values", []), lang), {3: _verdict_class})
               if d.get("live_values") else "<p>" + _e(_("No live values read.")) + "</p>")
    for c in d["checkouts"]:
        out.append("<h3>" + _e(_("Appendix {device}: checkout run #{id}, {title}: {status}").format(
            device=device, id=c["id"], title=recorded(c["title"], c, lang), status=word(c["status"], lang))) + "</h3><p>"
            + _e(_("Run by {user} on {time} in {duration}.").format(user=c["user"], time=when(c["time"], lang),
                                                                    duration=seconds(c["duration_s"], lang))) + "</p>")
        rows = [[recorded(s["name"], c, lang), Shown(word(s["status"], lang), s["status"]), recorded(s["limits"], c, lang),
                 step_detail(s, lang, c), evidence_text(s, lang)] for s in c["steps"]]
        out.append(_rows_html(head([N_("Step"), N_("Result"), N_("Limits"), N_("Measured, answers"), N_("Evidence file")], lang), rows,
                              {1: lambda r: _result_class(r, 1)}))
    out.append("<h3>" + _e(_("Appendix {device}: audit rows ({n})").format(device=device, n=len(d["audit"]))) + "</h3>")
    if d["audit"]:
        out.append(_rows_html(head(AUDIT_HEAD, lang), [
            [when(a["time"], lang), f'{a["user"]} ({a["role"]})', a["action"], a["parameter"], f'{a["old"]} → {a["new"]}', a["result"]]
            for a in d["audit"]]))
    return "\n".join(out)


def cover_lines(p: dict, lang: i18n.Lang | None = None) -> list[str]:
    """The cover's facts: when, with which version, from which plant file, and the record's check."""
    _ = language(lang).gettext
    pf = p.get("plant_file") or {}
    plant_line = (_("Plant file {path}, SHA-256 {sha256}").format(path=pf["path"], sha256=pf["sha256"]) if pf.get("sha256") else
                  _("Plant file {path}: not readable ({error})").format(path=pf["path"], error=pf.get("error", "")) if pf.get("path")
                  else _("Plant file: none (plant given without a file)"))
    check = p.get("record_check") or {}
    head_row = check.get("head")
    lines = [_("Generated {time} with {tool}.").format(time=when(p["generated"], lang), tool=p.get("tool", "commission")), plant_line]
    if check:
        lines.append(_("Record check: {verdict}").format(verdict=_("intact") if check["ok"] else _("ALTERED")) + (
            _("; last row #{id}, hash {hash}").format(id=head_row["id"], hash=head_row["hash"]) if head_row else ""))
    return lines


def altered_text(p: dict, lang: i18n.Lang | None = None) -> str:
    check = p.get("record_check") or {}
    if check.get("ok", True):
        return ""
    return language(lang).gettext("The record was altered outside the program: ") + "; ".join(check["problems"])


def _signed_word(d: dict, p: dict, lang: i18n.Lang | None = None) -> str:
    _ = language(lang).gettext
    return _("signed") if d["signoff"] else _("with the plant") if p.get("signoff") else _("not signed")


def plant_html(p: dict, lang: i18n.Lang | None = None) -> str:
    _ = language(lang).gettext
    sim = f'<div class="sim every">{_e(_(SIMULATED_MARK))}: {_e(", ".join(p["simulated"]))}</div>' if p.get("simulated") else ""
    altered = f'<div class="altered">{_e(altered_text(p, lang))}</div>' if altered_text(p) else ""
    rows = [summary_rows(d, p, lang) for d in p["devices"]]
    summary = _rows_html(head(SUMMARY_HEAD, lang), rows)
    title = _("As-left report {plant}").format(plant=p["plant"])
    return (f"<!doctype html><html lang='{language(lang).code}'><head><meta charset='utf-8'><title>{_e(title)}</title><style>{CSS}</style></head><body>"
            + sim + "<h1>" + _e(_("As-left report: plant {plant}").format(plant=p["plant"])) + "</h1>" + altered
            + "".join(f"<p>{_e(line)}</p>" for line in cover_lines(p, lang))
            + _signoff_html(p["signoff"], _("Plant {plant}").format(plant=p["plant"]), lang=lang) + summary
            + "".join(device_html(d, p["signoff"], appendix=False, lang=lang) for d in p["devices"])
            + "<h2>" + _e(_("Appendix: full listings")) + "</h2>" + "".join(sim + appendix_html(d, lang) for d in p["devices"]) + "</body></html>")


# -- evidence traces and the archive ----------------------------------------------------------------
