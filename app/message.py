"""A text that app/ words for someone to read, in the language of whoever reads it (docs/i18n.md).

:class:`~devices.message.Message` (with :func:`joined` and :func:`message_of`) lives in ``devices/message.py``, so
the device layer words its own texts too; here :func:`said` words any of them in a reader's :class:`Lang`::

    raise RecordError(Message(N_("{device}: a checkout is running already"), device=device))
    ...
    ui.notify(said(exc, lang))   # "gate: eine Prüfung läuft bereits"

What was stored as plain text (a record row, an audit row) stays as it was written. A record row that keeps beside
its English a table of the messages it holds (:func:`worded_table`, a checkout run's ``worded``) is worded again
after a restart: :func:`reworded` turns each stored text back into its :class:`Message`.
"""

from __future__ import annotations

from typing import Any

from app.i18n import Lang
from devices.message import Message, Word, joined, message_of

__all__ = ["Message", "joined", "message_of", "reworded", "said", "worded_table"]


def said(text: object, lang: Lang | None) -> str:
    """``text`` in ``lang``: a :class:`Message` (also one an error carries as its message) worded in it; any
    other text as it is."""
    if isinstance(text, BaseException):
        text = message_of(text)
    if isinstance(text, Message):
        return text.text(lang)
    return str(text)


def _form(value: Any) -> Any:
    """A field as the record keeps it: a :class:`Message` as ``{"t": template, "f": fields}``, a :class:`Word` as
    ``{"w": word, "c": context}``, a number or a plain text as it is."""
    if isinstance(value, Message):
        return {"t": value.template, "f": {name: _form(field) for name, field in value.fields.items()}}
    if isinstance(value, Word):
        return {"w": str(value), "c": value.context}
    return value


def _message(form: Any) -> Any:
    """The field :func:`_form` kept, made again."""
    if isinstance(form, dict) and "t" in form:
        return Message(form["t"], **{name: _message(field) for name, field in form.get("f", {}).items()})
    if isinstance(form, dict) and "w" in form:
        return Word(form["w"], form.get("c") or "")
    return form


def worded_table(data: Any, leave_out: tuple[str, ...] = ()) -> dict[str, dict]:
    """Every :class:`Message` in ``data`` (dictionaries and lists, but the keys ``leave_out``), each English text to
    its template and fields: stored beside the English, it lets a reader word the texts again after a restart."""
    table: dict[str, dict] = {}

    def walk(value: Any) -> None:
        if isinstance(value, Message):
            table.setdefault(str(value), _form(value))
        elif isinstance(value, dict):
            for key, item in value.items():
                if key not in leave_out:
                    walk(item)
        elif isinstance(value, list | tuple):
            for item in value:
                walk(item)

    walk(data)
    return table


def reworded(text: Any, table: dict[str, dict] | None) -> Any:
    """A text as the record stored it, made its :class:`Message` again through ``table`` (:func:`worded_table`);
    a text not in it, and one whose template no longer gives the stored English, stays as it was stored."""
    form = (table or {}).get(text) if isinstance(text, str) else None
    if form is None:
        return text
    try:
        message = _message(form)
    except (KeyError, IndexError, TypeError, ValueError):  # a template its fields do not fill
        return text
    return message if message == text else text
