"""German and English: the gettext catalogs of ``locale/`` (managed by pybabel, docs/i18n.md), the language of
a browser and of the command line, and numbers and times written the way each language writes them (Babel).

The source texts are English; ``locale/de`` translates them, ``locale/en`` gives the English texts the German
term of the device documents beside them where an engineer looks it up there. A :class:`Lang` is handed to the
code that draws or prints, never looked up behind its back: a store push that redraws a tile runs outside any
page, and the tile keeps the language of the page it belongs to.
"""

from __future__ import annotations

import copy
import os
import re
import sys
from collections.abc import Iterable, Mapping
from datetime import datetime
from pathlib import Path

from babel import Locale
from babel.dates import format_datetime, format_time
from babel.numbers import format_decimal
from babel.support import NullTranslations, Translations

LANGUAGES = {"en": "English", "de": "Deutsch"}  # code -> the language's own name
DEFAULT = "en"
DOMAIN = "messages"
BABEL_LOCALES = {"en": "en_GB", "de": "de_DE"}  # 24-hour clock in both; decimal point and comma
QUASAR_LANGUAGES = {"en": "en-GB", "de": "de-DE"}  # NiceGUI/Quasar's language packs (date pickers, tables ...)
STORAGE_KEY = "language"  # app.storage.user: the language a browser chose with the switch


def locale_dir() -> Path:
    """The catalogs: ``locale/`` of the checkout, else ``<prefix>/share/commission/locale`` of an installation."""
    here = Path(__file__).resolve().parent.parent / "locale"
    if here.is_dir():
        return here
    return Path(sys.prefix) / "share" / "commission" / "locale"


def N_(message: str) -> str:
    """Marks ``message`` for the catalog where it is defined; it is translated where it is shown."""
    return message


def NP_(context: str, message: str) -> str:
    """Marks a device's word for the catalog with the live point it is a value of as its context (``open`` of
    ``Gate state`` is not ``open`` of ``Session``); :meth:`Lang.phrase` looks it up so."""
    return message


def has_words(text: str) -> bool:
    """Whether ``text`` has words to translate besides its ``{fields}``, numbers and units."""
    return any(c.isalpha() for c in _UNITS.sub("", _FIELDS.sub("", text)))


_NUMBER = re.compile(r"(?<![\w.])-?\d+(?:\.\d+)?(?![\w.])")
_DIGITS = re.compile(r"\d+(?:\.\d+)?")
_FIELDS = re.compile(r"\{[^{}]*\}")
_UNITS = re.compile(r"°C|\b(?:mm/s|mm|ms|s|A|V|%|Inc|kbit/s)\b|\d")
_FORMAT_SPEC = re.compile(r"^(?:[<>=^]?)(?:[+\- ]?)(?:,?)(?:\.(?P<digits>\d+))?(?P<kind>[dfFgGn%]?)$")


