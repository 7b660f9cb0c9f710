"""The read-only OPC UA server on the demo plant, read with asyncua's own client: browse the DI DeviceSet,
identity and NAMUR health of every device, a subscription to a live value, refused write and call."""

from __future__ import annotations

import asyncio

import pytest
from asyncua import Client, ua
from conftest import free_port
from webutil import eventually, private_endpoints

from app.opcua_server import DEVICE_HEALTH, DI_URI, IDENTITY, OpcuaServer, health_of, status_of
from app.plant import OpcuaConfig, load_plant
from app.runtime import Runtime
from devices.live import DeviceState

pytestmark = pytest.mark.timeout(90)
DEMO_PLANT = "plants/demo.toml"


class _Changes:
    def __init__(self):
        self.values: list = []

    def datachange_notification(self, node, value, data):
        self.values.append((value, data.monitored_item.Value.StatusCode))


async def test_devices_identity_health_subscription_and_refused_write(tmp_path):
    plant = private_endpoints(load_plant(DEMO_PLANT), f"opcua-{tmp_path.name}")
    port = free_port()
    plant.opcua = OpcuaConfig(endpoint=f"opc.tcp://127.0.0.1:{port}")
    runtime = Runtime(plant, data_dir=tmp_path / "data")
    await runtime.start()
    client = Client(f"opc.tcp://127.0.0.1:{port}", timeout=10)
    try:
        await client.connect()  # anonymous: allowed by default, and it only reads
        di = await client.get_namespace_index(DI_URI)
        device_set = await client.nodes.objects.get_child(f"{di}:DeviceSet")
        devices = {(await n.read_browse_name()).Name: n for n in await device_set.get_children()}
        assert set(devices) == set(plant.devices)
        device_type = client.get_node(ua.NodeId(1002, di))
        assert (await device_type.read_browse_name()).Name == "DeviceType"
        for name, node in devices.items():
            assert (await node.read_type_definition()) == ua.NodeId(1002, di), name
            for prop in (*IDENTITY, "RevisionCounter", "DeviceHealth"):
                await (await node.get_child(f"{di}:{prop}")).read_value()  # every device has every property

        async def identities_read():
            found = {}
            for name, node in devices.items():
                found[name] = {p: await (await node.get_child(f"{di}:{p}")).read_value() for p in ("Manufacturer", "Model", "SerialNumber")}
            return found if found["door-1"]["SerialNumber"] == "660020" else None
        identity = await eventually(identities_read, 30, what="door-1's serial number read from the device")
        assert identity["door-1"]["Manufacturer"] == "BSS" and identity["lift-1"]["Manufacturer"] == "Ewellix"
        assert identity["heater-hm"]["Model"] == "CAN-M3IO HM"
        assert all(i["Model"] for i in identity.values())

        async def all_healthy():
            healths = {n: await (await d.get_child(f"{di}:DeviceHealth")).read_value() for n, d in devices.items()}
            return healths if all(DEVICE_HEALTH[h] in ("NORMAL", "OFF_SPEC", "MAINTENANCE_REQUIRED") for h in healths.values()) else None
        await eventually(all_healthy, 30, what="every demo device answers (no FAILURE)")

        # a live value with its unit and status; a subscription sees it change
        params = await devices["lift-1"].get_child(f"{di}:ParameterSet")

        async def some_points():
            return await params.get_children()
        points = await eventually(some_points, 20, what="lift-1's live values")
        units = [await (await p.get_child("0:EngineeringUnits")).read_value() for p in points]
        assert any(u.DisplayName.Text for u in units), "engineering units travel with the values"
        door_params = await devices["door-1"].get_child(f"{di}:ParameterSet")
        target = await eventually(door_params.get_children, 20, what="door-1's live values")
        value = await target[0].read_data_value()
        assert value.StatusCode.is_good() and value.SourceTimestamp is not None

        handler = _Changes()
        subscription = await client.create_subscription(100, handler)
        moving = [n for n in target if (await n.read_browse_name()).Name in ("BoltPosition", "Status", "DoorState")] or target
        await subscription.subscribe_data_change(moving)
        await eventually(lambda: asyncio.sleep(0, bool(handler.values)), 10, what="a data change notification")

        # the twin stops answering: its values turn Bad and its health FAILURE
        runtime.twins["door-1"].silent = True
        health = await devices["door-1"].get_child(f"{di}:DeviceHealth")
        await eventually(lambda: _equals(health, DEVICE_HEALTH.index("FAILURE")), 20, what="door-1's health FAILURE")
        assert (await target[0].read_data_value(raise_on_bad_status=False)).StatusCode.is_bad()
        runtime.twins["door-1"].silent = False

        # read-only for every session: Write and Call are refused by the server's rules
        with pytest.raises(ua.UaStatusCodeError) as err:
            await target[0].write_value(ua.DataValue(ua.Variant(1, ua.VariantType.Int64)))
        assert err.value.code == ua.StatusCodes.BadUserAccessDenied
        with pytest.raises(ua.UaStatusCodeError) as err:
            await (await devices["lift-1"].get_child(f"{di}:SerialNumber")).write_value("forged")
        assert err.value.code == ua.StatusCodes.BadUserAccessDenied
        server_node = client.get_node(ua.ObjectIds.Server)
        with pytest.raises(ua.UaStatusCodeError) as err:
            await server_node.call_method(ua.NodeId(ua.ObjectIds.Server_GetMonitoredItems), ua.Variant(1, ua.VariantType.UInt32))
        assert err.value.code == ua.StatusCodes.BadUserAccessDenied
        await subscription.delete()
    finally:
        await client.disconnect()
        await runtime.stop()


