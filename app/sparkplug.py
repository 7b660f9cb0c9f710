"""Sparkplug B (specification 3.0) beside the JSON topics: the instance is an edge node, each device a
Sparkplug device, read-only.

Turned on by ``sparkplug = true`` in ``[mqtt]``; group id = ``site``, edge node id = ``instance``.
Everything is read from the state store (``DeviceState.values()``), as the JSON publisher does
(app/mqtt.py); the node holds a broker connection of its own, because its last will is the
NDEATH that carries the bdSeq of its birth.

- NBIRTH (``bdSeq``, ``Node Control/Rebirth``, node facts) and one DBIRTH per device with every
  live value as a metric: name, datatype, value (``is_null`` when it has none), timestamp, and the
  properties ``Quality`` (192 good, 500 stale, 0 bad: the spec's quality codes) and ``engUnit``.
- DDATA: changed metrics only, at most ``rate`` times a second per device. A value that appears
  later is announced by a new DBIRTH of its device (definitions only ever grow); a device that
  goes offline gets a DDEATH and a DBIRTH when it is back.
- ``Node Control/Rebirth`` (NCMD) is answered on the same connection: NBIRTH with the *same*
  bdSeq, then every DBIRTH with the same definitions and fresh values. Every other NCMD or DCMD
  is refused; nothing is ever sent to a device from here. Anyone who may publish to the broker can
  send commands, so a refusal is bounded: one audit row per command (its metrics named, at most
  ``MAX_NAMED`` of them, cut to ``MAX_TEXT`` characters), at most ``RefusalRows``' rows a minute
  (the rest counted, and the next row says how many), written under the node's name (a device's
  audit rows and its as-left report stay the engineer's), never on a device's page; a payload over
  ``MAX_COMMAND_BYTES`` is refused undecoded, and a command on a topic with extra levels is refused too.
- ``primary_host``: births and data go out only while ``spBv1.0/STATE/<host>`` says online; when
  the host goes offline the node sends its NDEATH and disconnects, and is born again (next bdSeq)
  when the host is back (spec 3.0, "Edge Node operation with a Primary Host Application").

The payload classes are built at import from descriptors made in code (no protoc at build
time): the part of the spec's ``sparkplug_b.proto`` (package ``org.eclipse.tahu.protobuf``,
proto2) this node uses - Payload, Payload.Metric, Payload.PropertySet, Payload.PropertyValue,
Payload.PropertySetList - with the spec's field numbers and types, so any Sparkplug decoder reads
them; fields of the spec left out here (DataSet, Template, MetaData) are never sent.
"""

from __future__ import annotations

import asyncio
import json
import logging
import math
import time
from dataclasses import dataclass, field
from typing import Any

import aiomqtt
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from google.protobuf.message import DecodeError

from app.aio import end_tasks
from app.audit import WRITE_ERRORS, LogBudget
from app.auth import RefusalRows
from app.broker import BROKER_ERRORS

log = logging.getLogger(__name__)

NAMESPACE = "spBv1.0"
BACKOFF_FIRST_S = 0.5
BACKOFF_MAX_S = 5.0
CONNECT_TIMEOUT_S = 10.0

# Payload.Metric datatypes (spec 3.0, section 6.4.16)
INT8, INT16, INT32, INT64, UINT8, UINT16, UINT32, UINT64 = 1, 2, 3, 4, 5, 6, 7, 8
FLOAT, DOUBLE, BOOLEAN, STRING, DATETIME, TEXT = 9, 10, 11, 12, 13, 14
BYTES = 17
# quality codes (spec 3.0, "Quality Codes"; the property is named Quality)
QUALITY_BAD, QUALITY_GOOD, QUALITY_STALE = 0, 192, 500
QUALITY_CODES = {"good": QUALITY_GOOD, "stale": QUALITY_STALE, "offline": QUALITY_BAD, "unknown": QUALITY_BAD}
REBIRTH = "Node Control/Rebirth"
BDSEQ = "bdSeq"
MAX_COMMAND_BYTES = 64 * 1024  # a command payload beyond this is refused without decoding it
MAX_TEXT = 64  # characters of a metric name or value kept in a refusal
MAX_NAMED = 5  # metrics named in the one row of a refused command
REFUSED_KEPT = 100  # refusals kept for the summary, newest last

