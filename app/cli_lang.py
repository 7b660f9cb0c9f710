"""The language of the command line, shared by ``commission`` and every subcommand's module.

``commission`` sets it once (:func:`set_language`, from ``--lang`` or the environment: ``LANGUAGE``,
``LC_ALL``, ``LC_MESSAGES``, ``LANG``) before it builds its parser, so every subcommand's ``--help`` and
messages (``app/dbc.py``, ``report.py``, ``record_cli.py``, ``batch.py``, ``project.py``, ``verify.py``,
``mcap_export.py``) come in that language: each marks its texts with this module's :func:`_`.
"""

from __future__ import annotations

from app import i18n

_current = i18n.get(i18n.DEFAULT)
YES = ("y", "j")  # [y/N] and [j/N]: either is a yes in either language


def lang() -> i18n.Lang:
    """The command line's language now."""
    return _current


def set_language(code: str | None) -> i18n.Lang:
    """The language of the command's messages and help from now on (``code``; None: from the environment)."""
    global _current
    _current = i18n.get(code or i18n.environment_language())
    return _current


def _(message: str) -> str:
    """``message`` in the command line's language."""
    return _current.gettext(message)