class Lang:
    """One language: its catalog and its way of writing numbers and times."""

    def __init__(self, code: str, translations: NullTranslations | None = None):
        self.code = code
        self.locale = Locale.parse(BABEL_LOCALES[code])
        self.translations = translations if translations is not None else _load(code)
        self._probe = _load(code)  # the same catalog with a fallback that says "not there" (see :meth:`has`)
        self._probe.add_fallback(_Absent())
        self.missing: set[str] = set()  # device words shown as they came, for lack of an entry (a test looks)
        self._phrases: dict[tuple[str | None, str], str] = {}

    def __repr__(self) -> str:
        return f"Lang({self.code!r})"

    # -- texts ----------------------------------------------------------------------------------------

    def gettext(self, message: str) -> str:
        return self.translations.gettext(message)

    _ = gettext

    def ngettext(self, singular: str, plural: str, n: int) -> str:
        return self.translations.ngettext(singular, plural, n)

    def pgettext(self, context: str, message: str) -> str:
        return self.translations.pgettext(context, message)

    def unit(self, unit: str) -> str:
        """A unit as this language writes it: the catalog's entry with context ``unit`` (the SCU's ``counts`` are the
        document's ``Flanken``), else as it is (``ms``, ``°C``, ``Inc``)."""
        return self.pgettext("unit", unit) if unit and has_words(unit) else unit

    def value_word(self, point: str, word: str) -> str:
        """A value's name (an enum's) of the register or point ``point`` as the device vocabulary words it in this
        language (``LockState`` ``Unlocked (bolt retracted)``: ``geöffnet (Bolzen eingefahren)``), else as it is."""
        return self.pgettext(point, word) if self.has(word, point) else word

    def with_unit(self, text: str, unit: str) -> str:
        """A value as a parameter model writes it (``60 % or counts/s``) with its numbers and its unit in this language."""
        text = self.numbers_in(text)
        if unit and has_words(unit) and text.endswith(" " + unit):
            text = text[: -len(unit)] + self.unit(unit)
        return text

    def has(self, message: str, context: str | None = None) -> bool:
        """Whether the catalog holds ``message`` (with ``context``), translated or not."""
        found = self._probe.gettext(message) if context is None else self._probe.pgettext(context, message)
        return found is not _ABSENT

    def phrase(self, text: str, context: str | None = None) -> str:
        """A device's word or sentence (a state, a flag, an error, a tile's text) in this language: the catalog's
        entry of it as a value of the point ``context``, else without context; else the entry with its numbers
        as ``{0}``, ``{1}`` ... (``SSR3 fuse blown``, ``out of range (250.3)``); else each comma-separated part
        so, and each part of a list at ``; ``; numbers written the language's way. What is still not found is shown as it came and noted in
        :attr:`missing`."""
        key = (context, text)
        found = self._phrases.get(key)
        if found is None:
            found = self._phrase(text, context)
            if len(self._phrases) < 4096:  # the words of a plant are few; a counter in a text would grow it
                self._phrases[key] = found
        return found

    def _lookup(self, text: str, context: str | None) -> str | None:
        if context and self.has(text, context):
            return self.pgettext(context, text)
        if self.has(text):
            return self.gettext(text)
        return None

    def _phrase(self, text: str, context: str | None) -> str:
        if not text or not has_words(text):
            return self.numbers_in(text)
        found = self._lookup(text, context)
        if found is not None:
            return found
        if "{" not in text:
            numbers = _DIGITS.findall(text)
            if numbers:
                pieces = _DIGITS.split(text)
                pattern = "".join(piece + ("{%d}" % n if n < len(numbers) else "") for n, piece in enumerate(pieces))
                found = self._lookup(pattern, context)
                if found is not None:
                    return found.format(*(self._number_text(n) for n in numbers))
        for separator in ("; ", ", "):  # a list of words: each one looked up
            if separator in text:
                return separator.join(self.phrase(part, context) for part in text.split(separator))
        self.missing.add(text)
        return self.numbers_in(text)

    # -- numbers and times ------------------------------------------------------------------------------

    def number(self, value: float, digits: int | None = None, group: bool = True) -> str:
        """``value`` with ``digits`` decimals (None: as many as it has, at most three), the language's
        decimal sign and digit grouping (``1.234,5`` in German)."""
        if isinstance(value, bool) or not isinstance(value, int | float):
            return str(value)
        pattern = ("#,##0" if group else "0") + ("" if digits == 0 else "." + "0" * digits if digits is not None else ".###")
        if isinstance(value, int) and digits is None:
            pattern = "#,##0" if group else "0"
        return format_decimal(value, format=pattern, locale=self.locale)

    def _number_text(self, text: str) -> str:
        """A number as a device's text wrote it (``21.5``), written this language's way with as many decimals."""
        if "." not in text:
            return text  # a whole number reads alike in both (and keeps its leading zeros: 08:05:09, 0x0A)
        return self.number(float(text), len(text.split(".", 1)[1]), group=False)

    @property
    def decimal_sign(self) -> str:
        """The language's decimal sign: ``,`` in German, ``.`` in English."""
        return self.locale.number_symbols["latn"]["decimal"]

    def numbers_in(self, text: str) -> str:
        """``text`` with each decimal number in it written this language's way (``21.5 °C`` -> ``21,5 °C``)."""
        if self.decimal_sign == ".":
            return text
        return _NUMBER.sub(lambda m: self._number_text(m.group(0)), text)

    def clock(self, t: float | None = None) -> str:
        """The time of day of ``t`` (now when None): ``14:05:09``."""
        return format_time(datetime.fromtimestamp(t) if t is not None else datetime.now(), "HH:mm:ss", locale=self.locale)

    def datetime(self, t: float) -> str:
        """Date and time of ``t`` in the language's medium form: ``28.11.2026, 14:05:09``."""
        return format_datetime(datetime.fromtimestamp(t), "medium", locale=self.locale)

    def age(self, seconds: float | None) -> str:
        """How long ago, in words: ``never``, ``just now``, ``12 s ago``, ``3 min ago``, ``1.5 h ago``."""
        _ = self.gettext
        if seconds is None:
            return _("never")
        if seconds < 1:
            return _("just now")
        if seconds < 120:
            return _("{n} s ago").format(n=self.number(round(seconds)))
        if seconds < 7200:
            return _("{n} min ago").format(n=self.number(round(seconds / 60)))
        return _("{n} h ago").format(n=self.number(seconds / 3600, 1))

    def value(self, value, context: str | None = None):
        """``value`` for ``str.format`` templates: a number or a device word (a value of the point ``context``)
        that formats itself in this language and still compares equal to the value (a tile's conditions see
        the device's value)."""
        if isinstance(value, bool) or value is None:
            return value
        if isinstance(value, int):
            return LocalInt(value, self)
        if isinstance(value, float):
            return LocalFloat(value, self)
        if isinstance(value, str):
            return LocalWord(value, self, context)
        return value


