"""MQTT client-id takeover (issue 41, item 11): the Mosquitto configuration of docs/mqtt.md (accounts,
ACLs, the user name as client id) keeps outsiders from writing an instance's topics and from taking its
client id; on a broker without it, a takeover is detected, logged and shown."""

from __future__ import annotations

import asyncio
import json
import logging
import os
import re
import subprocess
from pathlib import Path

import aiomqtt
import pytest
from conftest import free_port, one_device_store
from webutil import eventually
from test_mqtt_helpers import MOSQUITTO, running_broker

from app.mqtt import MqttPublisher
from app.plant import parse_plant

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.timeout(90)
INSTANCE_TOPIC = "commission/hall-3/$instances/cab-a"


def _publisher(url: str, extra: str = "") -> MqttPublisher:
    plant = parse_plant(f'name = "cab-a"\n[mqtt]\nurl = "{url}"\nsite = "hall-3"\ninstance = "cab-a"\nheartbeat = 2\n{extra}')
    store, _ = one_device_store("door-1")
    return MqttPublisher(plant.mqtt, store, "cab-a")


class Watcher:
    """A subscriber that keeps every message on ``topic`` as (topic, decoded JSON or raw)."""

    def __init__(self, port: int, topic: str, **login):
        self.client = aiomqtt.Client("127.0.0.1", port, **login)
        self.topic, self.messages, self._task = topic, [], None

    async def __aenter__(self):
        await self.client.__aenter__()
        await self.client.subscribe(self.topic, qos=1)
        self._task = asyncio.create_task(self._read())
        return self

    async def _read(self):
        async for message in self.client.messages:
            try:
                self.messages.append((str(message.topic), json.loads(message.payload)))
            except ValueError:
                self.messages.append((str(message.topic), message.payload))

    async def __aexit__(self, *exc):
        self._task.cancel()
        await asyncio.gather(self._task, return_exceptions=True)
        await self.client.__aexit__(None, None, None)

    def wills(self) -> list:
        return [p for _t, p in self.messages if isinstance(p, dict) and p.get("reason") == "lost (last will)"]


async def test_a_takeover_of_the_client_id_is_detected_and_shown(tmp_path, caplog):
    caplog.set_level(logging.WARNING, logger="app.mqtt")
    with running_broker(tmp_path, free_port()) as broker:
        publisher = _publisher(broker.url)
        await publisher.start()
        try:
            await eventually(lambda: publisher.connected and publisher.sent > 2, 10, what="the instance connected")
            intruder = aiomqtt.Client("127.0.0.1", broker.port, identifier="commission-hall-3-cab-a")
            await intruder.__aenter__()
            await asyncio.sleep(0.5)  # the intruder holds the instance's client id for a while
            try:  # bounded: when the broker already dropped the intruder, its disconnect may wait for nothing
                await asyncio.wait_for(intruder.__aexit__(None, None, None), 5)
            except (aiomqtt.MqttError, TimeoutError):
                pass  # the instance took its id back meanwhile
            await eventually(lambda: publisher.summary().get("takeovers", 0) >= 1, 15, what="the takeover detected")
            assert "taken over" in publisher.summary()["state"]
            assert any("client id" in r.getMessage() and "commission-hall-3-cab-a" in r.getMessage() for r in caplog.records)
        finally:
            await publisher.stop()


def _doc_block(first_line: str) -> str:
    text = (ROOT / "docs" / "mqtt.md").read_text()
    blocks = re.findall(r"```conf\n(.*?)```", text, re.DOTALL)
    found = [b for b in blocks if b.startswith(first_line)]
    assert found, f"docs/mqtt.md has no block starting with {first_line!r}"
    return found[0]


async def test_the_documented_acls_keep_outsiders_out(tmp_path, monkeypatch):
    port = free_port()
    conf = _doc_block("# /etc/mosquitto/conf.d/commission.conf")
    acl = _doc_block("# /etc/mosquitto/commission.acl")
    passwd = tmp_path / "commission.passwd"
    for n, (user, password) in enumerate((("cab-a", "pw-cab-a"), ("view", "pw-view"))):
        subprocess.run(["mosquitto_passwd", *(["-c"] if n == 0 else []), "-b", str(passwd), user, password], check=True,
                       capture_output=True)
    (tmp_path / "commission.acl").write_text(acl)
    conf = conf.replace("/etc/mosquitto/commission.passwd", str(passwd)).replace("/etc/mosquitto/commission.acl",
                                                                                  str(tmp_path / "commission.acl"))
    with running_broker(tmp_path, port) as broker:
        broker.stop()
        # started as root, mosquitto drops to its own user, which cannot read the test's private folder
        keep_user = "user root\n" if os.geteuid() == 0 else ""
        broker.conf.write_text(f"listener {port} 127.0.0.1\npersistence false\n{keep_user}" + conf)
        broker.start()
        assert Path(MOSQUITTO).exists()
        monkeypatch.setenv("MQTT_PASSWORD_H4", "pw-cab-a")
        publisher = _publisher(broker.url, 'username = "cab-a"\npassword_env = "MQTT_PASSWORD_H4"\n')
        async with Watcher(port, "commission/#", username="view", password="pw-view") as watcher:
            await publisher.start()
            try:
                await eventually(lambda: any(t == INSTANCE_TOPIC and isinstance(p, dict) and p.get("state") == "online"
                                         for t, p in watcher.messages), 10, what="the instance's birth, read by the viewer")
                # a viewer cannot write the instance's topics
                async with aiomqtt.Client("127.0.0.1", port, username="view", password="pw-view") as forger:
                    await forger.publish(INSTANCE_TOPIC, b'{"state": "offline", "reason": "lost (last will)"}', qos=1)
                    await forger.publish("commission/hall-3/door-1/state", b'{"forged": true}', qos=1)
                # a client with the instance's client id but another account does not take its place
                async with aiomqtt.Client("127.0.0.1", port, username="view", password="pw-view",
                                          identifier="commission-hall-3-cab-a"):
                    await asyncio.sleep(1.0)  # the impostor stays connected for a second: it must not take the instance's place
                await asyncio.sleep(0.5)  # time for a forged will or message to arrive: none may
                assert not watcher.wills(), watcher.wills()
                assert not any(isinstance(p, dict) and p.get("forged") for _t, p in watcher.messages)
                assert publisher.reconnects == 0 and publisher.summary().get("takeovers", 0) == 0
            finally:
                await publisher.stop()
