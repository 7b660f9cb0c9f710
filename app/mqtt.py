"""Publish the plant's live data to an MQTT broker (``[mqtt]`` in the plant file), read-only.

Topic tree and payloads: docs/mqtt.md. Everything is read from the state store
(``DeviceState.values_json()`` / ``summary()``); nothing here talks to a bus, and MQTT carries no
commands: the only topic read is the instance's own instance topic, to notice a takeover of its
client id (its own last will published while it runs, or a birth of another ``session``).

Two asyncio tasks of their own: the *sampler* looks at every device at most ``rate`` times a
second and queues what changed (latest message per topic, so a broker that is away costs a
bounded amount of memory); the *sender* holds the broker connection, publishes the queue and
reconnects with backoff. Neither ever waits for the other, and the bus worker waits for neither.
"""

from __future__ import annotations

import asyncio
import json
import logging
import os
import secrets
import ssl
import time
from collections import OrderedDict, deque
from pathlib import Path
from typing import Any

import aiomqtt

from app.aio import end_tasks
from app.audit import LogBudget
from app.broker import BROKER_ERRORS
from app.plant import MqttConfig
from app.state import jsonable

log = logging.getLogger(__name__)

SCHEMA_VERSION = 1  # docs/mqtt.md "Stability": fields are only ever added within one version
TOPIC_ROOT = "commission"
INSTANCES = "$instances"  # a topic level no device name can take ('$' is not allowed in names)
BACKOFF_FIRST_S = 0.5
BACKOFF_MAX_S = 5.0
CONNECT_TIMEOUT_S = 10.0
PUBLISH_TIMEOUT_S = 5.0
PUBLISH_WINDOW = 16  # retained topics (state, status, alarms) published at QoS 1 without waiting for each other


def device_topic(site: str, device: str, leaf: str) -> str:
    return f"{TOPIC_ROOT}/{site}/{device}/{leaf}"


def instance_topic(site: str, instance: str) -> str:
    return f"{TOPIC_ROOT}/{site}/{INSTANCES}/{instance}"


def dumps(payload: dict[str, Any]) -> bytes:
    return json.dumps(payload, separators=(",", ":"), default=jsonable, allow_nan=False).encode()


def state_payload(state, instance: str, now: float) -> dict[str, Any]:
    """``commission/<site>/<device>/state``: every live value in the one JSON form of a live value
    (``LiveValue.to_json``, the API's too), with unit, quality and time (retained)."""
    return {"schema": "commission-state", "version": SCHEMA_VERSION, "instance": instance, "device": state.name,
            "type": state.type, "bus": state.bus, "status": state.status, "time": now, "values": state.values_json()}


def status_payload(state, instance: str, now: float) -> dict[str, Any]:
    """``commission/<site>/<device>/status``: online state, last error and counters (retained)."""
    s = state.summary()
    return {"schema": "commission-status", "version": SCHEMA_VERSION, "instance": instance, "device": state.name,
            "type": state.type, "bus": state.bus, "status": s["status"], "online": s["online"], "last_seen": s["last_seen"],
            "last_error": s["last_error"], "counters": s["counters"], "time": now,
            "drift": state.drift}


def instance_payload(config: MqttConfig, plant_name: str, devices: list[str], state: str, now: float,
                     reason: str = "", session: str = "") -> dict[str, Any]:
    """``commission/<site>/$instances/<instance>``: birth (``online``), death (``offline``) and the last will;
    ``session``: random per run, so the instance tells its own messages from another client's."""
    payload = {"schema": "commission-instance", "version": SCHEMA_VERSION, "instance": config.instance, "site": config.site,
               "plant": plant_name, "state": state, "devices": devices, "time": now, "heartbeat": config.heartbeat}
    if reason:
        payload["reason"] = reason
    if session:
        payload["session"] = session
    return payload


WILL_REASON = "lost (last will)"
_takeover_lines = LogBudget(lines=10, window_s=60.0)
TAKEOVER_SHOWN_S = 300.0  # the header says "client id taken over" this long after the last one


def _fingerprint(payload: dict[str, Any]) -> bytes:
    """What counts as a change: everything but the publish time and the values' read times."""
    values = {k: {f: v for f, v in item.items() if f != "time"} for k, item in payload.get("values", {}).items()}
    return dumps({**payload, "time": None, "last_seen": None, "values": values})