_refusal_lines = LogBudget(lines=10, window_s=60.0)  # log lines of refused commands (others cause them)


def _cut(text: Any) -> str:
    text = str(text)
    return text if len(text) <= MAX_TEXT else f"{text[:MAX_TEXT]}... ({len(text)} characters)"


# -- the payload schema, built in code ----------------------------------------------------------
def _schema() -> descriptor_pb2.FileDescriptorProto:
    F = descriptor_pb2.FieldDescriptorProto
    opt, rep = F.LABEL_OPTIONAL, F.LABEL_REPEATED

    def msg(name: str, fields: list[tuple], oneof: str | None = None) -> descriptor_pb2.DescriptorProto:
        m = descriptor_pb2.DescriptorProto(name=name)
        if oneof:
            m.oneof_decl.add(name=oneof)
        for fname, number, ftype, label, *rest in fields:
            f = m.field.add(name=fname, number=number, type=ftype, label=label)
            if ftype == F.TYPE_MESSAGE:
                f.type_name = rest[0]
            if rest and rest[-1] == "oneof":
                f.oneof_index = 0
        return m

    P = ".org.eclipse.tahu.protobuf.Payload"
    property_value = msg("PropertyValue", [
        ("type", 1, F.TYPE_UINT32, opt), ("is_null", 2, F.TYPE_BOOL, opt),
        ("int_value", 3, F.TYPE_UINT32, opt, "oneof"), ("long_value", 4, F.TYPE_UINT64, opt, "oneof"),
        ("float_value", 5, F.TYPE_FLOAT, opt, "oneof"), ("double_value", 6, F.TYPE_DOUBLE, opt, "oneof"),
        ("boolean_value", 7, F.TYPE_BOOL, opt, "oneof"), ("string_value", 8, F.TYPE_STRING, opt, "oneof"),
        ("propertyset_value", 9, F.TYPE_MESSAGE, opt, f"{P}.PropertySet", "oneof"),
        ("propertysets_value", 10, F.TYPE_MESSAGE, opt, f"{P}.PropertySetList", "oneof"),
    ], oneof="value")
    property_set = msg("PropertySet", [("keys", 1, F.TYPE_STRING, rep), ("values", 2, F.TYPE_MESSAGE, rep, f"{P}.PropertyValue")])
    property_set_list = msg("PropertySetList", [("propertyset", 1, F.TYPE_MESSAGE, rep, f"{P}.PropertySet")])
    metric = msg("Metric", [
        ("name", 1, F.TYPE_STRING, opt), ("alias", 2, F.TYPE_UINT64, opt), ("timestamp", 3, F.TYPE_UINT64, opt),
        ("datatype", 4, F.TYPE_UINT32, opt), ("is_historical", 5, F.TYPE_BOOL, opt), ("is_transient", 6, F.TYPE_BOOL, opt),
        ("is_null", 7, F.TYPE_BOOL, opt), ("properties", 9, F.TYPE_MESSAGE, opt, f"{P}.PropertySet"),
        ("int_value", 10, F.TYPE_UINT32, opt, "oneof"), ("long_value", 11, F.TYPE_UINT64, opt, "oneof"),
        ("float_value", 12, F.TYPE_FLOAT, opt, "oneof"), ("double_value", 13, F.TYPE_DOUBLE, opt, "oneof"),
        ("boolean_value", 14, F.TYPE_BOOL, opt, "oneof"), ("string_value", 15, F.TYPE_STRING, opt, "oneof"),
        ("bytes_value", 16, F.TYPE_BYTES, opt, "oneof"),
    ], oneof="value")
    payload = msg("Payload", [
        ("timestamp", 1, F.TYPE_UINT64, opt), ("metrics", 2, F.TYPE_MESSAGE, rep, f"{P}.Metric"),
        ("seq", 3, F.TYPE_UINT64, opt), ("uuid", 4, F.TYPE_STRING, opt), ("body", 5, F.TYPE_BYTES, opt),
    ])
    payload.nested_type.extend([property_set, property_set_list, property_value, metric])
    return descriptor_pb2.FileDescriptorProto(name="commission/sparkplug_b.proto", package="org.eclipse.tahu.protobuf",
                                              syntax="proto2", message_type=[payload])


