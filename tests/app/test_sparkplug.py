"""Sparkplug B on Mosquitto, read by a host of the test's own with a protobuf wire decoder written here
from the spec's sparkplug_b.proto (field numbers and wire types), independent of app/sparkplug.py's classes.

Two instances (the demo plant, and one HD-Lock line whose twin runs in a ``commission sim`` process)
publish; the host sees their births, data and deaths, sends Rebirth (same bdSeq, same definitions,
no reconnect), and a DCMD write that is refused and audited. The primary host's STATE is honoured.
"""

from __future__ import annotations

import asyncio
import signal
import sqlite3
import struct
import time

import aiomqtt
import pytest
from test_mqtt_helpers import running_broker
from test_mqtt_site import _spawn, plant_b
from conftest import one_device_store
from webutil import demo_plant_text, free_port, stop_app

pytestmark = pytest.mark.timeout(120)

DEMO_DEVICES = {"door-1", "door-2", "gate-1", "gate-2", "lift", "heater-hm", "heater-hmr", "lift-1", "barrier-in",
                "barrier-out-1", "barrier-out-2"}


# -- an independent decoder of the protobuf wire format (proto2, sparkplug_b.proto) --------------
def _varint(data: bytes, i: int) -> tuple[int, int]:
    shift = result = 0
    while True:
        b = data[i]
        i += 1
        result |= (b & 0x7F) << shift
        if not b & 0x80:
            return result, i
        shift += 7


def _fields(data: bytes):
    i = 0
    while i < len(data):
        key, i = _varint(data, i)
        number, wire = key >> 3, key & 7
        if wire == 0:
            value, i = _varint(data, i)
        elif wire == 1:
            value, i = data[i:i + 8], i + 8
        elif wire == 5:
            value, i = data[i:i + 4], i + 4
        elif wire == 2:
            size, i = _varint(data, i)
            value, i = data[i:i + size], i + size
        else:
            raise ValueError(f"wire type {wire}")
        yield number, wire, value


def _signed64(v: int) -> int:
    return v - (1 << 64) if v >= 1 << 63 else v


def decode_property_set(data: bytes) -> dict:
    keys, values = [], []
    for number, _wire, value in _fields(data):
        if number == 1:
            keys.append(value.decode())
        elif number == 2:
            pv = {}
            for n, _w, v in _fields(value):
                if n == 1:
                    pv["type"] = v
                elif n == 3:
                    pv["value"] = v
                elif n == 8:
                    pv["value"] = v.decode()
            values.append(pv.get("value"))
    return dict(zip(keys, values, strict=True))


def decode_metric(data: bytes) -> dict:
    m: dict = {"is_null": False}
    for number, _wire, value in _fields(data):
        if number == 1:
            m["name"] = value.decode()
        elif number == 3:
            m["timestamp"] = value
        elif number == 4:
            m["datatype"] = value
        elif number == 7:
            m["is_null"] = bool(value)
        elif number == 9:
            m["properties"] = decode_property_set(value)
        elif number in (10, 11):
            m["value"] = value
        elif number == 13:
            m["value"] = struct.unpack("<d", value)[0]
        elif number == 12:
            m["value"] = struct.unpack("<f", value)[0]
        elif number == 14:
            m["value"] = bool(value)
        elif number == 15:
            m["value"] = value.decode()
        elif number == 16:
            m["value"] = bytes(value)
    if m.get("datatype") == 4 and isinstance(m.get("value"), int):
        m["value"] = _signed64(m["value"])
    return m


def decode_payload(data: bytes) -> dict:
    p: dict = {"metrics": []}
    for number, _wire, value in _fields(data):
        if number == 1:
            p["timestamp"] = value
        elif number == 2:
            p["metrics"].append(decode_metric(value))
        elif number == 3:
            p["seq"] = value
    return p


def _key(number: int, wire: int) -> bytes:
    return _enc_varint(number << 3 | wire)


def _enc_varint(v: int) -> bytes:
    out = bytearray()
    while True:
        b = v & 0x7F
        v >>= 7
        out.append(b | (0x80 if v else 0))
        if not v:
            return bytes(out)


def _lenp(number: int, data: bytes) -> bytes:
    return _key(number, 2) + _enc_varint(len(data)) + data