def _format_number(value: float, lang: Lang, spec: str, plain) -> str:
    match = _FORMAT_SPEC.match(spec)
    if match is None:
        return lang.numbers_in(plain(spec))
    digits, kind = match.group("digits"), match.group("kind")
    if kind in ("f", "F", "%"):
        number = value * 100 if kind == "%" else value
        return lang.number(number, int(digits) if digits is not None else 6) + ("%" if kind == "%" else "")
    if kind == "d":
        return lang.number(int(value), 0)
    if isinstance(value, int) and kind in ("", "n"):
        return lang.number(int(value))
    return lang.numbers_in(plain(spec))  # g, G, n and no type: as Python writes it, the decimal sign the language's


class LocalInt(int):
    """An int that writes itself the language's way in ``format`` (``{value}``, ``{value:d}``)."""

    def __new__(cls, value: int, lang: Lang):
        obj = super().__new__(cls, value)
        obj.lang = lang
        return obj

    def __format__(self, spec: str) -> str:
        return _format_number(int(self), self.lang, spec, lambda s: int.__format__(int(self), s))


class LocalFloat(float):
    """A float that writes itself the language's way in ``format`` (``{value:.1f}`` -> ``12,5``)."""

    def __new__(cls, value: float, lang: Lang):
        obj = super().__new__(cls, value)
        obj.lang = lang
        return obj

    def __format__(self, spec: str) -> str:
        return _format_number(float(self), self.lang, spec, lambda s: float.__format__(float(self), s))


class LocalWord(str):
    """A device's word that stays itself for comparisons (``== "lost"``, ``startswith("Error")``) and is written
    in the language in ``format`` (``{text}`` -> ``verloren``)."""

    def __new__(cls, value: str, lang: Lang, context: str | None = None):
        obj = super().__new__(cls, value)
        obj.lang = lang
        obj.context = context
        return obj

    def __format__(self, spec: str) -> str:
        return format(self.lang.phrase(str(self), self.context), spec)


_ABSENT = "\x00absent"


class _Absent(NullTranslations):
    """The last fallback of a probe: a message the catalog lacks comes back as :data:`_ABSENT` itself."""

    def gettext(self, message: str) -> str:
        return _ABSENT

    def pgettext(self, context: str, message: str) -> str:
        return _ABSENT


def _load(code: str) -> NullTranslations:
    return Translations.load(str(locale_dir()), [code], DOMAIN)


_LANGS: dict[str, Lang] = {}


def get(code: str | None) -> Lang:
    """The :class:`Lang` of ``code`` (``de``, ``de_DE``, ``en-GB`` ...); English for anything else."""
    code = normalize(code) or DEFAULT
    lang = _LANGS.get(code)
    if lang is None:
        lang = _LANGS[code] = Lang(code)
    return lang


def english(lang: Lang | None) -> Lang:
    """``lang``, or English where a caller gives none (the texts of code not yet given a page's language)."""
    return lang or get("en")


def normalize(code: str | None) -> str | None:
    """``de_DE.UTF-8`` / ``de-AT`` / ``DE`` -> ``de``; None for a language the tool does not speak."""
    if not code:
        return None
    base = re.split(r"[-_.@]", code.strip(), maxsplit=1)[0].lower()
    return base if base in LANGUAGES else None


def accept_language(header: str | None) -> str:
    """The best of :data:`LANGUAGES` for an ``Accept-Language`` header (RFC 9110 q-values); English if none fits."""
    best, best_q = DEFAULT, -1.0
    for item in (header or "").split(","):
        tag, _sep, params = item.strip().partition(";")
        code = normalize(tag)
        if code is None:
            continue
        q = 1.0
        for param in params.split(";"):
            key, _eq, number = param.strip().partition("=")
            if key == "q":
                try:
                    q = float(number)
                except ValueError:
                    q = 0.0
        if q > best_q and q > 0:  # the first of equal weight wins
            best, best_q = code, q
    return best


def environment_language(environ: Mapping[str, str] | None = None) -> str:
    """The command line's language from the environment, as gettext reads it: ``LANGUAGE`` (a list),
    ``LC_ALL``, ``LC_MESSAGES``, ``LANG``; English for C/POSIX or a language the tool does not speak."""
    environ = os.environ if environ is None else environ
    for key in ("LANGUAGE", "LC_ALL", "LC_MESSAGES", "LANG"):
        value = environ.get(key)
        if not value:
            continue
        for part in value.split(":"):
            code = normalize(part)
            if code is not None:
                return code
        if key != "LANGUAGE":
            return DEFAULT  # the first one set decides (C.UTF-8: English)
    return DEFAULT