_pool = descriptor_pool.DescriptorPool()
_pool.Add(_schema())
Payload = message_factory.GetMessageClass(_pool.FindMessageTypeByName("org.eclipse.tahu.protobuf.Payload"))


def now_ms() -> int:
    return int(time.time() * 1000)


# -- metrics ----------------------------------------------------------------------------------------
def datatype_of(value: Any) -> int:
    """The Sparkplug datatype a live value is born with (kept for the metric's whole life)."""
    if isinstance(value, bool):
        return BOOLEAN
    if isinstance(value, int):
        return INT64
    if isinstance(value, float):
        return DOUBLE
    if isinstance(value, bytes | bytearray):
        return BYTES
    return STRING  # text, and anything structured as JSON text


def _json_text(value: Any) -> str:
    if isinstance(value, str):
        return value
    return json.dumps(value, separators=(",", ":"), default=str, sort_keys=True)


def set_value(metric, datatype: int, value: Any) -> bool:
    """Put ``value`` into ``metric`` as ``datatype``; False (and ``is_null``) when it has no such form."""
    try:
        if value is None:
            raise ValueError
        if datatype == BOOLEAN:
            metric.boolean_value = bool(value)
        elif datatype == INT64:
            if isinstance(value, float) and not value.is_integer():
                raise ValueError
            metric.long_value = int(value) & 0xFFFF_FFFF_FFFF_FFFF  # two's complement (spec 6.4.16)
        elif datatype == DOUBLE:
            number = float(value)
            if not math.isfinite(number):
                raise ValueError
            metric.double_value = number
        elif datatype == BYTES:
            metric.bytes_value = bytes(value)
        else:
            metric.string_value = _json_text(value)
        return True
    except (TypeError, ValueError, OverflowError):
        metric.is_null = True
        return False


def _property(props, key: str, kind: int, value: Any) -> None:
    props.keys.append(key)
    pv = props.values.add(type=kind)
    if kind == INT32:
        pv.int_value = int(value) & 0xFFFF_FFFF
    else:
        pv.string_value = str(value)


def add_metric(payload, name: str, datatype: int, entry: dict[str, Any] | None, birth: bool) -> None:
    """One live value as a metric: name, datatype, value or is_null, timestamp, Quality and engUnit."""
    metric = payload.metrics.add(name=name, datatype=datatype)
    if entry is None:
        metric.is_null = True
        metric.timestamp = now_ms()
        _property(metric.properties, "Quality", INT32, QUALITY_BAD)
        return
    stamp = entry.get("time")
    metric.timestamp = int(stamp * 1000) if isinstance(stamp, int | float) and math.isfinite(stamp) else now_ms()
    set_value(metric, datatype, entry.get("value"))
    _property(metric.properties, "Quality", INT32, QUALITY_CODES.get(entry.get("quality"), QUALITY_BAD))
    if birth and entry.get("unit"):
        _property(metric.properties, "engUnit", STRING, entry["unit"])


def node_topic(group: str, kind: str, node: str, device: str | None = None) -> str:
    return f"{NAMESPACE}/{group}/{kind}/{node}" + (f"/{device}" if device else "")


def state_topic(host: str) -> str:
    return f"{NAMESPACE}/STATE/{host}"


