"""A read-only OPC UA server (asyncua) with the Devices (DI) information model: ``[opcua]`` in the plant file.

asyncua ships no DI nodeset, so the part of OPC 10000-100 (DI) this server uses is modelled here in the DI
namespace ``http://opcfoundation.org/UA/DI/`` with the DI node ids: ``TopologyElementType`` (i=1001) ->
``ComponentType`` (i=15063) -> ``DeviceType`` (i=1002) with the mandatory identification properties
Manufacturer, Model, SerialNumber, SoftwareRevision, HardwareRevision, DeviceRevision, RevisionCounter and
the ``DeviceHealth`` variable of ``DeviceHealthEnumeration`` (i=6244: NORMAL, FAILURE, CHECK_FUNCTION,
OFF_SPEC, MAINTENANCE_REQUIRED, NAMUR NE 107), the ``ParameterSet`` component, and ``DeviceSet`` (i=5001)
under Objects. One ``DeviceType`` object per device of the plant.

Live values come from the state store only (``DeviceState.values()``), as variables of the device's
``ParameterSet`` with their engineering unit (``EngineeringUnits``) and a status code: Good, Uncertain
(``UncertainLastUsableValue``) for stale, Bad (``BadNotConnected``) for offline or never heard.

Read-only for everyone: the server's own permission rules (:class:`ReadOnlyRules`) refuse Write, Call,
HistoryUpdate and every node-management service for every session, whoever logged in; the variables
are also declared CurrentRead only. Anonymous sessions can be turned off (``anonymous = false``): then a
session logs in with an account of the accounts file (any role: it only reads). With ``certificate``
and ``private_key``, Basic256Sha256 SignAndEncrypt is offered beside None.
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
import weakref
from collections import OrderedDict
from collections.abc import Sequence
from datetime import datetime, timezone
from typing import Any

from asyncua import Server, ua
from asyncua.common.connection import TransportLimits
from asyncua.crypto.permission_rules import PermissionRuleset, User, UserRole
from asyncua.server.binary_server_asyncio import OPCUAProtocol
from asyncua.server.internal_session import SessionState
from asyncua.server.uaprocessor import UaProcessor
from asyncua.ua.ua_binary import nodeid_from_binary, struct_from_binary

from app.aio import end_tasks
from app.audit import LogBudget
from app.auth import LoginThrottle, check_login
from app.capabilities import controller_of
from devices.live import jsonable
from devices.registry import DEVICE_TYPES

log = logging.getLogger(__name__)

DI_URI = "http://opcfoundation.org/UA/DI/"
DEVICE_HEALTH = ("NORMAL", "FAILURE", "CHECK_FUNCTION", "OFF_SPEC", "MAINTENANCE_REQUIRED")
IDENTITY = ("Manufacturer", "Model", "SerialNumber", "SoftwareRevision", "HardwareRevision", "DeviceRevision")
REVISION_PERIOD_S = 5.0  # the revision counters are counted again from the audit log this often

# What clients may take (anonymous ones too). Per client address: sessions and connections that have not
# activated a session (the oldest idle one is closed for a new one, so a flood of idle sockets cannot keep
# a real client out); per session: subscriptions and monitored items; in all: connections, subscriptions,
# message and chunk sizes (a channel's unfinished chunks are bounded by the message size), idle time.
MAX_SESSIONS_PER_CLIENT = 8
MAX_IDLE_PER_CLIENT = 4
CONNECTIONS_PER_S_PER_CLIENT = 5.0  # new connections a second per client address (a burst of CONNECTION_BURST)
CONNECTION_BURST = 10  # beyond: closed at once, before any handshake (a guesser's refusals cost the loop next to nothing)
MAX_SUBSCRIPTIONS_PER_SESSION = 10
MAX_MONITORED_ITEMS_PER_SESSION = 2000  # created over the session's life
MAX_CONNECTIONS = 128
MAX_SUBSCRIPTIONS = 200
MAX_MESSAGE_BYTES = 2 * 1024 * 1024
MAX_CHUNK_BYTES = 65535
MAX_CHUNKS = 32
ACTIVATION_TIMEOUT_S = 10.0  # a connection without an activated session is closed after this
MAX_SESSION_TIMEOUT_MS = 60_000  # a session without requests ends after at most this
MAX_PENDING_MESSAGES = 50  # per connection, queued behind the one being handled
MAX_QUEUE_SIZE = 100  # per monitored item
LOG_LINES_PER_MINUTE = 30  # log lines that clients can cause (the library's and ours)

REFUSED_SERVICES = {ua.NodeId(i) for i in (
    ua.ObjectIds.WriteRequest_Encoding_DefaultBinary, ua.ObjectIds.CallRequest_Encoding_DefaultBinary,
    ua.ObjectIds.HistoryUpdateRequest_Encoding_DefaultBinary, ua.ObjectIds.AddNodesRequest_Encoding_DefaultBinary,
    ua.ObjectIds.DeleteNodesRequest_Encoding_DefaultBinary, ua.ObjectIds.AddReferencesRequest_Encoding_DefaultBinary,
    ua.ObjectIds.DeleteReferencesRequest_Encoding_DefaultBinary, ua.ObjectIds.RegisterServerRequest_Encoding_DefaultBinary,
    ua.ObjectIds.RegisterServer2Request_Encoding_DefaultBinary,
)}


_client_lines = LogBudget(lines=LOG_LINES_PER_MINUTE, window_s=60.0)  # what clients can make the server log


def _quiet_asyncua() -> None:
    """asyncua writes INFO lines for every connection and request and an ERROR for every refused one:
    its server loggers keep warnings only, within :data:`LOG_LINES_PER_MINUTE` a minute (the rest counted)."""
    import logging as _logging

    server_log = _logging.getLogger("asyncua.server")
    if server_log.level == _logging.NOTSET or server_log.level < _logging.WARNING:
        server_log.setLevel(_logging.WARNING)
    for name in list(_logging.root.manager.loggerDict):
        if name == "asyncua.server" or name.startswith("asyncua.server."):
            logger = _logging.getLogger(name)
            if _client_lines not in logger.filters:
                logger.addFilter(_client_lines)


class ReadOnlyRules(PermissionRuleset):
    """Every session may browse, read and subscribe; none may write, call or change the address space."""

    refused = 0

    def check_validity(self, user, action_type, body) -> bool:
        if action_type in REFUSED_SERVICES:
            ReadOnlyRules.refused += 1
            if _client_lines.take() is not None:
                log.info("opcua: %s refused for %s (the server is read-only)", action_type,
                         (user.name if isinstance(user, User) else None) or "anonymous")
            return False
        return True


class AccountUsers:
    """Sessions log in with an account of the accounts file (app/users.py); anonymous only if allowed.

    asyncua asks for the user synchronously, on the event loop, in the middle of ActivateSession;
    a password hash there would stop every bus task for its duration. So each user-name login is
    checked before asyncua sees it (:func:`_check_requests_first`): throttled, hashed in a thread and
    audited by :func:`app.auth.check_login`, like the web login; asyncua then only picks up the
    verdict. A login without a verdict is refused, never hashed on the loop.
    """

    def __init__(self, users, anonymous: bool, audit=None, throttle: LoginThrottle | None = None):
        self.users, self.anonymous, self.audit = users, anonymous, audit
        self.throttle = throttle if throttle is not None else LoginThrottle()
        self._verdicts: dict[tuple[str, str], list] = {}  # (name, password) -> [user or None, pending logins]

    async def check(self, username: str, password: str, address: str) -> None:
        """Check one user-name login before asyncua activates its session."""
        user, _words = await check_login(throttle=self.throttle, users=self.users, audit=self.audit, typed=username,
                                         secret=password, address=address, via="opcua")
        entry = self._verdicts.setdefault((username, password), [None, 0])
        entry[0], entry[1] = user, entry[1] + 1
        while len(self._verdicts) > 64:  # bounded: a verdict is taken at once by the login it belongs to
            self._verdicts.pop(next(iter(self._verdicts)))

    def get_user(self, iserver, username=None, password=None, certificate=None):
        if username is None:
            return User(role=UserRole.Anonymous) if self.anonymous else None
        entry = self._verdicts.get((username, password or ""))
        if entry is None:
            return None
        entry[1] -= 1
        if entry[1] <= 0:
            del self._verdicts[(username, password or "")]
        return None if entry[0] is None else User(role=UserRole.User, name=username)


_ACTIVATE = ua.NodeId(ua.ObjectIds.ActivateSessionRequest_Encoding_DefaultBinary)
_CREATE_SESSION = ua.NodeId(ua.ObjectIds.CreateSessionRequest_Encoding_DefaultBinary)
_CREATE_SUBSCRIPTION = ua.NodeId(ua.ObjectIds.CreateSubscriptionRequest_Encoding_DefaultBinary)
_CREATE_ITEMS = ua.NodeId(ua.ObjectIds.CreateMonitoredItemsRequest_Encoding_DefaultBinary)
_REGISTER = {ua.NodeId(ua.ObjectIds.RegisterServerRequest_Encoding_DefaultBinary),
             ua.NodeId(ua.ObjectIds.RegisterServer2Request_Encoding_DefaultBinary)}


class _Guard:
    """The server's accounts and what each client holds, for the checks before asyncua handles a request."""

    def __init__(self, logins: AccountUsers):
        self.logins = logins
        self.processors: weakref.WeakSet = weakref.WeakSet()  # every connection's processor that sent a request
        self.items: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # processor -> monitored items created
        self.framing: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # connection -> where its framing is
        self.arrivals: OrderedDict[str, list[float]] = OrderedDict()  # client address -> [tokens, last time]
        self.refused = 0

    def may_connect(self, host: str, now: float) -> bool:
        """A token bucket per client address: :data:`CONNECTIONS_PER_S_PER_CLIENT`, bursts of :data:`CONNECTION_BURST`."""
        bucket = self.arrivals.pop(host, None) or [float(CONNECTION_BURST), now]
        self.arrivals[host] = bucket
        while len(self.arrivals) > 4096:
            self.arrivals.popitem(last=False)
        bucket[0] = min(float(CONNECTION_BURST), bucket[0] + (now - bucket[1]) * CONNECTIONS_PER_S_PER_CLIENT)
        bucket[1] = now
        if bucket[0] < 1.0:
            return False
        bucket[0] -= 1.0
        return True

    def frame_fits(self, protocol, data: bytes) -> bool:
        """Follow the connection's framing (8-byte headers: type, chunk type, size); False as soon as a
        chunk announces more than :data:`MAX_CHUNK_BYTES`: asyncua would buffer it whole before looking."""
        state = self.framing.get(protocol)
        if state is None:
            state = self.framing[protocol] = [b"", 0]  # header bytes so far, bytes still to come of this chunk
        i, end = 0, len(data)
        while i < end:
            if state[1] > 0:
                step = min(state[1], end - i)
                state[1] -= step
                i += step
                continue
            need = 8 - len(state[0])
            state[0] += data[i:i + need]
            i += need
            if len(state[0]) < 8:
                break
            size = int.from_bytes(state[0][4:8], "little")
            state[0] = b""
            if size > MAX_CHUNK_BYTES or size < 8:
                return False
            state[1] = size - 8
        return True

    def sessions_of(self, host: str, besides) -> int:
        return sum(1 for p in list(self.processors) if p is not besides and _host(p.name) == host and p.session is not None
                   and p.session.state != SessionState.Closed)

    def subscriptions_of(self, iserver, session) -> int:
        return sum(1 for sub in list(iserver.subscription_service.subscriptions.values()) if sub.session_id == session.session_id)


