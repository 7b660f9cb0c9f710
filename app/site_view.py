"""``commission view``: every site and device that publishes to one broker, read back, read-only.

Subscribes to ``commission/#`` (docs/mqtt.md) and keeps the newest state, status and alarms of
each device, and the birth/death of each instance. Publishes nothing, ever. Bounded: at most
``MAX_DEVICES`` devices and ``MAX_INSTANCES`` instances; messages beyond are counted, not kept.

Anyone who may publish to the broker can send anything: every payload is checked against its
schema (the pydantic models below, strict: a heartbeat ``"30"`` is no number), at most
``MAX_PAYLOAD`` bytes and ``MAX_DEPTH`` levels deep, before anything of it is kept; what does not
fit is dropped and counted (``ignored``), and the view goes on answering.
"""

from __future__ import annotations

import asyncio
import json
import logging
import ssl
import time
from dataclasses import dataclass, field
from typing import Any, Literal

import aiomqtt
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from app.aio import end_tasks
from app.broker import BROKER_ERRORS
from app.mqtt import BACKOFF_FIRST_S, BACKOFF_MAX_S, CONNECT_TIMEOUT_S, INSTANCES, TOPIC_ROOT
from app.plant import parse_mqtt_url

log = logging.getLogger(__name__)

MAX_DEVICES = 5000
MAX_INSTANCES = 500
MAX_PAYLOAD = 1_000_000  # bytes; a larger message is not one of ours
MAX_DEPTH = 8  # levels of nesting (objects and lists); ours have at most five (state -> values -> value -> fields)
MAX_NAME = 256  # characters of a name, status or unit
MAX_TEXT = 4096  # characters of a text or an error


Name = Field(default="", max_length=MAX_NAME)
Number = float | int


class _Payload(BaseModel):
    model_config = ConfigDict(strict=True, extra="allow")
    instance: str = Field(default="", max_length=MAX_NAME)
    time: Number | None = None


class ValueEntry(BaseModel):
    """One value of a state message (docs/mqtt.md, "state")."""
    model_config = ConfigDict(strict=True, extra="allow")
    value: Any = None
    unit: str | None = Field(default="", max_length=MAX_NAME)
    quality: str | None = Field(default="", max_length=MAX_NAME)
    time: Number | None = None
    text: str | None = Field(default="", max_length=MAX_TEXT)


class InstancePayload(_Payload):
    site: str | None = Field(default=None, max_length=MAX_NAME)
    plant: str | None = Field(default=None, max_length=MAX_NAME)
    state: Literal["online", "offline"] = "online"
    reason: str = Field(default="", max_length=MAX_TEXT)
    devices: list[str] = Field(default_factory=list, max_length=MAX_DEVICES)
    heartbeat: Number = Field(default=10.0, gt=0, le=86_400)


class DevicePayload(_Payload):
    type: str = Name
    bus: str = Name
    device: str = Name
    status: str = Name


class StatePayload(DevicePayload):
    values: dict[str, ValueEntry] = Field(default_factory=dict)


class StatusPayload(DevicePayload):
    last_error: str | None = Field(default="", max_length=MAX_TEXT)
    counters: dict[str, Number | None] = Field(default_factory=dict)


class AlarmsPayload(DevicePayload):
    active: list[str] = Field(default_factory=list, max_length=1000)


SCHEMAS: dict[str, type[BaseModel]] = {"state": StatePayload, "status": StatusPayload, "alarms": AlarmsPayload}


def nested_within(data: Any, limit: int = MAX_DEPTH) -> bool:
    """Whether ``data`` (decoded JSON) is at most ``limit`` levels of objects and lists deep."""
    level = [data]
    for _ in range(limit):
        nxt = []
        for item in level:
            if isinstance(item, dict):
                nxt.extend(item.values())
            elif isinstance(item, list):
                nxt.extend(item)
        if not nxt:
            return True
        level = [i for i in nxt if isinstance(i, dict | list)]
        if not level:
            return True
    return False
STALE_HEARTBEATS = 3  # a device or instance is stale after this many heartbeats without a message


@dataclass
class SiteDevice:
    site: str
    name: str
    instance: str = ""
    type: str = ""
    bus: str = ""
    state: dict[str, Any] = field(default_factory=dict)  # the newest .../state payload
    status: dict[str, Any] = field(default_factory=dict)  # the newest .../status payload
    alarms: list[str] = field(default_factory=list)
    received: float = 0.0  # when this view last heard of the device (its own clock)


