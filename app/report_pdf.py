"""The as-left report as a PDF (ReportLab), from the same content as its HTML (``app/report.py``): the summary
on the first page, each device on a page of its own where it fits, the full listings in the appendix, the
simulated mark on every page; in the language chosen when it is made."""

from __future__ import annotations

import html
import io
from typing import Any

from app import i18n
from app.i18n import N_
from app.report import (
    DIFFERING,
    LIVE_HEAD,
    RUNS_HEAD,
    SETTING_HEAD,
    SIMULATED_MARK,
    SUMMARY_HEAD,
    altered_text,
    commissioned_text,
    cover_lines,
    differ_text,
    evidence_text,
    head,
    identity_rows,
    language,
    measured_answers,
    param_rows,
    recorded,
    result_cell,
    seconds,
    signoff_text,
    summary_rows,
    values_text,
    when,
    word,
)


def _escape(value: Any) -> str:
    """A text for a ReportLab paragraph, whose markup is HTML's."""
    return html.escape("" if value is None else str(value))


def plant_pdf(p: dict, lang: i18n.Lang | None = None) -> bytes:
    _ = language(lang).gettext
    from reportlab.lib import colors
    from reportlab.lib.pagesizes import A4
    from reportlab.lib.styles import getSampleStyleSheet
    from reportlab.lib.units import mm
    from reportlab.platypus import (
        KeepTogether,
        PageBreak,
        Paragraph,
        SimpleDocTemplate,
        Spacer,
        Table,
        TableStyle,
    )

    styles = getSampleStyleSheet()
    small = styles["BodyText"].clone("small", fontSize=7.5, leading=9)
    warn = styles["BodyText"].clone("warn", textColor=colors.HexColor("#b71c1c"), fontName="Helvetica-Bold")
    buf = io.BytesIO()
    doc = SimpleDocTemplate(buf, pagesize=A4, leftMargin=14 * mm, rightMargin=14 * mm, topMargin=18 * mm, bottomMargin=16 * mm,
                            title=_("As-left report {plant}").format(plant=p["plant"]), author=p.get("tool", "commission"))
    width = A4[0] - 28 * mm
    simulated = bool(p.get("simulated"))

    def every_page(canvas, document) -> None:  # the simulated mark on every page, the page number at the foot
        canvas.saveState()
        if simulated:
            canvas.setFillColor(colors.HexColor("#fff3cd"))
            canvas.rect(14 * mm, A4[1] - 13 * mm, width, 7 * mm, fill=1, stroke=0)
            canvas.setFillColor(colors.HexColor("#5d4200"))
            canvas.setFont("Helvetica-Bold", 9)
            canvas.drawCentredString(A4[0] / 2, A4[1] - 10.8 * mm, _(SIMULATED_MARK))
        canvas.setFillColor(colors.grey)
        canvas.setFont("Helvetica", 7)
        canvas.drawString(14 * mm, 8 * mm, _("As-left report {plant}").format(plant=p["plant"]) + f", {when(p['generated'], lang)}")
        canvas.drawRightString(A4[0] - 14 * mm, 8 * mm, _("page {n}").format(n=document.page))
        canvas.restoreState()

    def para(text: Any, style=small) -> Paragraph:
        return Paragraph(_escape(text), style)

    def table(rows: list[list[Any]], widths: list[float], style=small) -> Table:
        t = Table([[para(c, style if i else small) for i, c in enumerate(r)] for r in rows], colWidths=[w * width for w in widths], repeatRows=1)
        t.setStyle(TableStyle([("GRID", (0, 0), (-1, -1), 0.3, colors.grey), ("BACKGROUND", (0, 0), (-1, 0), colors.whitesmoke),
                               ("VALIGN", (0, 0), (-1, -1), "TOP")]))
        return t

    def sig(s: dict | None, what: str) -> Paragraph:
        plant = p.get("signoff") if what != plant_what else None
        return para(signoff_text(s, what, plant, lang), styles["BodyText"])

    plant_what = _("Plant {plant}").format(plant=p["plant"])
    story: list = [Paragraph(_escape(_("As-left report: plant {plant}").format(plant=p["plant"])), styles["Title"])]
    if altered_text(p):
        story.append(para(altered_text(p, lang), warn))
    story += [para(line, styles["BodyText"]) for line in cover_lines(p, lang)]
    story += [sig(p["signoff"], plant_what), Spacer(1, 4 * mm),
              table([head(SUMMARY_HEAD, lang)] + [summary_rows(d, p, lang) for d in p["devices"]], [0.13, 0.08, 0.37, 0.16, 0.14, 0.12])]
    story.append(para(_("Each device follows on the next pages; the full listings (settings, live values, every step with its "
                        "evidence file and SHA-256, audit rows) are in the appendix."), small))
    story.append(PageBreak())
    for d in p["devices"]:  # each device kept on one page where it fits, one after the other
        part = [Paragraph(_escape(f"{d['device']} ({d['type']})"), styles["Heading2"]), sig(d["signoff"], d["device"])]
        part.append(table([[_("Identity"), ""]] + [[k, v] for k, v in identity_rows(d, lang)], [0.3, 0.7]))
        part.append(para(commissioned_text(d, bool(p.get("signoff")), lang)))
        if d["drift"]:
            part.append(para(_("Changed since approved: ") + ", ".join(f"{r['name']} {r['approved']} -> {r['now']}" for r in d["drift"]), warn))
        part.append(Paragraph(_escape(_("Settings against the approved set")), styles["Heading3"]))
        changed = [r for r in d.get("settings", []) if r["verdict"] in DIFFERING] if d["approved"] else []
        part.append(para(values_text(d, lang) + differ_text(d, changed, lang)))
        if changed:
            part.append(table([head(SETTING_HEAD, lang)] + param_rows(changed, lang), [0.4, 0.25, 0.2, 0.15]))
        part.append(Paragraph(_escape(_("Checkout runs")), styles["Heading3"]))
        if not d["checkouts"]:
            part.append(para(_("No checkout run.")))
        else:
            part.append(table([head(RUNS_HEAD, lang)] + [
                [f"#{c['id']}", recorded(c["title"], c, lang), result_cell(c["status"], recorded(c["reason"], c, lang), lang),
                 c["user"], when(c["time"], lang), seconds(c["duration_s"], lang)] for c in d["checkouts"]],
                [0.07, 0.2, 0.37, 0.12, 0.15, 0.09]))
        story += [KeepTogether(part), Spacer(1, 6 * mm)]
    story += [PageBreak(), Paragraph(_escape(_("Appendix: full listings")), styles["Heading1"])]
    for d in p["devices"]:
        device = d["device"]
        story.append(Paragraph(_escape(_("{device} ({type}): settings").format(device=device, type=d["type"])), styles["Heading3"]))
        story.append(table([head(SETTING_HEAD, lang)] + param_rows(d.get("settings", []), lang), [0.4, 0.25, 0.2, 0.15])
                     if d.get("settings") else para(_("No settings read.")))
        story.append(Paragraph(_escape(_("{device}: live values (states and measurements, no settings)").format(device=device)), styles["Heading3"]))
        story.append(table([head(LIVE_HEAD, lang)] + param_rows(d.get("live_values", []), lang), [0.4, 0.25, 0.2, 0.15])
                     if d.get("live_values") else para(_("No live values read.")))
        for c in d["checkouts"]:
            story.append(Paragraph(_escape(_("{device}: checkout run #{id}, {title}: {status}").format(
                device=device, id=c["id"], title=recorded(c["title"], c, lang), status=word(c["status"], lang))), styles["Heading3"]))
            story.append(para(_("Run by {user} on {time} in {duration}.").format(user=c["user"], time=when(c["time"], lang),
                                                                                  duration=seconds(c["duration_s"], lang))))
            story.append(table([head([N_("Step"), N_("Result"), N_("Measured, answers"), N_("Evidence file, SHA-256")], lang)] + [
                [recorded(s["name"], c, lang), result_cell(s["status"], recorded(s["reason"], c, lang), lang),
                 "; ".join(measured_answers(s, lang, c)), evidence_text(s, lang)] for s in c["steps"]], [0.18, 0.2, 0.34, 0.28]))
        if d["audit"]:
            story.append(Paragraph(_escape(_("{device}: audit rows ({n})").format(device=device, n=len(d["audit"]))), styles["Heading3"]))
            story.append(table([head([N_("Time"), N_("User"), N_("Action"), N_("Parameter"), N_("Old -> new"), N_("Result")], lang)] + [
                [when(a["time"], lang), a["user"], a["action"], a["parameter"], f"{a['old']} -> {a['new']}", a["result"]] for a in d["audit"]],
                [0.15, 0.1, 0.2, 0.15, 0.2, 0.2]))
    doc.build(story, onFirstPage=every_page, onLaterPages=every_page)
    return buf.getvalue()