_GUARDS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # asyncua's InternalServer -> _Guard


def _host(peer) -> str:
    return str(peer[0]) if isinstance(peer, tuple) and peer else str(peer)


async def _refusal(guard: _Guard, processor, typeid, peek, seqhdr) -> ua.StatusCode | None:
    """The refusal of this request by the limits above, or None to let asyncua handle it."""
    if typeid in _REGISTER:
        return ua.StatusCode(ua.StatusCodes.BadServiceUnsupported)  # never a discovery server for others
    if typeid == _CREATE_SESSION:
        if guard.sessions_of(_host(processor.name), processor) >= MAX_SESSIONS_PER_CLIENT:
            return ua.StatusCode(ua.StatusCodes.BadTooManySessions)
    elif typeid == _CREATE_SUBSCRIPTION and processor.session is not None:
        if guard.subscriptions_of(processor.iserver, processor.session) >= MAX_SUBSCRIPTIONS_PER_SESSION:
            return ua.StatusCode(ua.StatusCodes.BadTooManySubscriptions)
    elif typeid == _CREATE_ITEMS and processor.session is not None:
        asked = len(struct_from_binary(ua.CreateMonitoredItemsParameters, peek).ItemsToCreate)
        made = guard.items.get(processor, 0)
        if made + asked > MAX_MONITORED_ITEMS_PER_SESSION:
            return ua.StatusCode(ua.StatusCodes.BadTooManyMonitoredItems)
        guard.items[processor] = made + asked
    elif typeid == _ACTIVATE and not guard.logins.anonymous and processor.session is not None:
        token = struct_from_binary(ua.ActivateSessionParameters, peek).UserIdentityToken
        if isinstance(token, ua.UserNameIdentityToken):
            name, password = processor.iserver.decrypt_user_token(processor.session, token)
            await guard.logins.check(name or "", password or "", _host(processor.name))
    return None


