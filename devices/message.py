"""A text worded for someone to read, in the language of whoever reads it (docs/i18n.md).

What the parameter model refuses, what an adapter diagnoses, what app/ finds or reports is worded before anyone
knows who reads it: a page in German, the command line in English, the audit log and the record (which keep it as
written, in English). A :class:`Message` is that text in English, a ``str`` like any other (compared, stored,
hashed and written as the English it always was), that keeps its marked template and fields, so a page or the
command line words it in its own language (``app.message.said``)::

    raise RecordError(Message(N_("{device}: a checkout is running already"), device=device))
    ...
    ui.notify(said(exc, lang))   # "gate: eine Prüfung läuft bereits"

A field that is a :class:`Message` itself is worded in the same language; a decimal number gets the language's
decimal sign. What was stored as plain text (a record row, an audit row) stays as it was written.

It lives in devices/ so the device layer words its own texts (devices/ imports nothing above it); the language
that words them is anything with ``gettext`` and ``value`` (``app.i18n.Lang``).
"""

from __future__ import annotations

from typing import Any, Protocol


def N_(message: str) -> str:
    """Marks ``message`` for the catalog where it is defined (``pybabel extract -k N_``); it is translated where
    it is shown."""
    return message


class Language(Protocol):
    """What words a :class:`Message`: the catalog's text of a template, a number written the language's way."""

    def gettext(self, message: str) -> str: ...

    def value(self, value: Any, context: str | None = None) -> Any: ...


class Message(str):
    """English ``template`` filled with ``fields``; :meth:`text` words it in another language."""

    template: str
    fields: dict[str, Any]

    def __new__(cls, template: str, /, **fields: Any) -> Message:
        made = super().__new__(cls, template.format(**fields) if fields else template)
        made.template = template
        made.fields = fields
        return made

    def __reduce__(self):  # copies and pickles keep the template, not only the English
        return _rebuild, (self.template, self.fields)

    def text(self, lang: Language | None) -> str:
        """This text in ``lang`` (None: English, as written)."""
        if lang is None or not self.template:  # "" (nothing joined) is not the catalog's header
            return str(self)
        template = lang.gettext(self.template)
        if not self.fields:
            return template
        return template.format(**{name: _field(value, lang) for name, value in self.fields.items()})


def _rebuild(template: str, fields: dict[str, Any]) -> Message:
    return Message(template, **fields)


class Word(str):
    """A device's word as a field of a :class:`Message`: a value of the live point ``context`` (``IrsLine`` of
    ``LockRequestSource``), worded as the catalog has it for that point (``app/device_words.py``)."""

    context: str

    def __new__(cls, word: str, context: str) -> Word:
        made = super().__new__(cls, word)
        made.context = context
        return made

    def __reduce__(self):
        return Word, (str(self), self.context)


def as_word(text: str, context: str) -> str:
    """A point's text as a field: a :class:`Message` as it is, a plain device word as a :class:`Word` of ``context``."""
    return text if isinstance(text, Message) else Word(text, context)


#: a yes/no field (a measured flag, its expected state) in the reader's language: "True" in English, "ja" in German
BOOLEANS = (N_("True"), N_("False"))


def _field(value: Any, lang: Language) -> Any:
    if isinstance(value, bool):
        return lang.gettext(str(value))
    if isinstance(value, Message):
        return value.text(lang)
    if isinstance(value, Word):
        return lang.value(str(value), value.context)
    if isinstance(value, float):
        return lang.value(value)
    return value


def joined(parts: list[str], separator: str = ", ") -> Message:
    """``parts`` (messages or plain texts) joined by ``separator``, each worded in the reader's language."""
    fields = {f"p{n}": part for n, part in enumerate(parts)}
    return Message(separator.join("{%s}" % name for name in fields), **fields)


def message_of(error: BaseException) -> str:
    """What ``error`` says: the :class:`Message` it carries (worded by its reader), else its text."""
    if len(error.args) == 1 and isinstance(error.args[0], Message):
        return error.args[0]
    return str(error)