def encode_command(name: str, datatype: int, value) -> bytes:
    """An NCMD/DCMD payload with one metric, encoded by hand."""
    metric = _lenp(1, name.encode()) + _key(4, 0) + _enc_varint(datatype)
    if isinstance(value, bool):
        metric += _key(14, 0) + _enc_varint(int(value))
    else:
        metric += _key(13, 1) + struct.pack("<d", float(value))
    return _key(1, 0) + _enc_varint(int(time.time() * 1000)) + _lenp(2, metric)


# -- the host ---------------------------------------------------------------------------------------
class Host:
    """Subscribes to ``spBv1.0/#`` and keeps every message decoded, in order of arrival."""

    def __init__(self, port: int):
        self.port = port
        self.messages: list[tuple[str, dict, bytes]] = []
        self.client: aiomqtt.Client | None = None
        self._task = None

    async def __aenter__(self):
        self.client = aiomqtt.Client("127.0.0.1", self.port, identifier=f"host-{self.port}")
        await self.client.__aenter__()
        await self.client.subscribe("spBv1.0/#", qos=1)
        self._task = asyncio.create_task(self._read())
        return self

    async def __aexit__(self, *exc):
        self._task.cancel()
        await asyncio.gather(self._task, return_exceptions=True)
        await self.client.__aexit__(None, None, None)

    async def _read(self):
        async for message in self.client.messages:
            topic = str(message.topic)
            payload = bytes(message.payload)
            decoded = decode_payload(payload) if "/STATE/" not in topic else {}
            self.messages.append((topic, decoded, payload))

    def of(self, kind: str, node: str, device: str | None = None, since: int = 0) -> list[dict]:
        wanted = f"spBv1.0/hall-3/{kind}/{node}" + (f"/{device}" if device else "")
        return [p for t, p, _ in self.messages[since:] if t == wanted]

    async def until(self, check, timeout: float, what: str):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            result = check()
            if result:
                return result
            await asyncio.sleep(0.05)
        raise AssertionError(f"not within {timeout} s: {what}; topics seen: {sorted({t for t, _, _ in self.messages})}")


def metrics(payload: dict) -> dict[str, dict]:
    return {m["name"]: m for m in payload["metrics"]}


def definitions(payload: dict) -> dict[str, int]:
    return {m["name"]: m["datatype"] for m in payload["metrics"]}


def _audit_rows(path) -> list[tuple]:
    db = sqlite3.connect(str(path))
    try:
        return db.execute("SELECT device, action, parameter, new, result FROM audit").fetchall()
    finally:
        db.close()