def _check_requests_first() -> None:
    """Let each request be checked (limits, logins awaited off the loop) before asyncua handles it.

    asyncua has no asynchronous seam for a login and handles RegisterServer before its permission
    rules: its processor's public ``process_message`` is wrapped once; it looks the server up in
    :data:`_GUARDS` and does nothing for others. Likewise ``OPCUAProtocol.connection_made`` closes
    the oldest connection of an address that holds :data:`MAX_IDLE_PER_CLIENT` without a session.
    """
    if UaProcessor.process_message.__module__ == __name__:
        return  # wrapped already
    original = UaProcessor.process_message

    async def process_message(self, seqhdr, body):
        guard = _GUARDS.get(self.iserver)
        if guard is not None:
            guard.processors.add(self)
            refusal, requesthdr = None, None
            try:
                peek = body.copy()
                typeid = nodeid_from_binary(peek)
                requesthdr = struct_from_binary(ua.RequestHeader, peek)
                refusal = await _refusal(guard, self, typeid, peek, seqhdr)
            except (ValueError, TypeError, IndexError, ua.UaError, ua.UaStatusCodeError):
                pass  # asyncua refuses the malformed request itself
            if refusal is not None and requesthdr is not None:
                guard.refused += 1
                if _client_lines.take() is not None:
                    log.warning("opcua: a request from %s refused: %s", _host(self.name), refusal.name)
                response = ua.ServiceFault()
                response.ResponseHeader.ServiceResult = refusal
                self.send_response(requesthdr.RequestHandle, seqhdr, response)
                return True
        return await original(self, seqhdr, body)

    UaProcessor.process_message = process_message

    made = OPCUAProtocol.connection_made

    def connection_made(self, transport):
        guard = _GUARDS.get(self.iserver)
        if guard is not None:
            host = _host(transport.get_extra_info("peername"))
            if not guard.may_connect(host, time.monotonic()):
                guard.refused += 1
                if _client_lines.take() is not None:
                    log.warning("opcua: %s opens more than %.0f connections a second: closed at once", host,
                                CONNECTIONS_PER_S_PER_CLIENT)
                transport.close()
                return
            idle = [c for c in list(self.clients) if _host(c.peer_name) == host and c.transport is not None
                    and (c.processor is None or c.processor.session is None or not c.processor.session.is_activated())]
            for old in idle[:max(0, len(idle) - MAX_IDLE_PER_CLIENT + 1)]:
                if _client_lines.take() is not None:
                    log.warning("opcua: %s holds %d connections without a session: the oldest closed", host, len(idle))
                old.transport.close()
        made(self, transport)

    OPCUAProtocol.connection_made = connection_made

    received = OPCUAProtocol.data_received

    def data_received(self, data: bytes) -> None:
        guard = _GUARDS.get(self.iserver)
        if guard is not None and not guard.frame_fits(self, data):
            if _client_lines.take() is not None:
                log.warning("opcua: %s announced a message chunk over %d bytes: connection closed",
                            _host(self.peer_name), MAX_CHUNK_BYTES)
            if self.transport is not None:
                self.transport.close()
            return
        received(self, data)

    OPCUAProtocol.data_received = data_received


