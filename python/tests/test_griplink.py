"""The GRIPLINK client (blocking) against the in-process simulated controller."""

from __future__ import annotations

import threading

import pytest

import gripper_rs
from gripper_rs import _native, griplink
from gripper_rs.griplink.sim import SimServer

RECIPE = [5.0, 18.0, 50.0, 0.0, 0.0, 0.0, 0.0, 0.0]


def test_controller_identity(griplink_client: griplink.Client) -> None:
    assert griplink_client.id() == "GRIPLINK-ET4"
    griplink_client.protocol_assert("GRIPLINK", 3)
    assert griplink_client.serial_number() == "123456"
    assert griplink_client.set_label("cell 7") == "cell 7"
    assert griplink_client.label() == "cell 7"
    assert griplink_client.version() == "4.0.0"
    assert griplink_client.set_verbose(True) is True
    with pytest.raises(gripper_rs.DeviceError):
        griplink_client.protocol_assert("GRIPLINK", 99)


def test_port_identity_and_values(griplink_client: griplink.Client) -> None:
    port = griplink_client.port(0)
    assert port.number == 0
    assert port.vendor_id() == 815
    assert port.product_id() == 20
    port.assert_device(815, 20)
    assert port.name() == "IEG 55-020"
    assert port.vendor() == "WEISS ROBOTICS"
    assert port.set_tag("left") == "left"
    assert port.tag() == "left"
    assert griplink_client.port(1).vendor_id() is None  # an empty port
    with pytest.raises(ValueError):
        griplink_client.port(32)


def test_grip_and_release(griplink_client: griplink.Client, griplink_sim: SimServer) -> None:
    port = griplink_client.port(0)
    port.home()
    stored = port.set_grip_config_f(1, "part", RECIPE)
    assert stored == griplink.GripConfigF(tag="part", params=RECIPE)
    assert port.grip_config_f(1) == stored
    assert port.grip_and_wait(1, poll_interval_s=0.01) is griplink.GripOutcome.HOLDING
    assert port.position_mm() == 12.0
    assert port.position_um() == 12000
    assert port.state() is griplink.DeviceState.HOLDING
    assert griplink_sim.device_state(0) is griplink.DeviceState.HOLDING
    assert port.release_and_wait(1) is griplink.ReleaseOutcome.RELEASED
    assert port.state() is griplink.DeviceState.RELEASED
    griplink_sim.set_part(0, None)
    port.grip(1, until_done=True)
    assert port.state() is griplink.DeviceState.NO_PART
    griplink_sim.fault_next_motion(0)
    assert port.release_and_wait(1, poll_interval_s=0.01) is griplink.ReleaseOutcome.FAULT


def test_flex_motion_and_recipes(griplink_client: griplink.Client) -> None:
    port = griplink_client.port(2)
    port.home()
    port.flex_release(40.0, 50.0, 100.0, until_done=True)
    assert port.position_mm() == 40.0
    port.set_grip_config(3, "raw", [1, 2, 3, 4, 5, 6, 7, 8])
    assert port.grip_config(3).params == [1, 2, 3, 4, 5, 6, 7, 8]
    with pytest.raises(ValueError):
        port.set_grip_config(3, "raw", [1, 2])


def test_device_error(griplink_client: griplink.Client, griplink_sim: SimServer) -> None:
    griplink_sim.fail_next(int(griplink.Status.STATE_CONFLICT))
    with pytest.raises(gripper_rs.DeviceError) as caught:
        griplink_client.port(0).home()
    assert caught.value.code == 19
    assert caught.value.name == "E_STATE_CONFLICT"
    assert caught.value.description == "Invalid state"
    assert "HOME" in str(caught.value.command)


def test_timeout_and_malformed(griplink_sim: SimServer) -> None:
    with griplink.Client.connect(griplink_sim.address, query_timeout_s=0.2) as client:
        griplink_sim.delay_next_reply(0.5)
        with pytest.raises(TimeoutError):
            client.id()
        # The late reply is consumed, not handed to the next call (which waits behind the
        # timed-out one on the wire, so it gets more time).
        assert client.with_timeout(5.0).serial_number() == "123456"
        griplink_sim.raw_next_reply(b"\x01garbage\n")
        with pytest.raises(gripper_rs.MalformedReplyError):
            client.version()


def test_connection_lost(griplink_client: griplink.Client, griplink_sim: SimServer) -> None:
    griplink_sim.close_next()
    with pytest.raises(gripper_rs.ConnectionLostError):
        griplink_client.id()
    assert griplink_client.is_closed


def test_with_says_bye(griplink_sim: SimServer) -> None:
    with griplink.Client.connect(griplink_sim.address) as client:
        client.id()
    with pytest.raises(gripper_rs.ClosedError):
        client.id()


def test_eight_threads_share_one_client(griplink_client: griplink.Client) -> None:
    ports = [griplink_client.port(0), griplink_client.port(2)]
    failures: list[BaseException] = []
    names: list[str] = []
    lock = threading.Lock()

    def work(i: int) -> None:
        try:
            for _ in range(25):
                name = ports[i % 2].name()
                with lock:
                    names.append(name)
                assert name == ("IEG 55-020" if i % 2 == 0 else "CRG 200-085")
        except BaseException as e:  # noqa: BLE001 - reported below
            with lock:
                failures.append(e)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert failures == []
    assert len(names) == 200


def test_watch_streams(griplink_client: griplink.Client) -> None:
    port = griplink_client.port(0)
    port.home()
    with port.watch_state(0.01) as states:
        assert next(states) is griplink.DeviceState.DISABLED
    port.set_value_f(0, 3.5)
    values = port.watch_value(0, 0.01)
    assert isinstance(next(values), float)
    values.close()


def test_status_enum_matches_the_rust_table() -> None:
    rust = _native.griplink.status_codes()
    assert [(s.value, "E_" + s.name) for s in griplink.Status] == [(c, n) for c, n, _ in rust]
    assert griplink.DeviceState(42).name == "UNKNOWN_42"


def test_sim_options() -> None:
    with SimServer(preset="WPG", time_scale=0.0) as sim, griplink.Client.connect(sim.address) as c:
        assert c.port(0).name() == "WPG 100-090"
    with pytest.raises(ValueError):
        SimServer(devices={0: "no such gripper"})
    with pytest.raises(ValueError):
        SimServer(parts={1: 3.0})  # port 1 of the ET4 preset is empty