async def _equals(node, expected) -> bool:
    return await node.read_value() == expected


async def test_accounts_only_when_anonymous_is_off(tmp_path):
    from app.plant import parse_plant
    from app.state import StateStore
    from app.users import UserStore

    users = UserStore(tmp_path / "users.toml")
    users.add("tablet", "viewer", "pass-word-1")
    port = free_port()
    plant = parse_plant(f'name = "p"\n[opcua]\nendpoint = "opc.tcp://127.0.0.1:{port}"\nanonymous = false\n')
    store = StateStore()
    store.add(DeviceState("pump", "hdlock", "line1"))
    server = OpcuaServer(plant.opcua, store, plant, users=users)
    await server.start()
    try:
        with pytest.raises(ua.UaStatusCodeError):
            async with Client(f"opc.tcp://127.0.0.1:{port}", timeout=5):
                pass
        client = Client(f"opc.tcp://127.0.0.1:{port}", timeout=5)
        client.set_user("tablet")
        client.set_password("wrong")
        with pytest.raises(ua.UaStatusCodeError):
            async with client:
                pass
        client = Client(f"opc.tcp://127.0.0.1:{port}", timeout=5)
        client.set_user("tablet")
        client.set_password("pass-word-1")
        async with client:
            di = await client.get_namespace_index(DI_URI)
            pump = await client.nodes.objects.get_child([f"{di}:DeviceSet", f"{server.ns}:pump"])
            health = await pump.get_child(f"{di}:DeviceHealth")
            assert await health.read_value() == DEVICE_HEALTH.index("NORMAL")  # never asked: nothing wrong known
            with pytest.raises(ua.UaStatusCodeError) as err:
                await health.write_value(ua.Variant(1, ua.VariantType.Int32))
            assert err.value.code == ua.StatusCodes.BadUserAccessDenied  # logged in, still read-only
    finally:
        await server.stop()


def test_health_and_status_in_namur_terms():
    state = DeviceState("d", "hdlock", "b", stale_after=3.0)
    state.mark_seen()
    assert DEVICE_HEALTH[health_of(state, controlled=False, alarms=[])] == "NORMAL"
    assert DEVICE_HEALTH[health_of(state, controlled=True, alarms=[])] == "CHECK_FUNCTION"
    assert DEVICE_HEALTH[health_of(state, controlled=False, alarms=["fuse blown"])] == "OFF_SPEC"
    state.unsaved.add("holding:3000")
    assert DEVICE_HEALTH[health_of(state, controlled=False, alarms=[])] == "MAINTENANCE_REQUIRED"
    state.mark_offline("no answer")
    assert DEVICE_HEALTH[health_of(state, controlled=True, alarms=[])] == "FAILURE"
    assert status_of("good").is_good() and status_of("stale").is_uncertain() and status_of("offline").is_bad()


@pytest.mark.parametrize("table, words", [
    ('[opcua]\nendpoint = "http://x:4840"\n', "opc.tcp://"),
    ('[opcua]\nanonymous = "no"\n', "true or false"),
    ('[opcua]\ncertificate = "c.der"\n', "both certificate and private_key"),
    ('[opcua]\nendpont = "opc.tcp://a:1"\n', "did you mean 'endpoint'"),
    ('[opcua]\nrate = 0\n', "rate must be a number above 0"),
])
def test_opcua_table_errors(table, words):
    from app.plant import PlantError, parse_plant

    with pytest.raises(PlantError) as err:
        parse_plant('name = "p"\n' + table)
    assert words in str(err.value)
    assert parse_plant('name = "p"\n').opcua is None  # off by default
    assert parse_plant('name = "p"\n[opcua]\n').opcua.endpoint == "opc.tcp://127.0.0.1:4840"