def health_of(state, controlled: bool, alarms: Sequence[str]) -> int:
    """NAMUR NE 107 from the device's state: FAILURE offline, CHECK_FUNCTION while an engineer controls it,
    OFF_SPEC with an active alarm of its tile, MAINTENANCE_REQUIRED with stale values or parameters
    written but not saved in the device, else NORMAL."""
    status = state.status
    if status == "offline":
        return DEVICE_HEALTH.index("FAILURE")
    if controlled:
        return DEVICE_HEALTH.index("CHECK_FUNCTION")
    if alarms:
        return DEVICE_HEALTH.index("OFF_SPEC")
    if status == "stale" or state.unsaved:
        return DEVICE_HEALTH.index("MAINTENANCE_REQUIRED")
    return DEVICE_HEALTH.index("NORMAL")


IDENTITY_POINT = "Identity"  # a device's identity record, where its type publishes one (e.g. M3IO addressed mode)


def published_identity(state) -> dict[str, Any]:
    """The fields of the identity record the device publishes as the point ``Identity`` (a record or a
    mapping, in its JSON form); {} until it has published one."""
    point = state.points.get(IDENTITY_POINT)
    fields = jsonable(point.value) if point is not None and point.value is not None else None
    return fields if isinstance(fields, dict) else {}


