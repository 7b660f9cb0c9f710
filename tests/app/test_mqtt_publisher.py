"""The [mqtt] table, and the publisher in-process: broker down at start, stopped and restarted, bounded queue."""

from __future__ import annotations

import asyncio
import json

import aiomqtt
import pytest
from conftest import free_port, modbus_plant
from test_mqtt_helpers import Broker, mqtt_table
from webutil import eventually, simulated_user

from app.mqtt import MqttPublisher, device_topic, instance_topic
from app.plant import PlantError, parse_plant
from app.runtime import Runtime
from app.state import StateStore

pytestmark = pytest.mark.timeout(60)


@pytest.mark.parametrize("table, line, words", [
    ('[mqtt]\nsite = "a"\n', 2, "'url' is required"),
    ('[mqtt]\nurl = "http://b:1883"\n', 3, "mqtt:// or mqtts://"),
    ('[mqtt]\nurl = "mqtt://user:pw@b"\n', 3, "use username"),
    ('[mqtt]\nurl = "mqtt://b"\npassword = "secret"\n', 4, "never goes in the plant file"),
    ('[mqtt]\nurl = "mqtt://b"\nrat = 2\n', 4, "did you mean 'rate'"),
    ('[mqtt]\nurl = "mqtt://b"\nrate = 0\n', 4, "rate must be a number above 0"),
    ('[mqtt]\nurl = "mqtt://b"\nrate = "2"\n', 4, "rate must be a number"),
    ('[mqtt]\nurl = "mqtt://b"\nsite = "hall/3"\n', 4, "topic level"),
    ('[mqtt]\nurl = "mqtt://b"\nca_file = "ca.pem"\n', 4, "mqtts://"),
    ('[mqtt]\nurl = "mqtt://b"\npassword_env = "PW"\n', 4, "needs username"),
    ('[mqtt]\nurl = "mqtt://b"\nbuffer = 5\n', 4, "10..100000"),
    ('mqtt = "mqtt://b"\n', 2, "[mqtt] must be a table"),
])
def test_mqtt_table_errors_name_file_line_and_problem(table, line, words):
    with pytest.raises(PlantError) as err:
        parse_plant('name = "p"\n' + table, None)
    assert f"<plant>:{line}:" in str(err.value)
    assert words in str(err.value)


def test_mqtt_table_defaults_and_tls(tmp_path):
    plant = parse_plant('name = "cab-a"\n[mqtt]\nurl = "mqtts://broker.local"\nusername = "u"\npassword_file = "pw"\nca_file = "ca.pem"\n',
                        tmp_path / "site.toml")
    cfg = plant.mqtt
    assert (cfg.host, cfg.port, cfg.tls, cfg.site, cfg.instance, cfg.rate) == ("broker.local", 8883, True, "cab-a", "cab-a", 2.0)
    assert cfg.password_file == tmp_path / "pw" and cfg.ca_file == tmp_path / "ca.pem"
    assert parse_plant('name = "x"\n').mqtt is None


async def test_queue_is_bounded_and_changes_only_while_the_broker_is_away():
    plant = parse_plant('name = "p"\n' + mqtt_table("mqtt://127.0.0.1:1", buffer=10))
    store = StateStore()
    from devices.live import DeviceState

    for i in range(5):
        store.add(DeviceState(f"d{i}", "hdlock", "line1", stale_after=1e9))
    pub = MqttPublisher(plant.mqtt, store, "p")
    pub.sample(now=1000.0)
    queued = len(pub._pending)
    assert queued == 5 * 3  # state, status, alarms per device: the newest message per topic only
    pub._pending.clear()
    pub.sample(now=1000.5)
    assert not pub._pending  # nothing changed: nothing queued
    store.devices["d0"].publish("BoltPosition", 5, "Inc", time=1000.6)
    for _ in range(100):
        pub.sample(now=1001.0)
    assert list(pub._pending) == [device_topic("hall-3", "d0", "state")]
    for i in range(50):  # alarm events beyond the buffer are dropped and counted
        pub._event("t", {"i": i})
    assert len(pub._events) == 10 and pub.dropped == 40
    pub.sample(now=1000.0 + plant.mqtt.heartbeat + 2)  # the heartbeat re-sends unchanged devices
    assert len(pub._pending) == 5 * 3


async def _retained(url_port: int, topic: str, timeout: float = 8.0) -> dict:
    async with aiomqtt.Client("127.0.0.1", url_port) as client:
        await client.subscribe(topic)
        async with asyncio.timeout(timeout):
            async for message in client.messages:
                if message.payload:
                    return json.loads(message.payload)
    raise AssertionError("no message")


async def test_broker_down_at_start_then_stopped_and_restarted(tmp_path):
    loop_errors: list = []
    asyncio.get_running_loop().set_exception_handler(lambda loop, context: loop_errors.append(context))
    port = free_port()
    broker = Broker(tmp_path, port)
    plant = modbus_plant(locks=(("door-1", 1),))
    plant.mqtt = parse_plant('name = "p"\n' + mqtt_table(broker.url, heartbeat=1)).mqtt
    plant.mqtt.instance = "cab-t"
    runtime = Runtime(plant, simulate=True)
    try:
        async with simulated_user(runtime) as user:
            await user.open("/")
            await eventually(lambda: runtime.mqtt.state == "down", timeout=5)
            await user.should_see("broker down", retries=30)  # header, refreshed every 2 s
            assert runtime.store.devices["door-1"].status == "online"  # the buses run on
            broker.start()
            await eventually(lambda: runtime.mqtt.connected, timeout=10, what="connected after the broker came")
            await user.should_see("broker connected", retries=30)
            state = await _retained(port, device_topic("hall-3", "door-1", "state"))
            bolt = state["values"]["BoltPosition"]
            assert isinstance(bolt["value"], int) and bolt["quality"] == "good" and bolt["time"] > 0
            birth = await _retained(port, instance_topic("hall-3", "cab-t"))
            assert birth["state"] == "online" and birth["devices"] == ["door-1"]
            broker.stop()
            await eventually(lambda: runtime.mqtt.state in ("down", "connecting"), timeout=10, what="broker loss noticed")
            assert runtime.store.devices["door-1"].status == "online"
            broker.start()  # persistence false: every retained message is gone until the publisher sends again
            await eventually(lambda: runtime.mqtt.connected, timeout=15, what="reconnected")
            state = await _retained(port, device_topic("hall-3", "door-1", "state"))
            assert state["device"] == "door-1" and state["status"] == "online"
            assert runtime.mqtt.reconnects >= 1
    finally:
        broker.stop()
    assert not loop_errors, loop_errors
