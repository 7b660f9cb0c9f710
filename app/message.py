"""A text that app/ words for someone to read, in the language of whoever reads it (docs/i18n.md).

:class:`~devices.message.Message` (with :func:`joined` and :func:`message_of`) lives in ``devices/message.py``, so
the device layer words its own texts too; here :func:`said` words any of them in a reader's :class:`Lang`::

    raise RecordError(Message(N_("{device}: a checkout is running already"), device=device))
    ...
    ui.notify(said(exc, lang))   # "gate: eine Prüfung läuft bereits"

What was stored as plain text (a record row, an audit row) stays as it was written.
"""

from __future__ import annotations

from app.i18n import Lang
from devices.message import Message, joined, message_of

__all__ = ["Message", "joined", "message_of", "said"]


def said(text: object, lang: Lang | None) -> str:
    """``text`` in ``lang``: a :class:`Message` (also one an error carries as its message) worded in it; any
    other text as it is."""
    if isinstance(text, BaseException):
        text = message_of(text)
    if isinstance(text, Message):
        return text.text(lang)
    return str(text)