def _signature(entry: dict[str, Any] | None) -> tuple:
    """What counts as a change of a metric: its value and its quality (not the read time)."""
    if entry is None:
        return (None, "unknown")
    value = entry.get("value")
    if isinstance(value, dict | list):
        value = _json_text(value)
    return (value, entry.get("quality"))


@dataclass
class _Device:
    definitions: dict[str, int] = field(default_factory=dict)  # metric name -> datatype (as born)
    sent: dict[str, tuple] = field(default_factory=dict)  # metric name -> signature last published
    born: bool = False
    last_data: float = 0.0


class SparkplugNode:
    """The instance as a Sparkplug B edge node on the broker of ``[mqtt]``.

    :param audit: the audit log (:class:`app.audit.AuditLog`) that refused commands are written to
    """

    def __init__(self, config, store, plant_name: str, audit=None, password=None, timeout_s: float = 5.0):
        self.config = config
        self.timeout_s = timeout_s  # the MQTT client's publish timeout, as the JSON publisher's
        self.store = store
        self.plant_name = plant_name
        self.audit = audit
        self._password = password  # async () -> str | None, the JSON publisher's reader
        self.group, self.node = config.site, config.instance
        self.bd_seq = -1  # the first connection is born with 0
        self.seq = 0
        self.state = "starting"
        self.last_error = ""
        self.sent = 0
        self.births = 0
        self.rebirths = 0
        self.refused: list[dict[str, Any]] = []  # the last REFUSED_KEPT refused commands (sizes capped), newest last
        self.refused_count = 0
        self._refusal_rows = RefusalRows()
        self.host_online: bool | None = None if config.primary_host else True
        self._devices: dict[str, _Device] = {}
        self._rebirth = asyncio.Event()
        self._host_changed = asyncio.Event()
        self._task: asyncio.Task | None = None
        self._client = None

    # -- life cycle ---------------------------------------------------------------------------------
    def summary(self) -> dict[str, Any]:
        return {"state": self.state, "last_error": self.last_error, "group": self.group, "node": self.node,
                "bdSeq": self.bd_seq, "sent": self.sent, "births": self.births, "rebirths": self.rebirths,
                "host_online": self.host_online, "refused": self.refused_count}

    async def start(self) -> None:
        self._task = asyncio.create_task(self._run(), name="sparkplug node")

    async def stop(self) -> None:
        """A clean goodbye: NDEATH (the bdSeq of the birth) and disconnect, bounded; the will covers the rest."""
        client = self._client if self.state == "online" else None
        if self._task is not None:
            await end_tasks([self._task], "sparkplug")
            self._task = None
        if client is not None:
            try:
                await asyncio.wait_for(client.publish(node_topic(self.group, "NDEATH", self.node), self.death_payload(),
                                                      qos=1, retain=False), 2.0)
                await asyncio.wait_for(client.__aexit__(None, None, None), 2.0)
            except BROKER_ERRORS as exc:  # the broker sends the will instead
                log.info("sparkplug: NDEATH not sent (%s); the broker sends the will", exc)
        self._client = None
        self.state = "stopped"

    # -- payloads -----------------------------------------------------------------------------------
    def death_payload(self) -> bytes:
        payload = Payload(timestamp=now_ms())
        payload.metrics.add(name=BDSEQ, datatype=INT64, long_value=self.bd_seq, timestamp=payload.timestamp)
        return payload.SerializeToString()

    def _next_seq(self) -> int:
        seq, self.seq = self.seq, (self.seq + 1) % 256
        return seq

    def node_birth_payload(self) -> bytes:
        self.seq = 0
        payload = Payload(timestamp=now_ms(), seq=self._next_seq())
        stamp = payload.timestamp
        payload.metrics.add(name=BDSEQ, datatype=INT64, long_value=self.bd_seq, timestamp=stamp)
        payload.metrics.add(name=REBIRTH, datatype=BOOLEAN, boolean_value=False, timestamp=stamp)
        payload.metrics.add(name="Node Info/Plant", datatype=STRING, string_value=self.plant_name, timestamp=stamp)
        payload.metrics.add(name="Node Info/Devices", datatype=INT64, long_value=len(self.store.devices), timestamp=stamp)
        payload.metrics.add(name="Node Info/Read Only", datatype=BOOLEAN, boolean_value=True, timestamp=stamp)
        return payload.SerializeToString()

    def device_birth_payload(self, name: str, values: dict[str, dict[str, Any]]) -> bytes:
        """Every known metric of the device (its definitions grow by what ``values`` holds new)."""
        dev = self._devices.setdefault(name, _Device())
        for metric, entry in values.items():
            if metric not in dev.definitions:
                dev.definitions[metric] = datatype_of(entry.get("value"))
        payload = Payload(timestamp=now_ms(), seq=self._next_seq())
        for metric, datatype in dev.definitions.items():
            entry = values.get(metric)
            add_metric(payload, metric, datatype, entry, birth=True)
            dev.sent[metric] = _signature(entry)
        dev.born = True
        return payload.SerializeToString()

    def device_data_payload(self, name: str, values: dict[str, dict[str, Any]]) -> bytes | None:
        """The metrics whose value or quality changed since last sent, or None."""
        dev = self._devices[name]
        payload = None
        for metric, datatype in dev.definitions.items():
            entry = values.get(metric)
            signature = _signature(entry)
            if dev.sent.get(metric) == signature:
                continue
            if payload is None:
                payload = Payload(timestamp=now_ms())
            add_metric(payload, metric, datatype, entry, birth=False)
            dev.sent[metric] = signature
        if payload is None:
            return None
        payload.seq = self._next_seq()
        return payload.SerializeToString()

    def device_death_payload(self, name: str) -> bytes:
        self._devices[name].born = False
        return Payload(timestamp=now_ms(), seq=self._next_seq()).SerializeToString()

    # -- the connection -------------------------------------------------------------------------------
    async def _connect(self):
        self.bd_seq = (self.bd_seq + 1) % 256
        password = await self._password() if self._password else None
        tls = None
        if self.config.tls:
            import ssl

            ca = str(self.config.ca_file) if self.config.ca_file else None
            tls = await asyncio.to_thread(ssl.create_default_context, cafile=ca)
        client = aiomqtt.Client(
            self.config.host, self.config.port, username=self.config.username, password=password,
            identifier=f"spb-{self.group}-{self.node}"[:64], clean_session=True,
            will=aiomqtt.Will(node_topic(self.group, "NDEATH", self.node), self.death_payload(), qos=1, retain=False),
            keepalive=max(5, int(self.config.heartbeat)), tls_context=tls, timeout=self.timeout_s,
        )
        await asyncio.wait_for(client.__aenter__(), CONNECT_TIMEOUT_S)
        return client

    async def _run(self) -> None:
        backoff = BACKOFF_FIRST_S
        while True:
            self.state = "connecting"
            try:
                self._client = await self._connect()
            except asyncio.CancelledError:
                raise
            except BROKER_ERRORS as exc:  # refused, unreachable, bad TLS, no password: a state, not a crash
                if str(exc) != self.last_error:
                    log.warning("sparkplug: broker %s: %s", self.config.url, exc)
                self.state, self.last_error = "down", str(exc) or type(exc).__name__
                await asyncio.sleep(backoff)
                backoff = min(BACKOFF_MAX_S, backoff * 2)
                continue
            backoff = BACKOFF_FIRST_S
            client = self._client
            listener = asyncio.create_task(self._listen(client), name="sparkplug commands")
            try:
                await self._session(client)
            except asyncio.CancelledError:
                raise
            except BROKER_ERRORS as exc:  # broker lost, or the primary host went away (a ConnectionError)
                self.state, self.last_error = "down", str(exc) or type(exc).__name__
                log.info("sparkplug: session ended: %s", self.last_error)
            finally:
                await end_tasks([listener], "sparkplug listener")
            try:
                await asyncio.wait_for(client.__aexit__(None, None, None), 1.0)
            except BROKER_ERRORS:  # already gone
                pass
            self._client = None
            await asyncio.sleep(backoff)

    async def _session(self, client) -> None:
        # '#' also matches the level itself: commands on topics with extra levels are heard, and refused
        await client.subscribe(node_topic(self.group, "NCMD", self.node) + "/#", qos=1)
        await client.subscribe(node_topic(self.group, "DCMD", self.node) + "/#", qos=1)
        if self.config.primary_host:
            self.state = "waiting for the primary host"
            await client.subscribe(state_topic(self.config.primary_host), qos=1)
            while not self.host_online:
                self._host_changed.clear()
                await self._host_changed.wait()
        await self._birth(client)
        self.state, self.last_error = "online", ""
        period = 1.0 / self.config.rate
        while True:
            if self.config.primary_host and not self.host_online:
                await client.publish(node_topic(self.group, "NDEATH", self.node), self.death_payload(), qos=1)
                raise ConnectionError(f"the primary host {self.config.primary_host} went offline")
            if self._rebirth.is_set():
                self._rebirth.clear()
                self.rebirths += 1
                await self._birth(client)
            started = time.monotonic()
            await self._publish_changes(client)
            self._host_changed.clear()
            waits = [asyncio.ensure_future(self._rebirth.wait()), asyncio.ensure_future(self._host_changed.wait())]
            try:
                await asyncio.wait(waits, timeout=max(0.0, period - (time.monotonic() - started)),
                                   return_when=asyncio.FIRST_COMPLETED)
            finally:
                for w in waits:
                    w.cancel()

    async def _publish(self, client, topic: str, payload: bytes, qos: int = 0) -> None:
        await client.publish(topic, payload, qos=qos, retain=False)
        self.sent += 1

    async def _birth(self, client) -> None:
        """NBIRTH with this connection's bdSeq, then a DBIRTH per device that has values."""
        self.births += 1
        await self._publish(client, node_topic(self.group, "NBIRTH", self.node), self.node_birth_payload())
        for name, state in list(self.store.devices.items()):
            dev = self._devices.get(name)
            if dev is not None:
                dev.born = False
            if state.status == "offline":
                continue  # born again once it answers (its DDEATH stands meanwhile)
            values = state.values()
            if values or (dev is not None and dev.definitions):
                await self._publish(client, node_topic(self.group, "DBIRTH", self.node, name), self.device_birth_payload(name, values))

    async def _publish_changes(self, client) -> None:
        for name, state in list(self.store.devices.items()):
            dev = self._devices.get(name)
            if state.status == "offline":
                if dev is not None and dev.born:
                    await self._publish(client, node_topic(self.group, "DDEATH", self.node, name), self.device_death_payload(name))
                continue
            values = state.values()
            if not values:
                continue
            if dev is None or not dev.born or any(metric not in dev.definitions for metric in values):
                await self._publish(client, node_topic(self.group, "DBIRTH", self.node, name), self.device_birth_payload(name, values))
                continue
            payload = self.device_data_payload(name, values)
            if payload is not None:
                await self._publish(client, node_topic(self.group, "DDATA", self.node, name), payload)
            await asyncio.sleep(0)  # a large plant in slices: the loop carries keep-alives

    # -- what comes in: commands and the primary host's STATE ---------------------------------------
    async def _listen(self, client) -> None:
        async for message in client.messages:
            topic = str(message.topic)
            try:
                if topic.startswith(f"{NAMESPACE}/STATE/"):
                    self._on_state(bytes(message.payload))
                else:
                    await self._on_command(topic, bytes(message.payload))
            except Exception:  # anyone may publish: no message, however made, may end the node's listener
                if _refusal_lines.take() is not None:  # anyone may publish: bounded like the refusals
                    log.exception("sparkplug: cannot handle a message on %s", topic[:200])

    def _on_state(self, payload: bytes) -> None:
        try:
            online = bool(json.loads(payload or b"{}").get("online"))
        except (ValueError, AttributeError):
            online = payload.strip().upper() == b"ONLINE"  # the 2.2 form
        if online != self.host_online and _refusal_lines.take() is not None:  # a flapping STATE: bounded lines
            log.info("sparkplug: primary host %s is %s", self.config.primary_host, "online" if online else "offline")
        self.host_online = online
        self._host_changed.set()

    async def _on_command(self, topic: str, data: bytes) -> None:
        parts = topic.split("/")
        kind = parts[2] if len(parts) > 2 else ""
        device = parts[4] if kind == "DCMD" and len(parts) > 4 else ""
        if len(parts) != (5 if kind == "DCMD" else 4):
            await self._refuse(kind, device, "", f"a topic with extra levels ({_cut(topic)})")
            return
        if len(data) > MAX_COMMAND_BYTES:
            await self._refuse(kind, device, "", f"a payload of {len(data)} bytes (at most {MAX_COMMAND_BYTES})")
            return
        payload = Payload()
        try:
            payload.ParseFromString(data)
        except DecodeError:  # not a Sparkplug payload
            await self._refuse(kind, device, "", "not a Sparkplug B payload")
            return
        others = []
        for metric in payload.metrics:
            if kind == "NCMD" and metric.name == REBIRTH and metric.WhichOneof("value") == "boolean_value" and metric.boolean_value:
                if not self._rebirth.is_set():
                    log.info("sparkplug: Rebirth requested; births again on the same connection (bdSeq %d)", self.bd_seq)
                self._rebirth.set()
                continue
            others.append(metric)
        if not payload.metrics:
            await self._refuse(kind, device, "", "no metrics")
        elif others:
            value = others[0].WhichOneof("value")
            await self._refuse(kind, device, ", ".join(_cut(m.name) for m in others[:MAX_NAMED]),
                               "read-only: Sparkplug commands other than Node Control/Rebirth are never executed",
                               getattr(others[0], value) if value and len(others) == 1 else None, count=len(others))

    async def _refuse(self, kind: str, device: str, metric: str, reason: str, value: Any = None, count: int = 1) -> None:
        """One refused command: counted, kept (capped), logged and audited within their bounds.

        Written under the node's name, never the device's, and not on the device's page: a command
        comes from whoever may publish to the broker, unauthenticated."""
        self.refused_count += 1
        target = f"{_cut(device)}: " if device else ""
        names = f"{target}{metric}" + (f" (+{count - MAX_NAMED} more)" if count > MAX_NAMED else "")
        shown = "" if value is None else _cut(value if not isinstance(value, bytes) else value.hex())
        what = f"{count} metrics" if count > 1 else "1 metric" if metric else "the command"
        row = {"time": time.time(), "kind": _cut(kind), "device": _cut(device), "metric": names, "value": shown,
               "reason": f"{what}: {reason}"}
        self.refused = [*self.refused[-(REFUSED_KEPT - 1):], row]
        if _refusal_lines.take() is not None:
            log.warning("sparkplug: %s %s refused (%s): %s", row["kind"], names or self.node, what, reason)
        skipped = self._refusal_rows.take("sparkplug")
        if self.audit is None or skipped is None:
            return
        result = f"refused: {what}: {reason}"
        if skipped:
            result += f"; {skipped} more refused commands not written one by one"
        try:
            await self.audit.arecord(user="sparkplug", role="unauthenticated", device=self.node, action=f"Sparkplug {row['kind']}",
                                     parameter=names, new=shown, result=result)
        except WRITE_ERRORS as exc:  # nothing was executed anyway
            log.error("audit: %s", exc)