def identity_of(state, device_type: str, options: dict[str, Any]) -> dict[str, str]:
    """The DI identification of one device, from its live values (as its backup identity reads them)."""
    values = state.values()
    info = published_identity(state)

    def first(*names: str) -> str:
        for name in names:
            entry = values.get(name)
            if entry is not None and entry.get("value") not in (None, ""):
                return str(entry["value"])
        return ""

    title = DEVICE_TYPES[device_type].title if device_type in DEVICE_TYPES else device_type
    model = title
    if options.get("variant"):
        model = f"{title} {options['variant']}"
    elif options.get("actuators") and isinstance(options["actuators"], list):
        models = sorted({str(a.get("model", "")) for a in options["actuators"] if isinstance(a, dict) and a.get("model")})
        model = f"{title} ({', '.join(models)})" if models else title
    return {
        "Manufacturer": (DEVICE_TYPES[device_type].manufacturer if device_type in DEVICE_TYPES else "") or title,
        "Model": model,
        "SerialNumber": (first("SerialNumber", "Serial number", "serial") or str(info.get("serial") or "")
                         or str(options.get("serial", ""))),
        "SoftwareRevision": (first("FirmwareVersion", "Program version", "Firmware info", "version", "Software version")
                             or str(info.get("version") or "")),
        "HardwareRevision": first("HardwareVersion", "Hardware version", "Product") or str(info.get("product") or ""),
        "DeviceRevision": first("Device code", "DeviceRevision", "Configuration info"),
    }


def status_of(quality: str | None) -> ua.StatusCode:
    if quality == "good":
        return ua.StatusCode(ua.StatusCodes.Good)
    if quality == "stale":
        return ua.StatusCode(ua.StatusCodes.UncertainLastUsableValue)
    return ua.StatusCode(ua.StatusCodes.BadNotConnected)


def variant_of(value: Any) -> ua.Variant:
    if isinstance(value, bool):
        return ua.Variant(value, ua.VariantType.Boolean)
    if isinstance(value, int):
        return ua.Variant(value, ua.VariantType.Int64) if -(1 << 63) <= value < 1 << 63 else ua.Variant(str(value), ua.VariantType.String)
    if isinstance(value, float):
        return ua.Variant(value, ua.VariantType.Double)
    if isinstance(value, bytes | bytearray):
        return ua.Variant(bytes(value), ua.VariantType.ByteString)
    return ua.Variant("" if value is None else str(value), ua.VariantType.String)