async def test_births_data_rebirth_refusal_and_death_of_two_instances(tmp_path):
    with running_broker(tmp_path, free_port()) as broker:
        a = demo_plant_text(free_port()).replace(
            'name = "demo"', f'name = "cab-a"\n\n[mqtt]\nurl = "{broker.url}"\nsite = "hall-3"\nsparkplug = true\nrate = 4', 1)
        (tmp_path / "a.toml").write_text(a)
        (tmp_path / "b.toml").write_text(plant_b(broker.url).replace("heartbeat = 2", "sparkplug = true"))
        async with Host(broker.port) as host:
            procs = {
                "sim-b": _spawn(["sim", "--plant", str(tmp_path / "b.toml")], tmp_path / "sim-b.log"),
                "a": _spawn(["--plant", str(tmp_path / "a.toml"), "--port", str(free_port()), "--data-dir", str(tmp_path / "da")],
                            tmp_path / "a.log"),
                "b": _spawn(["--plant", str(tmp_path / "b.toml"), "--no-sim", "--port", str(free_port()), "--data-dir",
                             str(tmp_path / "db")], tmp_path / "b.log"),
            }
            try:
                # births: NBIRTH with bdSeq and Rebirth, then a DBIRTH per device with values, quality and units
                for node in ("cab-a", "cab-b"):
                    nbirth = (await host.until(lambda n=node: host.of("NBIRTH", n), 40, f"NBIRTH of {node}"))[0]
                    names = metrics(nbirth)
                    assert names["bdSeq"]["datatype"] == 4 and names["Node Control/Rebirth"] == {**names["Node Control/Rebirth"], "value": False}
                    assert nbirth["seq"] == 0
                await host.until(lambda: all(host.of("DBIRTH", "cab-a", d) for d in DEMO_DEVICES), 40, "a DBIRTH of every demo device")
                await host.until(lambda: host.of("DBIRTH", "cab-b", "door-9"), 20, "DBIRTH of door-9")
                birth_seq_a = metrics(host.of("NBIRTH", "cab-a")[0])["bdSeq"]["value"]
                door = metrics(host.of("DBIRTH", "cab-a", "door-1")[-1])
                some = next(m for m in door.values() if not m["is_null"])
                assert {"Quality"} <= set(some["properties"]) and some["properties"]["Quality"] in (0, 192, 500)
                assert some["timestamp"] > 1_600_000_000_000
                assert any(m.get("properties", {}).get("engUnit") for m in door.values()), "units travel as engUnit"

                # data: DDATA with changed metrics only, every metric one the device was born with
                ddata = await host.until(lambda: [p for t, p, _ in host.messages if "/DDATA/cab-a/" in t], 30, "DDATA of cab-a")
                born = set()
                for t, p, _ in host.messages:
                    if "/DBIRTH/cab-a/" in t:
                        born |= set(definitions(p))
                for p in ddata:
                    assert 0 < len(p["metrics"]) and set(definitions(p)) <= born
                await host.until(lambda: [p for t, p, _ in host.messages if "/DDATA/cab-b/door-9" in t], 30, "DDATA of door-9")

                # seq runs 0..255 over every message of a node after its NBIRTH
                seqs = [p["seq"] for t, p, _ in host.messages if "/cab-a" in t and "/NDEATH/" not in t]
                assert seqs[0] == 0 and all((b - a) % 256 == 1 for a, b in zip(seqs, seqs[1:], strict=False))

                # Rebirth: on the same connection, the same bdSeq, the same definitions, fresh values
                await asyncio.sleep(1.0)  # let the definitions settle: values read once at start have all been heard
                before = {d: definitions(host.of("DBIRTH", "cab-a", d)[-1]) for d in DEMO_DEVICES}
                # a device whose new values arrived after its birth has been born again since; take the last birth
                mark = len(host.messages)
                await host.client.publish("spBv1.0/hall-3/NCMD/cab-a", encode_command("Node Control/Rebirth", 11, True), qos=1)
                nbirth = (await host.until(lambda: host.of("NBIRTH", "cab-a", since=mark), 10, "NBIRTH after Rebirth"))[0]
                assert metrics(nbirth)["bdSeq"]["value"] == birth_seq_a
                await host.until(lambda: all(host.of("DBIRTH", "cab-a", d, since=mark) for d in DEMO_DEVICES), 10, "every DBIRTH again")
                assert not host.of("NDEATH", "cab-a", since=mark), "Rebirth must not reconnect"
                for d in DEMO_DEVICES:
                    again = definitions(host.of("DBIRTH", "cab-a", d, since=mark)[0])
                    assert again == before[d] or set(before[d]) <= set(again), d  # grown only by values first heard meanwhile
                    assert {k: again[k] for k in before[d]} == before[d], f"{d}: datatypes changed on Rebirth"

                # read-only: a DCMD write is refused, audited and never executed
                await host.client.publish("spBv1.0/hall-3/DCMD/cab-a/door-1", encode_command("LockRequestDelay", 10, 500), qos=1)
                await host.client.publish("spBv1.0/hall-3/NCMD/cab-a", encode_command("Node Control/Reboot", 11, True), qos=1)

                def refused():
                    rows = _audit_rows(tmp_path / "da" / "audit.sqlite")
                    return [r for r in rows if r[1].startswith("Sparkplug") and r[4].startswith("refused")]
                rows = await host.until(lambda: len(refused()) >= 2, 10, "the refused commands in the audit log") and refused()
                assert {(r[0], r[1], r[2]) for r in rows} == {("cab-a", "Sparkplug DCMD", "door-1: LockRequestDelay"),
                                                             ("cab-a", "Sparkplug NCMD", "Node Control/Reboot")}

                # death: a killed instance's NDEATH is its will, with the bdSeq of its birth
                bd_b = metrics(host.of("NBIRTH", "cab-b")[-1])["bdSeq"]["value"]
                procs["b"].send_signal(signal.SIGKILL)
                death = (await host.until(lambda: host.of("NDEATH", "cab-b"), 15, "NDEATH (will) of cab-b"))[0]
                assert metrics(death)["bdSeq"]["value"] == bd_b
                # a stopped one says it itself
                stop_app(procs["a"])
                death = (await host.until(lambda: host.of("NDEATH", "cab-a"), 15, "NDEATH of cab-a"))[0]
                assert metrics(death)["bdSeq"]["value"] == birth_seq_a
            finally:
                for proc in procs.values():
                    stop_app(proc)


