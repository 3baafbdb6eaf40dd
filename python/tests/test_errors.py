"""Errors (issue 32): every error is a GripperError (range-checked integers and sequences
included), every error pickles and copies to an equal one, DeviceError's name and status."""

from __future__ import annotations

import builtins
import copy
import pickle
import socket
import types
from collections.abc import Callable, Iterator

import pytest

import gripper_rs
from gripper_rs import griplink, smartgrasp, wsg

GRASP_ID = 0x25
WIDTH_ID = 0x43


@pytest.mark.parametrize(
    "call",
    [
        lambda c: c.finger_info(256),
        lambda c: c.finger_info(-1),
        lambda c: c.home(2**70),
        lambda c: c.finger_flags(-(2**70)),
    ],
)
def test_wsg_integers_out_of_range(wsg_client: wsg.Client, call: Callable[[wsg.Client], object]) -> None:
    with pytest.raises(gripper_rs.InvalidArgumentError) as caught:
        call(wsg_client)
    assert isinstance(caught.value, ValueError)
    assert "does not fit" in str(caught.value)


def test_griplink_integers_out_of_range(griplink_client: griplink.Client) -> None:
    for n in (-1, 256):
        with pytest.raises(gripper_rs.InvalidArgumentError):
            griplink_client.port(n)
    port = griplink_client.port(0)
    with pytest.raises(gripper_rs.InvalidArgumentError):
        port.value(-1)
    with pytest.raises(gripper_rs.InvalidArgumentError):
        port.set_grip_config(1, "part", [2**40, 0, 0, 0, 0, 0, 0, 0])
    with pytest.raises(gripper_rs.InvalidArgumentError):
        port.set_value_f(-1, 1.0)
    with pytest.raises(gripper_rs.InvalidArgumentError):
        smartgrasp.sim.SimServer(max_version=70000)


def test_smartgrasp_integers_and_sequences(kit: smartgrasp.Client) -> None:
    with pytest.raises(gripper_rs.InvalidArgumentError):
        kit.set_tool(70000)
    with pytest.raises(gripper_rs.InvalidArgumentError):
        kit.robot_pose(smartgrasp.PoseFormat.QUATERNION, [0, 0, 0, 0, 0, 0])  # six, not seven
    # A wrong type stays a TypeError, as everywhere in Python.
    with pytest.raises(TypeError):
        kit.set_tool("tool")  # type: ignore[arg-type]  # the wrong type on purpose


def test_text_integers_out_of_range() -> None:
    with wsg.sim.SimServer(text=True) as sim, wsg.text.Client.connect(sim.address) as client:
        with pytest.raises(gripper_rs.InvalidArgumentError):
            client.autosend("POS", 70000)


def roundtrips(error: BaseException) -> None:
    for twin in (
        pickle.loads(pickle.dumps(error)),
        copy.copy(error),
        copy.deepcopy(error),
    ):
        assert type(twin) is type(error)
        assert twin == error
        assert str(twin) == str(error)
        assert twin.__dict__ == error.__dict__


def test_every_error_pickles_and_copies(wsg_client: wsg.Client, wsg_sim: wsg.sim.SimServer) -> None:
    wsg_client.home()
    wsg_sim.force_status(GRASP_ID, int(wsg.Status.AXIS_BLOCKED))
    with pytest.raises(gripper_rs.DeviceError) as device:
        wsg_client.grasp(40.0, 50.0)
    roundtrips(device.value)

    wsg_sim.drop_next_reply(WIDTH_ID)
    with pytest.raises(gripper_rs.TimeoutError) as timeout:
        wsg_client.with_timeouts(0.05, 1.0).width_mm()
    roundtrips(timeout.value)
    assert pickle.loads(pickle.dumps(timeout.value)).timeout_s == 0.05

    with pytest.raises(gripper_rs.InvalidArgumentError) as invalid:
        wsg_client.finger_info(3)
    roundtrips(invalid.value)

    wsg_client.close()
    with pytest.raises(gripper_rs.ClosedError) as closed:
        wsg_client.width_mm()
    roundtrips(closed.value)
    # Equality is by class, message and attributes.
    assert closed.value != invalid.value
    assert gripper_rs.ClosedError("x") == gripper_rs.ClosedError("x")


def test_the_other_errors_pickle_and_copy(
    griplink_client: griplink.Client,
    griplink_sim: griplink.sim.SimServer,
    wsg_sim: wsg.sim.SimServer,
) -> None:
    """The four error classes the test above does not meet, each raised for real."""
    griplink_sim.raw_next_reply(b"\x01garbage\n")
    with pytest.raises(gripper_rs.MalformedReplyError) as malformed:
        griplink_client.version()
    roundtrips(malformed.value)

    with pytest.raises(gripper_rs.TransportError) as refused:
        wsg.Client.connect_tcp(wsg_sim.address.replace(str(wsg_sim.port), "1"))
    roundtrips(refused.value)
    assert isinstance(pickle.loads(pickle.dumps(refused.value)), OSError)

    with smartgrasp.sim.SimServer(server_state=smartgrasp.ServerState.STOPPED) as stopped:
        with pytest.raises(gripper_rs.ProtocolError) as protocol:
            smartgrasp.Client.connect(stopped.address)
    roundtrips(protocol.value)

    griplink_sim.close_next()
    with pytest.raises(gripper_rs.ConnectionLostError) as connection:
        griplink_client.id()
    roundtrips(connection.value)