def _coerce(value: Any, vtype: ua.VariantType) -> ua.Variant | None:
    """``value`` in the variable's type (fixed when the variable was made), or None."""
    try:
        if value is None:
            return None
        if vtype == ua.VariantType.Boolean:
            return ua.Variant(bool(value), vtype)
        if vtype == ua.VariantType.Int64:
            if isinstance(value, float) and not value.is_integer():
                return None
            return ua.Variant(int(value), vtype)
        if vtype == ua.VariantType.Double:
            number = float(value)
            return ua.Variant(number, vtype) if math.isfinite(number) else None
        if vtype == ua.VariantType.ByteString:
            return ua.Variant(bytes(value), vtype)
        return ua.Variant(str(value), vtype)
    except (TypeError, ValueError, OverflowError):
        return None


class OpcuaServer:
    """The plant as DI devices, read-only. Started and stopped with the runtime.

    :param worker: the bus worker, asked only whether an engineer controls a device (CHECK_FUNCTION)
    :param audit: the audit log, counted for the revision counters
    """

    def __init__(self, config, store, plant, worker=None, users=None, audit=None, throttle: LoginThrottle | None = None):
        self.config, self.store, self.plant = config, store, plant
        self.worker, self.users, self.audit = worker, users, audit
        self.throttle = throttle  # the web login's (app/auth.py): a guesser is slowed down on both faces
        self.server: Server | None = None
        self.ns = self.di = 0
        self._devices: dict[str, dict[str, Any]] = {}  # device -> node ids and what was last written
        self._task: asyncio.Task | None = None
        self.updates = 0
        self.started = False

    async def start(self) -> None:
        logins = AccountUsers(self.users, self.config.anonymous, audit=self.audit, throttle=self.throttle)
        server = Server(user_manager=logins)
        await server.init()
        self._limit(server)
        _check_requests_first()
        _GUARDS[server.iserver] = _Guard(logins)
        server.set_endpoint(self.config.endpoint)
        server.set_server_name(f"commission {self.plant.name}")
        await server.set_application_uri(f"urn:commission:{self.plant.name}")
        policies = [ua.SecurityPolicyType.NoSecurity]
        if self.config.certificate and self.config.private_key:
            await server.load_certificate(str(self.config.certificate))
            await server.load_private_key(str(self.config.private_key))
            policies.append(ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt)
        server.set_security_policy(policies, permission_ruleset=ReadOnlyRules())
        # user names only when anonymous sessions are off: otherwise a login would be a free password oracle
        tokens = [ua.AnonymousIdentityToken] if self.config.anonymous else [ua.UserNameIdentityToken]
        server.set_identity_tokens(tokens)
        self.server = server
        self.di = await server.register_namespace(DI_URI)
        self.ns = await server.register_namespace(f"urn:commission:{self.plant.name}")
        device_type, device_set = await self._di_model()
        for name, state in self.store.devices.items():
            await self._add_device(device_set, device_type, name, state)
        await server.start()
        self.started = True
        self._task = asyncio.create_task(self._update_loop(), name="opcua values")
        log.info("opcua: read-only server on %s (%d devices)", self.config.endpoint, len(self._devices))

    @staticmethod
    def _limit(server: Server) -> None:
        """The limits of what clients may take, on asyncua's own settings (see the constants above)."""
        server.limits = TransportLimits(max_recv_buffer=MAX_CHUNK_BYTES, max_send_buffer=MAX_CHUNK_BYTES,
                                        max_chunk_count=MAX_CHUNKS, max_message_size=MAX_MESSAGE_BYTES)
        iserver = server.iserver
        iserver.max_connections = MAX_CONNECTIONS
        iserver.max_pending_activation_seconds = ACTIVATION_TIMEOUT_S
        iserver.max_subscriptions = MAX_SUBSCRIPTIONS
        iserver.max_session_timeout_ms = MAX_SESSION_TIMEOUT_MS
        iserver.max_pending_messages_per_connection = MAX_PENDING_MESSAGES
        iserver.max_monitored_item_queue_size = MAX_QUEUE_SIZE
        _quiet_asyncua()

    async def stop(self) -> None:
        if self._task is not None:
            await end_tasks([self._task], "opc ua")
            self._task = None
        if self.server is not None and self.started:
            await self.server.stop()
        self.started = False

    # -- the DI model ----------------------------------------------------------------------------------
    async def _di_model(self):
        server, di = self.server, self.di
        health_enum = await server.nodes.enum_data_type.add_data_type(ua.NodeId(6244, di), ua.QualifiedName("DeviceHealthEnumeration", di))
        definition = ua.EnumDefinition()
        for index, text in enumerate(DEVICE_HEALTH):
            definition.Fields.append(ua.EnumField(Name=text, Value=index, DisplayName=ua.LocalizedText(text)))
        await health_enum.write_data_type_definition(definition)
        await health_enum.add_property(0, "EnumStrings", ua.Variant([ua.LocalizedText(t) for t in DEVICE_HEALTH]))
        topology = await server.nodes.base_object_type.add_object_type(ua.NodeId(1001, di), ua.QualifiedName("TopologyElementType", di))
        component = await topology.add_object_type(ua.NodeId(15063, di), ua.QualifiedName("ComponentType", di))
        device_type = await component.add_object_type(ua.NodeId(1002, di), ua.QualifiedName("DeviceType", di))
        for prop in IDENTITY:
            node = await device_type.add_property(di, prop, "", varianttype=ua.VariantType.String)
            await node.set_modelling_rule(True)
        node = await device_type.add_property(di, "RevisionCounter", -1, varianttype=ua.VariantType.Int32)
        await node.set_modelling_rule(True)
        health = await device_type.add_variable(di, "DeviceHealth", 0, varianttype=ua.VariantType.Int32, datatype=health_enum.nodeid)
        await health.set_modelling_rule(True)
        params = await device_type.add_object(di, "ParameterSet")
        await params.set_modelling_rule(True)
        device_set = await server.nodes.objects.add_object(ua.NodeId(5001, di), ua.QualifiedName("DeviceSet", di))
        return device_type, device_set

    async def _add_device(self, device_set, device_type, name: str, state) -> None:
        config = self.plant.devices.get(name)
        obj = await device_set.add_object(ua.NodeId(name, self.ns), ua.QualifiedName(name, self.ns), objecttype=device_type.nodeid)
        children = {}
        for child in await obj.get_children():
            children[(await child.read_browse_name()).Name] = child
        ident = identity_of(state, state.type, config.options if config else {})
        for prop, text in ident.items():
            await children[prop].write_value(ua.Variant(text, ua.VariantType.String))
        await children["RevisionCounter"].write_value(ua.Variant(0, ua.VariantType.Int32))
        for node in children.values():  # whatever a client is allowed in principle: reading only
            if await node.read_node_class() == ua.NodeClass.Variable:
                await node.write_attribute(ua.AttributeIds.UserAccessLevel, ua.DataValue(ua.Variant(1, ua.VariantType.Byte)))
        await obj.add_property(self.ns, "Bus", state.bus)
        await obj.add_property(self.ns, "DeviceKind", state.type)
        self._devices[name] = {"node": obj, "params": children["ParameterSet"], "health": children["DeviceHealth"].nodeid,
                               "revision": children["RevisionCounter"].nodeid, "identity": ident,
                               "ident_nodes": {k: children[k].nodeid for k in IDENTITY},
                               "points": {}, "version": None, "written": {}, "last_health": None}

    async def _add_point(self, dev: dict, device: str, point: str, entry: dict[str, Any]):
        variant = variant_of(entry.get("value"))
        var = await dev["params"].add_variable(ua.NodeId(f"{device}/{point}", self.ns), ua.QualifiedName(point, self.ns),
                                               variant.Value, varianttype=variant.VariantType)
        unit = entry.get("unit") or ""
        eu = ua.EUInformation(NamespaceUri="http://www.opcfoundation.org/UA/units/un/cefact", UnitId=-1,
                              DisplayName=ua.LocalizedText(unit), Description=ua.LocalizedText(unit))
        await var.add_property(0, "EngineeringUnits", ua.Variant(eu, ua.VariantType.ExtensionObject))
        dev["points"][point] = (var.nodeid, variant.VariantType)
        return dev["points"][point]

    # -- live values -------------------------------------------------------------------------------------
    def _controlled(self, name: str) -> bool:
        adapter = self.worker.adapters.get(name) if self.worker is not None else None
        return controller_of(adapter) is not None

    async def _update_loop(self) -> None:
        next_revision = 0.0
        while True:
            started = time.monotonic()
            try:
                if started >= next_revision and self.audit is not None:
                    next_revision = started + REVISION_PERIOD_S
                    await self._update_revisions()
                await self.update()
            except asyncio.CancelledError:
                raise
            except Exception:  # the server's one update task must not end: whatever failed is logged with its traceback
                log.exception("opcua: updating the values failed")
            await asyncio.sleep(max(0.0, 1.0 / self.config.rate - (time.monotonic() - started)))

    async def update(self) -> int:
        """Write every changed value, status, health and identity into the address space; returns the writes."""
        writes = 0
        now = time.time()
        for name, dev in self._devices.items():
            state = self.store.devices.get(name)
            if state is None:
                continue
            health = health_of(state, self._controlled(name), self.store.active_alarms(name, now) if state.status != "offline" else ())
            if health != dev["last_health"]:
                dev["last_health"] = health
                await self.server.write_attribute_value(dev["health"], ua.DataValue(ua.Variant(health, ua.VariantType.Int32)))
                writes += 1
            if dev["version"] == state.version and state.status == dev.get("status"):
                continue
            dev["version"], dev["status"] = state.version, state.status
            config = self.plant.devices.get(name)
            ident = identity_of(state, state.type, config.options if config else {})
            for key, text in ident.items():
                if text != dev["identity"].get(key):
                    dev["identity"][key] = text
                    await self.server.write_attribute_value(dev["ident_nodes"][key], ua.DataValue(ua.Variant(text, ua.VariantType.String)))
            for point, entry in state.values().items():
                known = dev["points"].get(point) or await self._add_point(dev, name, point, entry)
                nodeid, vtype = known
                quality = entry.get("quality") if state.status != "offline" else "offline"
                mark = (entry.get("value"), quality, entry.get("time"))
                if dev["written"].get(point) == mark:
                    continue
                dev["written"][point] = mark
                variant = _coerce(entry.get("value"), vtype)
                status = status_of(quality)
                if variant is None:
                    variant, status = ua.Variant(None, vtype), ua.StatusCode(ua.StatusCodes.BadNoData)
                stamp = entry.get("time")
                source = datetime.fromtimestamp(stamp, timezone.utc) if isinstance(stamp, int | float) else None
                await self.server.write_attribute_value(nodeid, ua.DataValue(variant, StatusCode=status, SourceTimestamp=source,
                                                                             ServerTimestamp=datetime.now(timezone.utc)))
                writes += 1
        self.updates += writes
        return writes

    async def _update_revisions(self) -> None:
        """RevisionCounter: the device's parameter changes that went through since its last approval."""
        counts = await asyncio.to_thread(self._count_revisions)
        for name, count in counts.items():
            dev = self._devices.get(name)
            if dev is not None and dev.get("revision_count") != count:
                dev["revision_count"] = count
                await self.server.write_attribute_value(dev["revision"], ua.DataValue(ua.Variant(count, ua.VariantType.Int32)))

    def _count_revisions(self) -> dict[str, int]:
        counts: dict[str, int] = {}
        for name in self._devices:
            rows = self.audit.query(device=name, limit=10_000)  # newest first
            count = 0
            for row in rows:
                if "approv" in row.action.lower():
                    break
                if row.parameter and row.result.startswith("ok"):
                    count += 1
            counts[name] = count
        return counts
