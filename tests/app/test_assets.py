"""NiceGUI's files from memory, compressed once (app/assets.py)."""

from __future__ import annotations

import gzip
import os

import httpx
import pytest
from starlette.applications import Starlette
from starlette.responses import PlainTextResponse
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from app.assets import PREFIX, AssetCache, preload_links

SCRIPT = b"const answer = 42;\n" * 20_000  # 380 kB: served from disk in several pieces
FONT = os.urandom(40_000)  # does not compress


@pytest.fixture
def served(tmp_path):
    (tmp_path / "app.js").write_bytes(SCRIPT)
    (tmp_path / "font.woff2").write_bytes(FONT)
    calls = []

    async def dynamic(request):
        return PlainTextResponse("made now " * 100)

    inner = Starlette(routes=[Route(PREFIX + "dynamic_resources/x", dynamic),
                              Mount(PREFIX + "static", StaticFiles(directory=tmp_path))])

    async def counting(scope, receive, send):
        if scope["type"] == "http":
            calls.append(scope["path"])
        await inner(scope, receive, send)

    cache = AssetCache(counting)
    client = httpx.AsyncClient(transport=httpx.ASGITransport(app=cache), base_url="http://127.0.0.1")
    return cache, client, calls


async def test_a_file_is_read_once_and_then_answered_from_memory_compressed(served) -> None:
    cache, client, calls = served
    async with client:
        first = await client.get(PREFIX + "static/app.js", headers={"accept-encoding": "gzip"})
        second = await client.get(PREFIX + "static/app.js", headers={"accept-encoding": "gzip"})
    assert calls == [PREFIX + "static/app.js"], "the second request must not reach the app"
    for answer in (first, second):
        assert answer.status_code == 200
        assert answer.headers["content-encoding"] == "gzip"
        assert answer.content == SCRIPT  # httpx decodes
        assert "javascript" in answer.headers["content-type"]
        assert int(answer.headers["content-length"]) == len(gzip.compress(SCRIPT, 9, mtime=0))
    assert cache.hits == 2 and cache.size < len(SCRIPT) / 10


async def test_an_incompressible_file_is_kept_as_it_is(served) -> None:
    cache, client, calls = served
    async with client:
        for _ in range(2):
            answer = await client.get(PREFIX + "static/font.woff2", headers={"accept-encoding": "gzip"})
            assert answer.content == FONT and "content-encoding" not in answer.headers
    assert len(calls) == 1 and cache.size == len(FONT)


async def test_revalidation_head_and_clients_without_gzip(served) -> None:
    cache, client, calls = served
    async with client:
        first = await client.get(PREFIX + "static/app.js", headers={"accept-encoding": "gzip"})
        etag = first.headers["etag"]
        unchanged = await client.get(PREFIX + "static/app.js", headers={"accept-encoding": "gzip", "if-none-match": etag})
        assert unchanged.status_code == 304 and unchanged.content == b""
        head = await client.head(PREFIX + "static/app.js", headers={"accept-encoding": "gzip"})
        assert head.status_code == 200 and head.content == b""
        plain = await client.get(PREFIX + "static/app.js", headers={"accept-encoding": "identity"})
        assert plain.content == SCRIPT and "content-encoding" not in plain.headers
    assert len(calls) == 2, "only the client without gzip goes to the disk again"


async def test_missing_files_ranges_and_generated_answers_go_to_the_app(served) -> None:
    cache, client, calls = served
    async with client:
        for _ in range(2):
            missing = await client.get(PREFIX + "static/nothing.js")
            assert missing.status_code == 404
        part = await client.get(PREFIX + "static/app.js", headers={"range": "bytes=0-9"})
        assert part.status_code == 206 and part.content == SCRIPT[:10]
        for _ in range(2):
            made = await client.get(PREFIX + "dynamic_resources/x")
            assert made.text.startswith("made now")
    assert len(calls) == 5 and cache.entries == {}


async def test_the_cache_is_bounded(served) -> None:
    cache, client, calls = served
    cache.limit_bytes = 100  # less than either file, compressed
    async with client:
        for _ in range(2):
            answer = await client.get(PREFIX + "static/app.js", headers={"accept-encoding": "gzip"})
            assert answer.content == SCRIPT
    assert cache.entries == {} and len(calls) == 2


def test_preloads_name_files_nicegui_has() -> None:
    import re
    from pathlib import Path

    import nicegui

    static = Path(nicegui.__file__).parent / "static"
    hrefs = re.findall(r'href="([^"]+)"', preload_links())
    assert len(hrefs) == 2, "the sanitiser module and the text font"
    for href in hrefs:
        assert href.startswith(PREFIX + "static/")
        assert (static / href[len(PREFIX + "static/"):]).is_file(), href
