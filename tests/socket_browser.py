"""A browser reduced to what the server sees: the page's HTTP request (with its cookie) and the
page's socket.io connection, driven by hand. For probes that a real browser would not send:
events naming another page's client id, handshakes from another browser, malformed messages.
"""

from __future__ import annotations

import asyncio
import json
import uuid
from dataclasses import dataclass, field
from urllib.parse import urljoin

import httpx
import socketio

MARK = "createApp(parseElements(String.raw`"


@dataclass
class Page:
    """A page as the server built it: its client id and its elements (id -> tag, props, events)."""

    client_id: str
    elements: dict[int, dict]

    def find(self, **props) -> int:
        """The id of the one element whose props include ``props``."""
        found = [i for i, e in self.elements.items() if all(e.get("props", {}).get(k) == v for k, v in props.items())]
        assert len(found) == 1, f"{len(found)} elements with {props}"
        return found[0]

    def listener(self, element: int, event: str) -> str:
        events = self.elements[element].get("events", [])
        found = [e["listener_id"] for e in events if e["type"] == event]
        assert found, f"element {element} has no {event!r} listener: {[e['type'] for e in events]}"
        return found[0]


def parse_page(html: str) -> Page:
    start = html.index(MARK) + len(MARK)
    raw = html[start:html.index("`), {", start)]
    for entity, char in (("&#36;", "$"), ("&#96;", "`"), ("&gt;", ">"), ("&lt;", "<"), ("&amp;", "&")):
        raw = raw.replace(entity, char)
    client_id = html[html.index("'client_id': '") + len("'client_id': '"):]
    return Page(client_id[:client_id.index("'")], {int(k): v for k, v in json.loads(raw).items()})


@dataclass
class SocketBrowser:
    """One browser (one cookie jar) with at most one open page and its socket."""

    base: str
    http: httpx.AsyncClient = field(init=False)
    sio: socketio.AsyncClient | None = None
    page: Page | None = None
    navigations: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.http = httpx.AsyncClient(base_url=self.base, follow_redirects=True, timeout=20)

    async def open(self, path: str, handshake: bool = True) -> Page:
        await self.close_socket()
        response = await self.http.get(path)
        response.raise_for_status()
        self.page = parse_page(response.text)
        self.navigations = []
        if handshake:
            assert await self.connect(self.page.client_id), "the page's own handshake was refused"
        return self.page

    async def connect(self, client_id: str, implicit: bool = False) -> bool:
        """Open a socket with this browser's cookie and hand-shake it for ``client_id`` (in the
        socket's query, as NiceGUI's page script does, with ``implicit``)."""
        await self.close_socket()
        self.sio = socketio.AsyncClient(reconnection=False)
        self.sio.on("open", lambda msg: self.navigations.append(msg.get("path", "") if isinstance(msg, dict) else str(msg)))
        cookie = "; ".join(f"{k}={v}" for k, v in self.http.cookies.items())
        url = self.base
        if implicit:
            url += f"/?client_id={client_id}&tab_id={uuid.uuid4()}&document_id={uuid.uuid4()}&implicit_handshake=true&next_message_id=0"
        try:
            await self.sio.connect(url, socketio_path="/_nicegui_ws/socket.io", transports=["websocket"],
                                   headers={"Cookie": cookie}, wait_timeout=10)
        except socketio.exceptions.ConnectionError:
            return False
        if implicit:
            return True
        answer = await self.sio.call("handshake", {"client_id": client_id, "tab_id": str(uuid.uuid4()),
                                                   "document_id": str(uuid.uuid4()), "next_message_id": 0}, timeout=10)
        return answer is True

    async def sio_connect_query(self, query: str) -> bool:
        """Open a socket with this browser's cookie and a query of one's own; whether it was accepted."""
        await self.close_socket()
        self.sio = socketio.AsyncClient(reconnection=False)
        cookie = "; ".join(f"{k}={v}" for k, v in self.http.cookies.items())
        try:
            await self.sio.connect(f"{self.base}/?{query}", socketio_path="/_nicegui_ws/socket.io", transports=["websocket"],
                                   headers={"Cookie": cookie}, wait_timeout=10)
        except socketio.exceptions.ConnectionError:
            return False
        return True

    async def emit_event(self, element: int, event: str, args: list | None = None, *, page: Page | None = None) -> None:
        """Send what a browser sends for ``event`` on ``element`` of ``page`` (default: this browser's page),
        over this browser's socket."""
        page = page or self.page
        await self.sio.emit("event", {"id": element, "client_id": page.client_id, "listener_id": page.listener(element, event),
                                      "args": [json.dumps(a) for a in (args or [])]})

    async def set_value(self, element: int, value, *, page: Page | None = None) -> None:
        """What a browser sends when a field's value changes (``update:value`` or ``update:modelValue``)."""
        page = page or self.page
        kinds = {e["type"] for e in page.elements[element].get("events", [])}
        await self.emit_event(element, "update:value" if "update:value" in kinds else "update:modelValue", [value], page=page)

    async def follow(self, timeout: float = 15) -> None:
        """Follow the page's next ``ui.navigate.to`` like a browser (the login's ticket)."""
        loop = asyncio.get_running_loop()
        end = loop.time() + timeout
        while not self.navigations:
            assert loop.time() < end, "the page did not navigate"
            await asyncio.sleep(0.05)
        await self.http.get(urljoin(self.base, self.navigations.pop(0)))

    async def login(self, user: str, password: str) -> None:
        page = await self.open("/login")
        name, secret = page.find(label="User"), page.find(label="Password")
        await self.set_value(name, user)
        await self.set_value(secret, password)
        button = next(i for i, e in page.elements.items() if e["tag"] == "q-btn" and e.get("props", {}).get("label") == "Log in")
        await self.emit_event(button, "click", [])
        await self.follow()

    async def close_socket(self) -> None:
        if self.sio is not None:
            await self.sio.disconnect()
            self.sio = None

    async def aclose(self) -> None:
        await self.close_socket()
        await self.http.aclose()
