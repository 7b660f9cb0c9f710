"""What the browser pages of a test did besides what it asserts: reloads, lost connections, script errors.

A browser test that fails on a loaded machine says little about why a typed value or a press did not arrive;
NiceGUI's page reloads itself when its connection cannot be taken up again, and says so on the console. Every page
that playwright opens in a test process is watched (``watch_pages``); a failing test's report gets the events of its
pages as a section of its own (``tests/conftest.py``), with what the apps that the test process started logged
meanwhile: their warnings and errors, and the dead-man's words (a beat late on its way, a session that stopped
confirming it is alive)."""

from __future__ import annotations

import time
from pathlib import Path

import liveapp

EVENTS: list[str] = []  # this test's, emptied before each test
_started = time.monotonic()
WORDS = ("reload", "disconnect", "connect_error", "timed out", "handshake", "notification: ")
# each notification the page shows, said on its console (what a refused or failed press said) once drawn
NOTIFICATIONS = """new MutationObserver((changes) => {
  for (const change of changes) for (const node of change.addedNodes)
    if (node.nodeType === 1 && node.classList.contains("q-notification"))
      setTimeout(() => console.log("notification: " + node.innerText.replace(/\\s+/g, " ").slice(0, 300)), 200);
}).observe(document, {childList: true, subtree: true});"""


def _stamp() -> str:
    return f"{time.monotonic() - _started:8.2f} s"


def watch(page) -> None:
    """Keep ``page``'s navigations, notifications, console lines about its connection, console errors and script
    errors (from its next navigation on: a page is watched before it opens its first address)."""

    def console(message) -> None:
        text = message.text
        if message.type == "error" or any(word in text.lower() for word in WORDS):
            EVENTS.append(f"{_stamp()} {page.url}: console {message.type}: {text[:400]}")

    def navigated(frame) -> None:
        if frame == page.main_frame:
            EVENTS.append(f"{_stamp()} navigated to {frame.url}")

    page.add_init_script(NOTIFICATIONS)
    page.on("console", console)
    page.on("framenavigated", navigated)
    page.on("pageerror", lambda error: EVENTS.append(f"{_stamp()} {page.url}: script error: {str(error)[:400]}"))
    page.on("crash", lambda _page: EVENTS.append(f"{_stamp()} {page.url}: the page crashed"))


def watch_pages() -> None:
    """Every page playwright's sync API opens in this process is watched (patched once, idempotent)."""
    from playwright.sync_api._generated import Browser, BrowserContext

    if getattr(Browser, "_events_watched", False):
        return
    for cls in (Browser, BrowserContext):
        original = cls.new_page

        def new_page(self, *args, _original=original, **kwargs):
            page = _original(self, *args, **kwargs)
            watch(page)
            return page

        cls.new_page = new_page
    Browser._events_watched = True


_LOG_WORDS = (" WARNING ", " ERROR ", " CRITICAL ", "deadman", "Traceback")
_log_offsets: dict[Path, int] = {}  # each app log's size when the test began


def app_logs_began() -> None:
    """Note where each app log of this process stands: what a test's report quotes begins there."""
    for path in liveapp.LOGS:
        try:
            _log_offsets[path] = path.stat().st_size
        except OSError:
            _log_offsets[path] = 0


def app_log_lines(limit: int = 30) -> list[str]:
    """The lines with :data:`_LOG_WORDS` that the apps of this process logged since :func:`app_logs_began` (an app
    started since then from its first line), the last ``limit`` of them."""
    lines = []
    for path in dict.fromkeys(liveapp.LOGS):
        try:
            with open(path, "rb") as log:
                log.seek(_log_offsets.get(path, 0))
                text = log.read(1 << 20).decode(errors="replace")
        except OSError:
            continue
        lines += [f"{path.parent.name}: {line[:400]}" for line in text.splitlines() if any(w in line for w in _LOG_WORDS)]
    return lines[-limit:]
