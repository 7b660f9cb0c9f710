"""CSV exports as the language's spreadsheets read them (issue 47).

In English a comma separates the cells and a point the decimals; in German (decimal comma) a semicolon separates
the cells and the numbers carry a comma, as German spreadsheet programs expect when they open a file. The column
headings are in the language; times stay ISO (``2026-11-28 14:05:09.120``), which every spreadsheet reads; texts
that a spreadsheet would run as a formula are made plain text (:func:`app.audit.csv_cell`).
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Sequence
from typing import Any

from app import i18n


def delimiter(lang: i18n.Lang | None) -> str:
    """``;`` where the decimal sign is a comma (a comma would split the numbers), else ``,``."""
    return ";" if lang is not None and lang.decimal_sign == "," else ","


def cell(value: Any, lang: i18n.Lang | None) -> Any:
    """A number written the language's way (``12,5`` in German, every decimal kept, no grouping); None as empty;
    anything else as it is."""
    if value is None:
        return ""
    if isinstance(value, float) and lang is not None:
        return repr(value).replace(".", lang.decimal_sign)  # every decimal Python keeps; 1e-05 and inf as they are
    return value


def csv_text(head: Sequence[str], rows: Iterable[Sequence[Any]], lang: i18n.Lang | None = None) -> str:
    """The file: ``head`` (texts of the catalog, shown in ``lang``) then ``rows`` (numbers by :func:`cell`)."""
    shown = i18n.english(lang)
    out = io.StringIO()
    writer = csv.writer(out, delimiter=delimiter(lang))
    writer.writerow([shown.gettext(h) for h in head])
    for row in rows:
        writer.writerow([cell(v, lang) for v in row])
    return out.getvalue()