async def test_primary_host_state_is_honoured(tmp_path):
    from app.plant import parse_plant
    from app.sparkplug import SparkplugNode

    with running_broker(tmp_path, free_port()) as broker:
        plant = parse_plant(f'name = "cab-c"\n[mqtt]\nurl = "{broker.url}"\nsite = "hall-3"\nsparkplug = true\n'
                            'primary_host = "scada"\nrate = 20\n')
        store, state = one_device_store("pump")
        node = SparkplugNode(plant.mqtt, store, "cab-c")
        async with Host(broker.port) as host:
            await node.start()
            try:
                await host.until(lambda: node.state == "waiting for the primary host", 10, "the node waits for the host")
                await asyncio.sleep(0.3)  # time for a premature birth to arrive: none may
                assert not host.of("NBIRTH", "cab-c"), "no birth while the primary host is not online"
                await host.client.publish("spBv1.0/STATE/scada", b'{"online": true, "timestamp": 1}', qos=1, retain=True)
                await host.until(lambda: host.of("DBIRTH", "cab-c", "pump"), 10, "births once the host is online")
                first_bd = metrics(host.of("NBIRTH", "cab-c")[0])["bdSeq"]["value"]
                state.publish("Speed", 2.5, "rpm")
                data = await host.until(lambda: host.of("DDATA", "cab-c", "pump"), 10, "DDATA of the change")
                assert metrics(data[0])["Speed"]["value"] == 2.5 and "engUnit" not in metrics(data[0])["Speed"].get("properties", {})
                mark = len(host.messages)
                await host.client.publish("spBv1.0/STATE/scada", b'{"online": false, "timestamp": 2}', qos=1, retain=True)
                death = (await host.until(lambda: host.of("NDEATH", "cab-c", since=mark), 10, "NDEATH when the host goes"))[0]
                assert metrics(death)["bdSeq"]["value"] == first_bd
                mark = len(host.messages)
                state.publish("Speed", 3.5, "rpm")
                await asyncio.sleep(0.5)  # time for a publication to arrive while the host is offline: none may
                assert not host.of("DDATA", "cab-c", "pump", since=mark), "nothing published while the host is offline"
                await host.client.publish("spBv1.0/STATE/scada", b'{"online": true, "timestamp": 3}', qos=1, retain=True)
                nbirth = (await host.until(lambda: host.of("NBIRTH", "cab-c", since=mark), 10, "born again"))[0]
                assert metrics(nbirth)["bdSeq"]["value"] == (first_bd + 1) % 256
                assert metrics(host.of("DBIRTH", "cab-c", "pump", since=mark)[0])["Speed"]["value"] == 3.5
            finally:
                await node.stop()


def test_mqtt_table_sparkplug_keys():
    from app.plant import PlantError, parse_plant

    base = 'name = "p"\n[mqtt]\nurl = "mqtt://b"\n'
    assert parse_plant(base).mqtt.sparkplug is False
    cfg = parse_plant(base + 'sparkplug = true\nprimary_host = "ignition"\n').mqtt
    assert cfg.sparkplug is True and cfg.primary_host == "ignition"
    for extra, words in (('sparkplug = "yes"\n', "true or false"), ('primary_host = "scada"\n', "add sparkplug = true"),
                         ('sparkplug = true\nprimary_host = "a/b"\n', "topic level")):
        with pytest.raises(PlantError) as err:
            parse_plant(base + extra)
        assert words in str(err.value)