@dataclass
class SiteInstance:
    site: str
    name: str
    payload: dict[str, Any] = field(default_factory=dict)
    received: float = 0.0


class SiteStore:
    """What the broker says about every site, kept by the view's subscriber task."""

    def __init__(self, url: str, username: str | None = None, password: str | None = None, ca_file: str | None = None):
        self.url = url
        self.host, self.port, self.tls = parse_mqtt_url(url)
        self.username, self.password, self.ca_file = username, password, ca_file
        self.devices: dict[tuple[str, str], SiteDevice] = {}
        self.instances: dict[tuple[str, str], SiteInstance] = {}
        self.state = "starting"
        self.last_error = ""
        self.received = 0
        self.ignored = 0  # malformed, foreign or over the bounds
        self.latency: list[float] = []  # receive time - publish time (same host clocks), newest last, bounded
        self._task: asyncio.Task | None = None

    # -- messages ----------------------------------------------------------------------------------
    def handle(self, topic: str, payload: bytes, now: float | None = None) -> None:
        """One message from the broker (O(1) apart from JSON decoding); never raises on bad input."""
        now = time.time() if now is None else now
        self.received += 1
        parts = topic.split("/")
        if len(parts) != 4 or parts[0] != TOPIC_ROOT:
            self.ignored += 1
            return
        _root, site, middle, leaf = parts
        data: dict[str, Any] = {}
        if payload:  # an empty retained message clears the topic
            if len(payload) > MAX_PAYLOAD:
                self.ignored += 1
                return
            try:
                data = json.loads(payload)
            except (ValueError, RecursionError):  # RecursionError: nested deeper than the decoder goes
                self.ignored += 1
                return
            schema = InstancePayload if middle == INSTANCES else SCHEMAS.get(leaf)
            if not isinstance(data, dict) or not nested_within(data):
                self.ignored += 1
                return
            if schema is not None:
                try:
                    schema.model_validate(data)
                except ValidationError:
                    self.ignored += 1
                    return
        if middle == INSTANCES:
            self._instance(site, leaf, data, now)
        elif leaf in ("state", "status", "alarms"):
            self._device(site, middle, leaf, data, now)
        # "alarm" events and unknown leaves: the retained "alarms" list carries the same

    def _instance(self, site: str, name: str, data: dict[str, Any], now: float) -> None:
        key = (site, name)
        if not data:
            self.instances.pop(key, None)
            return
        if key not in self.instances and len(self.instances) >= MAX_INSTANCES:
            self.ignored += 1
            return
        inst = self.instances.setdefault(key, SiteInstance(site, name))
        inst.payload, inst.received = data, now

    def _device(self, site: str, name: str, leaf: str, data: dict[str, Any], now: float) -> None:
        key = (site, name)
        if not data:
            if leaf == "state":
                self.devices.pop(key, None)
            return
        if key not in self.devices and len(self.devices) >= MAX_DEVICES:
            self.ignored += 1
            return
        dev = self.devices.setdefault(key, SiteDevice(site, name))
        dev.instance = str(data.get("instance") or dev.instance)
        dev.type = str(data.get("type") or dev.type)
        dev.bus = str(data.get("bus") or dev.bus)
        if leaf == "state":
            dev.state = data
            sent = data.get("time")
            if isinstance(sent, int | float):
                self.latency.append(now - sent)
                if len(self.latency) > 10_000:
                    del self.latency[:5000]
        elif leaf == "status":
            dev.status = data
        else:
            active = data.get("active")
            dev.alarms = [str(a) for a in active] if isinstance(active, list) else []
        dev.received = now

    # -- what the view shows ----------------------------------------------------------------------
    def instance_state(self, inst: SiteInstance | None, now: float) -> str:
        """``online``, ``stale`` (no heartbeat for a while), ``stopped`` or ``vanished`` (its last will)."""
        if inst is None:
            return "unknown"
        if inst.payload.get("state") == "offline":
            return "stopped" if inst.payload.get("reason") == "stopped" else "vanished"
        heartbeat = inst.payload.get("heartbeat")
        heartbeat = heartbeat if isinstance(heartbeat, int | float) and heartbeat > 0 else 10.0
        return "stale" if now - inst.received > STALE_HEARTBEATS * heartbeat else "online"

    def device_view(self, dev: SiteDevice, now: float) -> dict[str, Any]:
        """One device as the view's API and tiles show it; ``view_status`` adds what the broker tells."""
        inst = self.instances.get((dev.site, dev.instance))
        inst_state = self.instance_state(inst, now)
        status = dev.status.get("status") or dev.state.get("status") or "unknown"
        heartbeat = (inst.payload.get("heartbeat") if inst else None) or 10.0
        if inst_state in ("vanished", "stopped"):
            view_status = inst_state
        elif now - dev.received > STALE_HEARTBEATS * heartbeat or inst_state == "stale":
            view_status = "stale"
        else:
            view_status = status
        values = dev.state.get("values") if isinstance(dev.state.get("values"), dict) else {}
        return {"site": dev.site, "name": dev.name, "instance": dev.instance, "type": dev.type, "bus": dev.bus,
                "status": status, "view_status": view_status, "instance_state": inst_state,
                "age": max(0.0, now - dev.received) if dev.received else None,
                "last_error": dev.status.get("last_error", ""), "counters": dev.status.get("counters", {}),
                "alarms": list(dev.alarms), "values": values}

    def snapshot(self, now: float | None = None) -> dict[str, Any]:
        """Every site with its instances and devices (the view's JSON API), sorted by name."""
        now = time.time() if now is None else now
        sites: dict[str, dict[str, Any]] = {}
        for (site, name), inst in sorted(self.instances.items()):
            entry = sites.setdefault(site, {"site": site, "instances": [], "devices": []})
            entry["instances"].append({"name": name, "state": self.instance_state(inst, now), "plant": inst.payload.get("plant"),
                                       "devices": inst.payload.get("devices", []), "reason": inst.payload.get("reason", ""),
                                       "age": max(0.0, now - inst.received)})
        for (site, _name), dev in sorted(self.devices.items()):
            sites.setdefault(site, {"site": site, "instances": [], "devices": []})["devices"].append(self.device_view(dev, now))
        return {"broker": self.broker(), "sites": [sites[k] for k in sorted(sites)]}

    def broker(self) -> dict[str, Any]:
        return {"url": self.url, "state": self.state, "connected": self.state == "connected", "last_error": self.last_error,
                "received": self.received, "ignored": self.ignored}

    # -- the subscriber task -------------------------------------------------------------------------
    async def start(self) -> None:
        self._task = asyncio.create_task(self._run(), name="site view subscriber")

    async def stop(self) -> None:
        if self._task is not None:
            await end_tasks([self._task], "site view")
            self._task = None

    async def _run(self) -> None:
        backoff = BACKOFF_FIRST_S
        while True:
            self.state = "connecting"
            try:
                tls = None
                if self.tls:
                    tls = await asyncio.to_thread(ssl.create_default_context, cafile=self.ca_file)
                client = aiomqtt.Client(self.host, self.port, username=self.username, password=self.password, tls_context=tls,
                                        max_queued_incoming_messages=100_000)
                await asyncio.wait_for(client.__aenter__(), CONNECT_TIMEOUT_S)
            except asyncio.CancelledError:
                raise
            except BROKER_ERRORS as exc:  # a state, shown in the header
                self.state, self.last_error = "down", str(exc) or type(exc).__name__
                await asyncio.sleep(backoff)
                backoff = min(BACKOFF_MAX_S, backoff * 2)
                continue
            backoff = BACKOFF_FIRST_S
            try:
                await client.subscribe(f"{TOPIC_ROOT}/#", qos=1)
                self.state, self.last_error = "connected", ""
                async for message in client.messages:
                    payload = message.payload if isinstance(message.payload, bytes | bytearray) else b""
                    self.handle(str(message.topic), bytes(payload))
            except asyncio.CancelledError:
                raise
            except BROKER_ERRORS as exc:  # the broker went away (handle() never raises on bad input)
                self.state, self.last_error = "down", str(exc) or type(exc).__name__
            finally:
                try:
                    await asyncio.wait_for(client.__aexit__(None, None, None), 1.0)
                except BROKER_ERRORS:  # already gone
                    pass
            await asyncio.sleep(backoff)
