"""The browser's own files (scripts, styles, fonts, components, plot libraries) from memory.

NiceGUI serves them from disk for every new page: each file in 64 kB pieces, every piece
read in a worker thread and then compressed on the event loop (gzip level 9, some 45 ms
of the loop's time for a page's core files, about 200 ms more for the plot library). With
many pages open the loop is busy and every hop waits for it, so a new page waited 0.1 to
0.4 s for each file, and the compressing held up every keep-alive meanwhile.

These files cannot change while the program runs (their addresses carry NiceGUI's
version), so :class:`AssetCache` keeps each one compressed in memory after its first
request (compressed once, in a worker thread) and answers later requests in one piece,
without a thread or a compressor. The cache is bounded; what does not fit is served as
before.
"""

from __future__ import annotations

import asyncio
import gzip
import logging
import re
from dataclasses import dataclass
from pathlib import Path

import nicegui
from nicegui import __version__ as NICEGUI_VERSION

log = logging.getLogger(__name__)

PREFIX = f"/_nicegui/{NICEGUI_VERSION}/"
# generated per request (not files): always passed through
UNCACHED = ("dynamic_resources/",)
LIMIT_BYTES = 32 * 1024 * 1024  # NiceGUI's files with the plot library take about 2 MB compressed
GZIP_LEVEL = 9  # once per file, in a thread: the smallest transfer costs nothing later


def _text_font() -> str | None:
    """The file of NiceGUI's Roboto for Latin text (the one every label is drawn in), from its fonts.css."""
    try:
        css = (Path(nicegui.__file__).parent / "static" / "fonts.css").read_text(encoding="utf-8")
    except OSError:
        return None
    for block in re.findall(r"@font-face\s*{([^}]*)}", css):
        if '"Roboto"' in block and "U+0000-00FF" in block:
            found = re.search(r"url\((fonts/[\w.-]+\.woff2)\)", block)
            if found:
                return found.group(1)
    return None


TAILWIND_CSS = Path(__file__).resolve().parent.parent / "static" / "tailwind.css"


def tailwind_style() -> str:
    """The Tailwind rules of the pages' classes, compiled beforehand (tools/stylesheet.py) instead
    of in every browser: the app runs NiceGUI with ``tailwind=False``."""
    try:
        return f"<style>{TAILWIND_CSS.read_text(encoding='utf-8')}</style>"
    except OSError as exc:
        log.error("the pages' stylesheet is missing (%s): layouts will look wrong; "
                  "run `python -m tools.stylesheet` in the source folder", exc)
        return ""


def preload_links() -> str:
    """Fetched by every page as soon as its head is read, not once the script or stylesheet asking
    for them has arrived and run: the sanitiser NiceGUI's module script imports, and the text font
    (chromium draws no text in a font that is still loading)."""
    links = [f'<link rel="modulepreload" href="{PREFIX}static/dompurify.mjs">']
    font = _text_font()
    if font:
        links.append(f'<link rel="preload" as="font" type="font/woff2" crossorigin href="{PREFIX}static/{font}">')
    return "\n".join(links)


@dataclass(frozen=True)
class Entry:
    headers: list[tuple[bytes, bytes]]  # as the app answered, without content-length/encoding
    body: bytes
    gzipped: bool  # body is gzip (else the file did not get smaller: fonts, images)
    etag: bytes | None


def _header(headers: list[tuple[bytes, bytes]], name: bytes) -> bytes | None:
    for key, value in headers:
        if key.lower() == name:
            return value
    return None


def _compress(body: bytes) -> bytes:
    return gzip.compress(body, compresslevel=GZIP_LEVEL, mtime=0)


class AssetCache:
    """ASGI middleware: NiceGUI's versioned files from memory, compressed once."""

    def __init__(self, asgi_app, limit_bytes: int = LIMIT_BYTES, prefix: str = PREFIX):
        self.app = asgi_app
        self.limit_bytes = limit_bytes
        self.prefix = prefix
        self.entries: dict[str, Entry] = {}
        self.size = 0
        self.hits = 0

    def _cacheable(self, scope) -> bool:
        path = scope.get("path", "")
        if scope["type"] != "http" or scope.get("method") not in ("GET", "HEAD") or not path.startswith(self.prefix):
            return False
        return not path[len(self.prefix):].startswith(UNCACHED)

    async def __call__(self, scope, receive, send):
        if not self._cacheable(scope):
            return await self.app(scope, receive, send)
        headers = dict(scope.get("headers", []))
        if b"range" in headers:  # a part of a file: the app answers it
            return await self.app(scope, receive, send)
        key = scope["path"] + ("?" + scope["query_string"].decode("latin-1") if scope.get("query_string") else "")
        entry = self.entries.get(key)
        if entry is None:
            if scope["method"] != "GET":
                return await self.app(scope, receive, send)
            entry = await self._load(key, scope, receive, send)
            if entry is None:
                return None  # already answered by the app
        if entry.gzipped and b"gzip" not in headers.get(b"accept-encoding", b""):
            return await self.app(scope, receive, send)  # a client without gzip: rare, served from disk
        self.hits += 1
        await self._answer(entry, scope, headers, send)
        return None

    async def _answer(self, entry: Entry, scope, headers: dict, send) -> None:
        if entry.etag is not None and headers.get(b"if-none-match") == entry.etag:
            out = [(k, v) for k, v in entry.headers if k in (b"etag", b"cache-control", b"last-modified", b"vary")]
            await send({"type": "http.response.start", "status": 304, "headers": out})
            await send({"type": "http.response.body", "body": b""})
            return
        out = list(entry.headers) + [(b"content-length", str(len(entry.body)).encode())]
        if entry.gzipped:
            out += [(b"content-encoding", b"gzip"), (b"vary", b"Accept-Encoding")]
        await send({"type": "http.response.start", "status": 200, "headers": out})
        await send({"type": "http.response.body", "body": b"" if scope["method"] == "HEAD" else entry.body})

    async def _load(self, key: str, scope, receive, send) -> Entry | None:
        """The app's answer to the first request for ``key``: kept if it is a whole file, else passed on."""
        plain = {**scope, "headers": [(k, v) for k, v in scope.get("headers", []) if k.lower() not in
                                       (b"accept-encoding", b"if-none-match", b"if-modified-since")]}
        messages: list[dict] = []

        async def capture(message) -> None:
            messages.append(message)

        await self.app(plain, receive, capture)
        start = next((m for m in messages if m["type"] == "http.response.start"), None)
        body = b"".join(m.get("body", b"") for m in messages if m["type"] == "http.response.body")
        complete = (start is not None and start["status"] == 200
                    and all(m["type"] in ("http.response.start", "http.response.body") for m in messages))
        headers = [(k.lower(), v) for k, v in (start or {}).get("headers", [])]
        if not complete or _header(headers, b"content-encoding") is not None:
            for message in messages:  # not a plain file: the app's own answer, as it gave it
                await send(message)
            return None
        compressed = await asyncio.to_thread(_compress, body)
        gzipped = len(compressed) < len(body)
        kept = [(k, v) for k, v in headers if k not in (b"content-length", b"content-encoding", b"vary")]
        entry = Entry(kept, compressed if gzipped else body, gzipped, _header(headers, b"etag"))
        if key not in self.entries and self.size + len(entry.body) <= self.limit_bytes:
            self.entries[key] = entry
            self.size += len(entry.body)
        elif key not in self.entries:
            log.info("asset cache full (%d kB): %s is served from disk", self.size // 1024, key)
        return entry