class MqttPublisher:
    """The instance's broker connection: birth/death, device state, status and alarms (docs/mqtt.md)."""

    def __init__(self, config: MqttConfig, store, plant_name: str, audit=None):
        self.config = config
        self.store = store
        self.plant_name = plant_name
        self.state = "starting"  # "connecting", "connected", "down"
        self.last_error = ""
        self.since = time.time()
        self.sent = 0
        self.dropped = 0  # alarm events dropped from a full buffer
        self.reconnects = 0
        self.session = secrets.token_hex(8)  # this run's: in the birth and the will
        self.takeovers = 0
        self.last_takeover: float | None = None
        self._pending: OrderedDict[str, tuple[bytes, bool]] = OrderedDict()  # topic -> newest retained message
        self._events: deque[tuple[str, bytes]] = deque(maxlen=config.buffer)  # alarm rise/clear, not retained
        self._wake = asyncio.Event()
        self._last: dict[str, tuple[bytes, float]] = {}  # topic -> (fingerprint, time sent to the queue)
        self._alarms: dict[str, set[str]] = {}
        self._tasks: list[asyncio.Task] = []
        self._client = None
        self._password: str | None = None
        self.sparkplug = None  # the Sparkplug B edge node beside the JSON topics (``sparkplug = true``)
        if config.sparkplug:
            from app.sparkplug import SparkplugNode

            self.sparkplug = SparkplugNode(config, store, plant_name, audit=audit, password=self._read_password,
                                           timeout_s=PUBLISH_TIMEOUT_S)

    # -- what the header shows -----------------------------------------------------------------
    @property
    def connected(self) -> bool:
        return self.state == "connected"

    @property
    def client_id(self) -> str:
        return f"commission-{self.config.site}-{self.config.instance}"[:64]

    def summary(self) -> dict[str, Any]:
        state = self.state
        if state == "connected" and self.last_takeover is not None and time.time() - self.last_takeover < TAKEOVER_SHOWN_S:
            state = "connected: client id taken over"
        return {"url": self.config.url, "state": state, "connected": self.connected, "last_error": self.last_error,
                "since": self.since, "sent": self.sent, "queued": len(self._pending) + len(self._events),
                "dropped": self.dropped, "reconnects": self.reconnects, "takeovers": self.takeovers,
                **({"sparkplug": self.sparkplug.summary()} if self.sparkplug is not None else {})}

    def _set_state(self, state: str, error: str = "") -> None:
        if state != self.state or error != self.last_error:
            self.since = time.time()
        self.state, self.last_error = state, error

    # -- life cycle ------------------------------------------------------------------------------
    async def start(self) -> None:
        self._tasks = [asyncio.create_task(self._sample_loop(), name="mqtt sampler"),
                       asyncio.create_task(self._send_loop(), name="mqtt sender")]
        if self.sparkplug is not None:
            await self.sparkplug.start()

    async def stop(self) -> None:
        """Say goodbye (retained ``offline``, reason ``stopped``) if connected, then end both tasks (bounded)."""
        if self.sparkplug is not None:
            await self.sparkplug.stop()  # its NDEATH first, while the store still holds the devices
        client = self._client if self.connected else None
        await end_tasks(self._tasks, "mqtt")
        self._tasks = []
        if client is not None:
            try:
                payload = instance_payload(self.config, self.plant_name, list(self.store.devices), "offline", time.time(), "stopped",
                                           self.session)
                await asyncio.wait_for(client.publish(self._instance_topic, dumps(payload), qos=1, retain=True), 2.0)
                await asyncio.wait_for(client.__aexit__(None, None, None), 2.0)
            except BROKER_ERRORS as exc:  # the last will says the same when this fails
                log.info("mqtt: goodbye not sent (%s); the broker sends the last will", exc)
        self._client = None
        self._set_state("stopped")

    @property
    def _instance_topic(self) -> str:
        return instance_topic(self.config.site, self.config.instance)

    # -- sampler: store -> queue, rate-limited, changes only -------------------------------------
    def _queue(self, topic: str, payload: dict[str, Any], now: float, force: bool = False) -> None:
        mark = _fingerprint(payload)
        last = self._last.get(topic)
        if not force and last is not None and last[0] == mark and now - last[1] < self.config.heartbeat:
            return
        self._last[topic] = (mark, now)
        self._pending[topic] = (dumps(payload), True)
        self._pending.move_to_end(topic)
        self._wake.set()

    def _event(self, topic: str, payload: dict[str, Any]) -> None:
        if len(self._events) == self._events.maxlen:
            self.dropped += 1
        self._events.append((topic, dumps(payload)))
        self._wake.set()

    def sample(self, now: float | None = None) -> None:
        """One look at every device: queue each topic whose content changed (or whose heartbeat is due)."""
        now = time.time() if now is None else now
        site, instance = self.config.site, self.config.instance
        for state in self.store.devices.values():
            self.sample_device(state, site, instance, now)

    def sample_device(self, state, site: str, instance: str, now: float) -> None:
        name = state.name
        self._queue(device_topic(site, name, "state"), state_payload(state, instance, now), now)
        self._queue(device_topic(site, name, "status"), status_payload(state, instance, now), now)
        alarms = set(self.store.active_alarms(name, now))  # evaluated in the store, once per change
        before = self._alarms.get(name, set())
        if alarms != before or device_topic(site, name, "alarms") not in self._last:
            for text in sorted(alarms - before):
                self._event(device_topic(site, name, "alarm"), {"schema": "commission-alarm", "version": SCHEMA_VERSION,
                            "instance": instance, "device": name, "alarm": text, "state": "raised", "time": now})
            for text in sorted(before - alarms):
                self._event(device_topic(site, name, "alarm"), {"schema": "commission-alarm", "version": SCHEMA_VERSION,
                            "instance": instance, "device": name, "alarm": text, "state": "cleared", "time": now})
            self._alarms[name] = alarms
        self._queue(device_topic(site, name, "alarms"), {"schema": "commission-alarms", "version": SCHEMA_VERSION,
                    "instance": instance, "device": name, "active": sorted(alarms), "time": now}, now)

    async def _sample_loop(self) -> None:
        period = 1.0 / self.config.rate
        site, instance = self.config.site, self.config.instance
        while True:
            started = time.monotonic()
            for state in list(self.store.devices.values()):
                try:
                    self.sample_device(state, site, instance, time.time())
                except Exception:  # the publisher must not die: one device's odd value must not stop the others
                    log.exception("mqtt: cannot build the messages of %s", state.name)
                await asyncio.sleep(0)  # a large plant is sampled in slices: the loop carries keep-alives
            await asyncio.sleep(max(0.0, period - (time.monotonic() - started)))

    # -- sender: queue -> broker, reconnect with backoff -------------------------------------------
    async def _read_password(self) -> str | None:
        if self.config.password_env:
            value = os.environ.get(self.config.password_env)
            if value is None:
                raise OSError(f"the environment variable {self.config.password_env} (password_env) is not set")
            return value
        if self.config.password_file:
            path: Path = self.config.password_file
            text = await asyncio.to_thread(path.read_text, encoding="utf-8")
            return text.strip()
        return None

    async def _tls_context(self) -> ssl.SSLContext | None:
        if not self.config.tls:
            return None
        ca = str(self.config.ca_file) if self.config.ca_file else None
        return await asyncio.to_thread(ssl.create_default_context, cafile=ca)  # reads the CA file off the loop

    async def _connect(self):
        will_payload = dumps(instance_payload(self.config, self.plant_name, list(self.store.devices), "offline",
                                              time.time(), WILL_REASON, self.session))
        client = aiomqtt.Client(
            self.config.host, self.config.port, username=self.config.username, password=self._password,
            identifier=self.client_id,
            will=aiomqtt.Will(self._instance_topic, will_payload, qos=1, retain=True),
            keepalive=max(5, int(self.config.heartbeat)), tls_context=await self._tls_context(), timeout=PUBLISH_TIMEOUT_S,
        )
        await asyncio.wait_for(client.__aenter__(), CONNECT_TIMEOUT_S)  # connects in a thread (DNS, TCP, TLS)
        return client

    async def _send_loop(self) -> None:
        backoff = BACKOFF_FIRST_S
        while True:
            self._set_state("connecting", self.last_error)
            try:
                self._password = await self._read_password()
                self._client = await self._connect()
            except asyncio.CancelledError:
                raise
            except BROKER_ERRORS as exc:  # refused, unreachable, bad TLS, no password: a state, not a crash
                why = _why(exc)
                if why != self.last_error:  # logged once per reason, not once per try
                    log.warning("mqtt: broker %s: %s; trying again every %.0f s at most", self.config.url, why, BACKOFF_MAX_S)
                self._set_state("down", why)
                await asyncio.sleep(backoff)
                backoff = min(BACKOFF_MAX_S, backoff * 2)
                continue
            backoff = BACKOFF_FIRST_S
            self._set_state("connected")
            log.info("mqtt: connected to %s as %s/%s", self.config.url, self.config.site, self.config.instance)
            try:
                await self._publish_session(self._client)
            except asyncio.CancelledError:
                raise
            except BROKER_ERRORS as exc:  # the broker went away or stalled
                self._set_state("down", _why(exc))
                log.warning("mqtt: lost the broker %s: %s", self.config.url, self.last_error)
                self.reconnects += 1
                client, self._client = self._client, None
                try:
                    await asyncio.wait_for(client.__aexit__(None, None, None), 1.0)
                except BROKER_ERRORS:  # already gone
                    pass
                self._last.clear()  # a broker without persistence lost every retained message: send all again
                await asyncio.sleep(backoff)

    def on_own_topic(self, payload: bytes, retained: bool = False) -> None:
        """A message on this instance's own instance topic: its own last will (the broker closed this
        connection: another client connected with its client id, or the broker dropped it), or a birth
        of another run (a second instance of the same name, or a client posing as it), is a takeover."""
        try:
            data = json.loads(payload) if payload else {}
        except ValueError:
            data = {}
        if not isinstance(data, dict):
            data = {}
        session = data.get("session")
        if session == self.session and data.get("reason") == WILL_REASON:
            what = ("the broker published this instance's last will while it runs: another client connected with its "
                    f"client id {self.client_id!r}, or the broker dropped the connection")
        elif data.get("state") == "online" and session != self.session and not retained:
            # (a retained birth of another session is the last run's, before its connection timed out)
            what = f"another client publishes as this instance on {self._instance_topic} (client id {self.client_id!r} or its name)"
        else:
            return
        self.takeovers += 1
        self.last_takeover = time.time()
        if _takeover_lines.take() is None:
            return  # a client taking the id again and again: counted, logged at most 10 times a minute
        log.warning("mqtt: %s; give each instance a broker account and let the broker take it as the client id "
                    "(docs/mqtt.md, \"The broker's side\")", what)

    async def _watch_own_topic(self, client) -> None:
        async for message in client.messages:
            if str(message.topic) == self._instance_topic:
                payload = message.payload if isinstance(message.payload, bytes | bytearray) else b""
                self.on_own_topic(bytes(payload)[:65536], bool(message.retain))

    async def _publish_session(self, client) -> None:
        watcher = None
        try:
            await client.subscribe(self._instance_topic, qos=1)
            watcher = asyncio.create_task(self._watch_own_topic(client), name="mqtt own topic")
        except BROKER_ERRORS as exc:  # a broker that refuses the subscription: publishing goes on
            log.info("mqtt: cannot read the instance's own topic (%s): a takeover of its client id is not noticed", _why(exc))
        try:
            await self._publish_until_lost(client)
        finally:
            if watcher is not None:
                await end_tasks([watcher], "mqtt own topic")

    async def _publish_until_lost(self, client) -> None:
        birth = instance_payload(self.config, self.plant_name, list(self.store.devices), "online", time.time(),
                                 session=self.session)
        await client.publish(self._instance_topic, dumps(birth), qos=1, retain=True)
        self.sent += 1
        self._last.clear()  # the first look after a (re)connect sends everything
        next_birth = time.monotonic() + self.config.heartbeat
        inflight: set[asyncio.Task] = set()
        failed: list[BaseException] = []
        try:
            await self._publish_loop(client, birth, next_birth, inflight, failed)
        finally:
            for task in list(inflight):
                task.cancel()

    async def _publish_loop(self, client, birth: dict, next_birth: float, inflight: set, failed: list) -> None:
        while True:
            if failed:
                raise failed[0]
            if time.monotonic() >= next_birth:  # the instance's heartbeat: subscribers tell a stalled one
                birth["time"] = time.time()
                await client.publish(self._instance_topic, dumps(birth), qos=1, retain=True)
                self.sent += 1
                next_birth = time.monotonic() + self.config.heartbeat
            if self._events:
                topic, payload = self._events[0]
                await client.publish(topic, payload, qos=1, retain=False)
                self._events.popleft()  # only once the broker has it
                self.sent += 1
                continue
            if self._pending and len(inflight) < PUBLISH_WINDOW:
                # several retained topics in flight at once: an instance's rate is not one round trip through
                # its event loop per message (a cabinet on a busy machine fell behind its own 20 devices)
                topic, (payload, retain) = next(iter(self._pending.items()))
                del self._pending[topic]  # a newer one queued meanwhile goes out after it; a lost broker sends all again
                task = asyncio.create_task(client.publish(topic, payload, qos=1, retain=retain))
                inflight.add(task)
                task.add_done_callback(lambda t: self._published(t, inflight, failed))
                continue
            if failed:
                raise failed[0]
            self._wake.clear()
            try:
                await asyncio.wait_for(self._wake.wait(), max(0.05, next_birth - time.monotonic()))
            except TimeoutError:
                pass

    def _published(self, task: asyncio.Task, inflight: set, failed: list) -> None:
        """A retained topic's publish ended: counted when the broker has it, its error ends the session."""
        inflight.discard(task)
        if task.cancelled():
            return
        if task.exception() is not None:
            failed.append(task.exception())
        else:
            self.sent += 1
        self._wake.set()


def _why(exc: BaseException) -> str:
    text = str(exc) or type(exc).__name__
    if isinstance(exc, TimeoutError | asyncio.TimeoutError):
        text = "no answer from the broker (timeout)"
    return text
