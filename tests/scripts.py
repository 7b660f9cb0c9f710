"""Scripted conversations for request/response protocols (as python-canopen's ``test/test_sdo.py``): the
adapter's requests expected in order, ``(TX, bytes)``, each answered with the scripted telegrams that
follow it, ``(RX, bytes)``, after an optional ``(PAUSE, seconds)``. The peer is a TCP server on a free
port: the line under test connects to it through ``socket://`` (serial) or TCP (LogiTed)."""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Iterable

from conftest import free_port

TX, RX, PAUSE = "TX", "RX", "PAUSE"


class Script:
    """A TCP peer that expects the adapter's requests in order and answers each with the scripted bytes.

    :param steps: ``(TX, request)``, ``(RX, answer)`` and ``(PAUSE, seconds)`` in the order they happen
    :param splitter: makes the protocol's frame splitter (``feed(bytes)`` yields items with ``.raw``)
    """

    def __init__(self, steps: Iterable[tuple[str, object]], splitter: Callable[[], object]):
        self.steps = list(steps)
        self.splitter = splitter
        self.seen: list[bytes] = []
        self.problems: list[str] = []
        self.port = free_port()
        self.server = None

    async def __aenter__(self) -> Script:
        self.server = await asyncio.start_server(self._handle, "127.0.0.1", self.port)
        return self

    async def __aexit__(self, *exc) -> None:
        self.server.close()
        await self.server.wait_closed()

    def add(self, *steps: tuple[str, object]) -> None:
        self.steps.extend(steps)

    async def _handle(self, reader, writer) -> None:
        splitter = self.splitter()
        try:
            while True:
                data = await reader.read(4096)
                if not data:
                    return
                for item in splitter.feed(data):
                    raw = getattr(item, "raw", b"")
                    self.seen.append(raw)
                    if not self.steps or self.steps[0][0] != TX:
                        self.problems.append(f"unexpected request {raw.hex(' ')}")
                        continue
                    _, expected = self.steps.pop(0)
                    if raw != expected:
                        self.problems.append(f"expected {expected.hex(' ')}, got {raw.hex(' ')}")
                    while self.steps and self.steps[0][0] in (RX, PAUSE):
                        kind, what = self.steps.pop(0)
                        if kind == PAUSE:
                            await writer.drain()
                            await asyncio.sleep(what)
                        else:
                            writer.write(what)
                    await writer.drain()
        except (ConnectionError, asyncio.CancelledError):
            pass
        finally:
            writer.close()

    def done(self) -> None:
        """Every request was the expected one, and the script ran to its end."""
        assert not self.problems, self.problems
        assert not self.steps, f"not reached: {self.steps[:2]}"
