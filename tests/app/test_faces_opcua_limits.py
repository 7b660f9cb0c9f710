"""What an anonymous OPC UA client may take (issue 41, items 2 and 10): RegisterServer refused,
subscriptions and monitored items per session, sessions and idle connections per client address,
message and chunk sizes bounded; and the log lines such clients cause are bounded."""

from __future__ import annotations

import asyncio
import logging
import socket

import pytest
from asyncua import Client, ua
from conftest import free_port, one_device_store

from app import opcua_server
from app.opcua_server import OpcuaServer
from app.plant import parse_plant

pytestmark = pytest.mark.timeout(90)


@pytest.fixture
async def server():
    port = free_port()
    plant = parse_plant(f'name = "p"\n[opcua]\nendpoint = "opc.tcp://127.0.0.1:{port}"\n')
    store, _ = one_device_store("pump")
    srv = OpcuaServer(plant.opcua, store, plant)
    await srv.start()
    srv.url = f"opc.tcp://127.0.0.1:{port}"
    srv.port = port
    try:
        yield srv
    finally:
        await srv.stop()


def _registered(n: int) -> ua.RegisteredServer:
    entry = ua.RegisteredServer()
    entry.ServerUri = f"urn:forged:{n}"
    entry.ProductUri = "x" * 4000
    entry.ServerNames = [ua.LocalizedText(f"forged {n}")]
    entry.ServerType = ua.ApplicationType.Server
    entry.DiscoveryUrls = [f"opc.tcp://10.0.0.{n % 250}:4840"]
    entry.IsOnline = True
    return entry


async def test_register_server_is_refused(server):
    async with Client(server.url, timeout=5) as client:
        for n in range(3):
            with pytest.raises(ua.UaStatusCodeError):
                await client.uaclient.register_server(_registered(n))
        servers = await client.find_servers()
        assert [s.ApplicationUri for s in servers] == ["urn:commission:p"]


async def test_subscriptions_per_session_are_bounded(server):
    client = Client(server.url, timeout=5)
    other = Client(server.url, timeout=5)
    await client.connect()
    await other.connect()
    try:
        made = 0
        with pytest.raises(ua.UaStatusCodeError) as refused:
            for _ in range(opcua_server.MAX_SUBSCRIPTIONS_PER_SESSION + 1):
                await client.create_subscription(1000, None)
                made += 1
        assert made == opcua_server.MAX_SUBSCRIPTIONS_PER_SESSION
        assert refused.value.code == ua.StatusCodes.BadTooManySubscriptions
        await other.create_subscription(1000, None)  # the next client still gets one
    finally:
        await client.disconnect()
        await other.disconnect()


async def test_monitored_items_per_request_are_bounded(server):
    async with Client(server.url, timeout=5) as client:
        sub = await client.create_subscription(1000, None)
        node = client.get_node(ua.ObjectIds.Server_ServerStatus_CurrentTime)
        with pytest.raises(ua.UaStatusCodeError) as refused:
            await sub.subscribe_data_change([node] * (opcua_server.MAX_MONITORED_ITEMS_PER_SESSION + 1))
        assert refused.value.code == ua.StatusCodes.BadTooManyMonitoredItems


async def test_sessions_per_client_address_are_bounded(server):
    clients = []
    try:
        for _ in range(opcua_server.MAX_SESSIONS_PER_CLIENT):
            client = Client(server.url, timeout=5)
            await client.connect()
            clients.append(client)
        extra = Client(server.url, timeout=5)
        with pytest.raises((ua.UaStatusCodeError, ua.UaError)):
            await extra.connect()
        await extra.disconnect()
    finally:
        for client in clients:
            await client.disconnect()


async def _connections(port: int, n: int, gap_s: float = 0.0) -> list[socket.socket]:
    """``n`` plain TCP connections to ``port`` that send nothing (``gap_s`` apart), not blocking."""
    socks = []
    for _ in range(n):
        sock = socket.create_connection(("127.0.0.1", port))
        sock.setblocking(False)
        socks.append(sock)
        if gap_s:
            await asyncio.sleep(gap_s)
    return socks


async def _closed(sock: socket.socket, within_s: float) -> bool:
    """Whether the server closed ``sock`` (it reads the end within ``within_s``)."""
    try:
        return await asyncio.wait_for(asyncio.get_running_loop().sock_recv(sock, 1), within_s) == b""
    except (asyncio.TimeoutError, ConnectionError):
        return False


async def test_idle_connections_of_one_address_are_bounded_and_a_real_client_gets_in(server):
    idle = await _connections(server.port, opcua_server.MAX_IDLE_PER_CLIENT * 3, gap_s=0.01)
    await asyncio.sleep(0.3)  # the server's idle limit has time to close the surplus connections
    still_open = [s for s in idle if not await _closed(s, 0.05)]
    assert len(still_open) <= opcua_server.MAX_IDLE_PER_CLIENT, len(still_open)
    client = Client(server.url, timeout=5)
    await client.connect()
    await client.disconnect()
    for sock in idle:
        sock.close()


async def test_limits_of_the_transport_and_the_server(server):
    limits = server.server.limits
    assert limits.max_message_size <= 4 * 1024 * 1024 and limits.max_chunk_count <= 64
    iserver = server.server.iserver
    assert iserver.max_connections <= 256 and iserver.max_pending_activation_seconds <= 15
    assert iserver.max_subscriptions <= 500 and iserver.max_session_timeout_ms <= 120_000


async def test_outsiders_cannot_fill_the_log(server, caplog):
    caplog.set_level(logging.INFO)
    async with Client(server.url, timeout=5) as client:
        for n in range(200):
            with pytest.raises(ua.UaStatusCodeError):
                await client.uaclient.register_server(_registered(n))
    server_lines = [r for r in caplog.records if r.name.startswith(("asyncua.server", "app.opcua_server"))]
    assert len(server_lines) <= 60, f"{len(server_lines)} log lines for 200 refused requests"


async def test_a_chunk_announced_larger_than_the_limit_closes_the_connection(server):
    loop = asyncio.get_running_loop()
    sock = socket.create_connection(("127.0.0.1", server.port))
    sock.setblocking(False)
    try:
        header = b"MSGC" + (50 * 1024 * 1024).to_bytes(4, "little")  # an unfinished chunk of 50 MB
        try:
            await loop.sock_sendall(sock, header)
            for _ in range(64):
                await loop.sock_sendall(sock, b"\0" * 16384)
            closed = await asyncio.wait_for(loop.sock_recv(sock, 1), 3) == b""
        except ConnectionError:
            closed = True  # closed by the server while this was still sending
        except asyncio.TimeoutError:
            closed = False
        assert closed, "the server keeps buffering an unfinished chunk"
    finally:
        sock.close()


async def test_new_connections_per_client_address_are_rate_limited(server):
    socks = await _connections(server.port, opcua_server.CONNECTION_BURST * 3)
    shut = [s for s in socks if await _closed(s, 0.2)]
    assert len(shut) >= opcua_server.CONNECTION_BURST, f"{len(shut)} of {len(socks)} closed at once"
    for sock in socks:
        sock.close()
    await asyncio.sleep(1.0)  # the bucket fills again: a real client gets in
    client = Client(server.url, timeout=5)
    await client.connect()
    await client.disconnect()