def test_device_error_name_and_status(wsg_client: wsg.Client, wsg_sim: wsg.sim.SimServer) -> None:
    wsg_client.home()
    wsg_sim.force_status(GRASP_ID, int(wsg.Status.AXIS_BLOCKED))
    with pytest.raises(gripper_rs.DeviceError) as known:
        wsg_client.grasp(40.0, 50.0)
    assert known.value.status is wsg.Status.AXIS_BLOCKED
    assert known.value.name == "E_AXIS_BLOCKED"
    wsg_sim.force_status(GRASP_ID, 99)
    with pytest.raises(gripper_rs.DeviceError) as unknown:
        wsg_client.grasp(40.0, 50.0)
    # As documented: no name and no description for a code the manual does not list.
    assert unknown.value.code == 99
    assert unknown.value.name is None
    assert unknown.value.description is None
    assert isinstance(unknown.value.status, wsg.Status)
    assert unknown.value.status == 99 and not unknown.value.status.known
    roundtrips(unknown.value)


def test_griplink_device_error_status(
    griplink_client: griplink.Client, griplink_sim: griplink.sim.SimServer
) -> None:
    griplink_sim.fail_next(int(griplink.Status.RANGE_ERROR))
    with pytest.raises(gripper_rs.DeviceError) as caught:
        griplink_client.id()
    assert caught.value.status is griplink.Status.RANGE_ERROR
    assert caught.value.name == "E_RANGE_ERROR"
    griplink_sim.fail_next(999)
    with pytest.raises(gripper_rs.DeviceError) as unknown:
        griplink_client.id()
    assert unknown.value.name is None
    assert unknown.value.status == 999


def test_smartgrasp_device_error_status(kit_sim: smartgrasp.sim.SimServer) -> None:
    with smartgrasp.Client.connect(kit_sim.address) as kit:
        kit_sim.refuse_next(int(smartgrasp.ResponseCode.ERROR))
        with pytest.raises(gripper_rs.DeviceError) as known:
            kit.get_state()
        assert known.value.status is smartgrasp.ResponseCode.ERROR
        assert known.value.name == "ERROR"
        # A code the manual does not define: no name, the status still the protocol's IntEnum.
        kit_sim.refuse_next(200)
        with pytest.raises(gripper_rs.DeviceError) as unknown:
            kit.get_state()
        assert unknown.value.code == 200
        assert unknown.value.name is None
        assert isinstance(unknown.value.status, smartgrasp.ResponseCode)
        assert unknown.value.status == 200
        roundtrips(unknown.value)
        assert kit.get_protocol_version() == 4  # the client goes on


def test_timeout_error_stays_out_of_star_imports() -> None:
    assert "TimeoutError" not in gripper_rs.__all__
    assert "TimeoutError" not in gripper_rs.errors.__all__
    namespace: dict[str, object] = {}
    exec("from gripper_rs import *", namespace)
    exec("from gripper_rs.errors import *", namespace)
    assert "TimeoutError" not in namespace
    assert issubclass(gripper_rs.TimeoutError, TimeoutError)


def test_simulator_options_take_any_mapping() -> None:
    # The stub says Mapping: a read-only mapping is accepted, not only a dict.
    parts = types.MappingProxyType({0: 12.0})
    with griplink.sim.SimServer(time_scale=0.0, parts=parts) as sim, griplink.Client.connect(
        sim.address
    ) as client:
        port = client.port(0)
        port.home()
        port.set_grip_config_f(1, "part", [5.0, 18.0, 50.0, 0, 0, 0, 0, 0])
        assert port.grip_and_wait(1) is griplink.GripOutcome.HOLDING
    with pytest.raises(gripper_rs.InvalidArgumentError):
        griplink.sim.SimServer(parts={300: 12.0})


@pytest.fixture
def unanswered_address() -> Iterator[str]:
    """A loopback address whose connects hang: a listener that never accepts, with a backlog of
    0 already filled, so the kernel drops further SYNs and a connect waits until its timeout."""
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(0)
    host, port = listener.getsockname()
    fillers = []
    try:
        for _ in range(3):
            s = socket.socket()
            s.setblocking(False)
            s.connect_ex((host, port))
            fillers.append(s)
        yield f"{host}:{port}"
    finally:
        for s in fillers:
            s.close()
        listener.close()


@pytest.mark.parametrize(
    "connect",
    [
        lambda a: wsg.Client.connect_tcp(a, connect_timeout_s=0.2),
        lambda a: wsg.text.Client.connect(a, connect_timeout_s=0.2),
        lambda a: griplink.Client.connect(a, connect_timeout_s=0.2),
        lambda a: smartgrasp.Client.connect(a, connect_timeout_s=0.2),
    ],
    ids=["wsg", "text", "griplink", "smartgrasp"],
)
def test_a_connect_timeout_is_a_timeout_error_without_duration(
    unanswered_address: str, connect: Callable[[str], object]
) -> None:
    # gripper::ErrorKind::Timeout (an I/O error of kind TimedOut), once a TransportError: every
    # protocol's connect timeout is the TimeoutError its docs promise, and it has no duration.
    with pytest.raises(gripper_rs.TimeoutError) as caught:
        connect(unanswered_address)
    assert isinstance(caught.value, builtins.TimeoutError)
    assert caught.value.timeout_s is None
    assert pickle.loads(pickle.dumps(caught.value)) == caught.value


def test_a_subscription_conflict_is_an_invalid_argument(wsg_client: wsg.Client) -> None:
    # gripper::ErrorKind::InvalidArgument (refused before sending), once a plain GripperError.
    stream = wsg_client.subscribe_width_mm(0.05)
    try:
        with pytest.raises(gripper_rs.InvalidArgumentError) as caught:
            wsg_client.subscribe_width_mm(0.1)
        assert "already streamed" in str(caught.value)
    finally:
        stream.close()