def cli_language(argv: Iterable[str] | None = None, environ: Mapping[str, str] | None = None) -> str:
    """``--lang CODE`` (or ``--lang=CODE``) among ``argv``, else :func:`environment_language`. Read before the
    parser is built, since its help texts are in that language."""
    words = list(sys.argv[1:] if argv is None else argv)
    for n, word in enumerate(words):
        if word == "--":
            break
        if word.startswith("--lang="):
            return normalize(word.split("=", 1)[1]) or DEFAULT
        if word == "--lang" and n + 1 < len(words):
            return normalize(words[n + 1]) or DEFAULT
    return environment_language(environ)


# -- the browser's language --------------------------------------------------------------------------------


def _stored() -> str | None:
    from nicegui import app

    try:
        return normalize(app.storage.user.get(STORAGE_KEY))
    except (RuntimeError, AssertionError):  # no per-browser storage here (no session middleware)
        return None


QUERY_KEY = "lang"  # ?lang=de on any page: the switch's links; kept for the browser from then on


def _keep(code: str) -> None:
    from nicegui import app

    try:
        if app.storage.user.get(STORAGE_KEY) != code:
            app.storage.user[STORAGE_KEY] = code
    except (RuntimeError, AssertionError):  # no per-browser storage here: the page itself still gets the language
        pass


def browser_code() -> str:
    """The language of the browser building the current page: the one it asked for with ``?lang=`` (the
    header's switch; kept in its ``app.storage.user`` from then on), else the one it chose before, else its
    ``Accept-Language``."""
    from nicegui import context

    request = context.client.request
    asked = normalize(request.query_params.get(QUERY_KEY)) if request is not None else None
    if asked is not None:
        _keep(asked)
        return asked
    stored = _stored()
    if stored is not None:
        return stored
    return accept_language(request.headers.get("accept-language") if request is not None else None)


def page_language() -> Lang:
    """The language of the page being built, set for NiceGUI/Quasar's own components of this client too
    (``ui.page(language=...)`` is one language for every browser: the client gets its own copy of its page)."""
    from nicegui import context

    code = browser_code()
    client = context.client
    wanted = QUASAR_LANGUAGES[code]
    if client.page.resolve_language() != wanted:
        page = copy.copy(client.page)
        page.language = wanted
        client.page = page
    lang = get(code)
    client.__dict__[CLIENT_KEY] = lang  # what a press on this page answers in (:func:`client_language`)
    return lang


CLIENT_KEY = "commission_lang"


def client_language() -> Lang:
    """The language of the page whose event is being handled (a press, a dialog's answer): the one
    :func:`page_language` gave the page when it was built, English for a page built without it. For the code
    that answers a press (the command client's notifications and questions); what draws gets its ``Lang``
    handed, since a store push runs outside any page."""
    from nicegui import context

    try:
        lang = context.client.__dict__.get(CLIENT_KEY)
    except RuntimeError:  # no page here
        lang = None
    return lang if isinstance(lang, Lang) else get(DEFAULT)


def switch_href(code: str) -> str:
    """This page again in ``code``: its own address with ``?lang=code`` (its other query parameters kept)."""
    from urllib.parse import urlencode

    from nicegui import context

    request = context.client.request
    query = {k: v for k, v in (request.query_params.items() if request is not None else ()) if k != QUERY_KEY}
    return "?" + urlencode({**query, QUERY_KEY: code})


SWITCH_STYLE = "padding: 0 6px; border-radius: 4px; text-decoration: none; font-size: 13px; font-weight: 600; line-height: 22px"
SWITCH_COLOURS = {  # (chosen, the other) on a dark header and on a light card
    True: ("background: #fff; color: #263238", "color: #fff"),
    False: ("background: #1976d2; color: #fff", "color: #1976d2"),
}


def language_switch(lang: Lang, *, dark: bool = True, size: str = "sm"):
    """``DE | EN`` for a page's header: two links to the page itself in the other language (``?lang=``), so a
    page with nothing to press (the plant view) has nothing to press here either; the choice is kept per
    browser. ``size="md"``: a finger's width on a tablet."""
    from nicegui import ui

    chosen, other = SWITCH_COLOURS[dark]
    padding = "; padding: 4px 10px; font-size: 16px" if size == "md" else ""
    label = lang.gettext("Language")
    with ui.element("span").style("display: inline-flex; gap: 2px; align-items: center").props(
            f'data-testid=language role=group aria-label="{label}"') as box:
        for code, name in LANGUAGES.items():
            current = code == lang.code
            ui.link(code.upper(), switch_href(code)).style(f"{SWITCH_STYLE}; {chosen if current else other}{padding}").props(
                f'data-lang={code} hreflang={code} lang={code} title="{name}"' + (' aria-current="true"' if current else ""))
    return box
