"""The WSG client (blocking) against the in-process simulator over real TCP/UDP sockets."""

from __future__ import annotations

import signal
import threading
import time

import pytest

import gripper_rs
from gripper_rs import _native, wsg
from gripper_rs.wsg.sim import SimServer

GRASP_ID = 0x25
WIDTH_ID = 0x43


def test_motion_and_queries(wsg_client: wsg.Client, wsg_sim: SimServer) -> None:
    wsg_client.home(wsg.HomingDirection.POSITIVE)
    assert wsg_client.width_mm() == 110.0
    assert wsg.SystemState.REFERENCED in wsg_client.system_state()
    wsg_client.pre_position(60.0, 100.0)
    assert wsg_client.width_mm() == 60.0
    wsg_client.pre_position_relative(-10.0, 100.0)
    assert wsg_client.width_mm() == 50.0
    wsg_client.grasp(40.0, 50.0)
    state = wsg_client.grip_state()
    assert state is wsg.GripState.HOLDING
    assert wsg_sim.snapshot().grip_state is wsg.GripState.HOLDING
    wsg_client.release(60.0, 100.0)
    assert wsg_client.grip_state() is wsg.GripState.IDLE
    assert wsg_client.width_mm() == 60.0
    assert isinstance(wsg_client.speed_mm_per_s(), float)
    assert isinstance(wsg_client.force_n(), float)
    assert wsg_client.temperature_c() == 23.4
    stats = wsg_client.grasping_statistics(reset=True)
    assert stats.total >= 1
    assert wsg_client.grasping_statistics().total == 0
    wsg_client.stop()


def test_settings_and_identity(wsg_client: wsg.Client) -> None:
    wsg_client.set_acceleration(2000.0)
    assert wsg_client.acceleration_mm_per_s2() == 2000.0
    wsg_client.set_grasping_force(30.0)
    assert wsg_client.grasping_force_n() == 30.0
    assert wsg_client.soft_limits() is None
    wsg_client.set_soft_limits(5.0, 100.0)
    assert wsg_client.soft_limits() == wsg.SoftLimits(minus_mm=5.0, plus_mm=100.0)
    wsg_client.clear_soft_limits()
    assert wsg_client.soft_limits() is None
    wsg_client.set_device_tag("cell-7")
    assert wsg_client.device_tag() == "cell-7"
    info = wsg_client.system_info()
    assert info.device_type is wsg.DeviceType.WSG50
    assert info.serial_number == 4711
    assert wsg_client.system_limits().stroke_mm == 110.0
    assert wsg_client.finger_info(1).finger_type is wsg.FingerType.GENERIC
    assert isinstance(wsg_client.finger_flags(2), wsg.FingerFlags)
    assert wsg_client.loop_back(b"\x01\x02hello") == b"\x01\x02hello"


def test_fast_stop_must_be_acknowledged(wsg_client: wsg.Client) -> None:
    wsg_client.home()
    wsg_client.fast_stop()
    assert wsg.SystemState.FAST_STOP in wsg_client.system_state()
    with pytest.raises(gripper_rs.DeviceError):
        wsg_client.pre_position(50.0, 100.0)
    wsg_client.acknowledge_fast_stop()
    wsg_client.pre_position(50.0, 100.0)
    assert wsg_client.width_mm() == 50.0


def test_device_error_carries_code_name_and_description(
    wsg_client: wsg.Client, wsg_sim: SimServer
) -> None:
    wsg_client.home()
    wsg_sim.force_status(GRASP_ID, int(wsg.Status.AXIS_BLOCKED))
    with pytest.raises(gripper_rs.DeviceError) as caught:
        wsg_client.grasp(40.0, 50.0)
    e = caught.value
    assert isinstance(e, gripper_rs.GripperError)
    assert e.code == 29
    assert wsg.Status(e.code) is wsg.Status.AXIS_BLOCKED
    assert e.name == "E_AXIS_BLOCKED"
    assert e.description == "axis blocked"
    assert e.command == GRASP_ID
    # The client is still usable.
    assert wsg_client.width_mm() == 110.0


def test_invalid_arguments_are_value_errors(wsg_client: wsg.Client) -> None:
    with pytest.raises(gripper_rs.InvalidArgumentError) as caught:
        wsg_client.home(7)
    assert isinstance(caught.value, ValueError)
    with pytest.raises(ValueError):
        wsg_client.finger_info(3)
    with pytest.raises(ValueError):
        wsg_client.subscribe_width_mm(0.001)
    with pytest.raises(ValueError):
        wsg_client.subscribe_width_mm(-1.0)
    with pytest.raises(ValueError):
        wsg_client.set_device_tag("x" * 300)
    with pytest.raises(ValueError):
        wsg.sim.SimServer(model="WSG99")


def test_timeout_is_a_builtin_timeout_and_leaves_the_client_paired(wsg_sim: SimServer) -> None:
    # The timed-out request keeps its command id for the grace period (its late reply must not
    # be taken for the next 0x43's); a short grace keeps the test short.
    with wsg.Client.connect_tcp(
        wsg_sim.address, query_timeout_s=0.2, late_reply_grace_s=0.05
    ) as client:
        client.home()
        client.pre_position(70.0, 100.0)
        wsg_sim.drop_next_reply(WIDTH_ID)
        with pytest.raises(TimeoutError) as caught:
            client.width_mm()
        assert isinstance(caught.value, gripper_rs.TimeoutError)
        assert caught.value.timeout_s == pytest.approx(0.2)
        # The next call gets its own reply, not a stale one.
        assert client.grip_state() is wsg.GripState.IDLE
        assert client.with_timeouts(5.0, 30.0).width_mm() == 70.0


def test_corrupted_reply_is_skipped_as_noise(wsg_sim: SimServer) -> None:
    with wsg.Client.connect_tcp(
        wsg_sim.address, query_timeout_s=0.2, late_reply_grace_s=0.05
    ) as client:
        client.home()
        wsg_sim.corrupt_next_reply(WIDTH_ID)
        # A frame with a wrong checksum is noise (manual 2.2): the call times out, and the
        # connection stays usable.
        with pytest.raises(gripper_rs.TimeoutError):
            client.width_mm()
        assert client.with_timeouts(5.0, 30.0).width_mm() == 110.0


def test_connection_lost_and_closed(wsg_sim: SimServer) -> None:
    client = wsg.Client.connect_tcp(wsg_sim.address)
    # A call first: the simulator serves the connection once it has accepted it, which may be
    # after `connect_tcp` returned; `unplug` drops the connections it serves.
    client.width_mm()
    wsg_sim.unplug()
    with pytest.raises(gripper_rs.ConnectionLostError) as caught:
        for _ in range(100):  # until the task has seen the connection end
            client.width_mm()
    assert isinstance(caught.value, ConnectionError)
    other = wsg.Client.connect_tcp(wsg_sim.address)
    other.close()
    with pytest.raises(gripper_rs.ClosedError):
        other.width_mm()
    other.close()  # closing twice does nothing (issue 32: `finally: c.close()` is safe)
    client.close()  # so does closing a client whose connection is lost
    with pytest.raises(gripper_rs.TransportError) as refused:
        wsg.Client.connect_tcp(wsg_sim.address.replace(str(wsg_sim.port), "1"))
    assert isinstance(refused.value, OSError)


def test_with_announces_the_disconnect(wsg_sim: SimServer) -> None:
    with wsg.Client.connect_tcp(wsg_sim.address) as client:
        client.home()
    # 0x07: the disconnect announcement, so the gripper does not FAST STOP.
    assert wsg_sim.received_ids()[-1] == 0x07
    with wsg.Client.connect_tcp(wsg_sim.address) as client:
        assert wsg.SystemState.FAST_STOP not in client.system_state()


def test_udp(wsg_sim: SimServer) -> None:
    with SimServer(udp=True) as sim, wsg.Client.connect_udp(sim.address) as client:
        client.home()
        client.pre_position(33.0, 100.0)
        assert client.width_mm() == 33.0


def test_eight_threads_share_one_client(wsg_client: wsg.Client) -> None:
    wsg_client.home()
    wsg_client.pre_position(55.0, 100.0)
    failures: list[BaseException] = []
    results: list[float] = []
    lock = threading.Lock()

    def work() -> None:
        try:
            for _ in range(50):
                w = wsg_client.width_mm()
                s = wsg_client.grip_state()
                with lock:
                    results.append(w)
                assert s is wsg.GripState.IDLE
        except BaseException as e:  # noqa: BLE001 - reported below
            with lock:
                failures.append(e)

    threads = [threading.Thread(target=work) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert failures == []
    assert results == [55.0] * 400


def test_streams(wsg_client: wsg.Client, wsg_sim: SimServer) -> None:
    wsg_client.home()
    with wsg_client.subscribe_width_mm(0.01) as widths:
        first = next(widths)
        assert first == 110.0
        assert next(widths) == 110.0
        assert wsg_sim.snapshot().streams == 1
    states = wsg_client.subscribe_grip_state(0.01, on_change=True)
    assert next(states) is wsg.GripState.IDLE
    states.close()
    assert list(states) == []
    assert isinstance(next(wsg_client.subscribe_system_state(0.01)), wsg.SystemState)
    assert isinstance(next(wsg_client.subscribe_force_n(0.01)), float)
    assert isinstance(next(wsg_client.subscribe_speed_mm_per_s(0.01)), float)


def test_stream_ends_when_the_client_closes(wsg_sim: SimServer) -> None:
    client = wsg.Client.connect_tcp(wsg_sim.address)
    widths = client.subscribe_width_mm(0.01)
    next(widths)
    client.close()
    assert all(isinstance(w, float) for w in widths)  # ends instead of blocking forever


def test_keyboard_interrupt_ends_a_blocking_wait(wsg_client: wsg.Client, wsg_sim: SimServer) -> None:
    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signals are delivered to the main thread")
    wsg_sim.delay_next_reply(WIDTH_ID, 5.0)
    # Python leaves SIGINT ignored when it starts with it ignored, as a background job of a
    # non-interactive shell does (`cmd &` in a script): then the signal below would do nothing
    # and the call would run into its timeout (seen when CI was started that way). The test is
    # about the wait honouring Python's handler, so it installs the usual one for its duration.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(0.2, signal.raise_signal, (signal.SIGINT,))
    try:
        timer.start()
        start = time.monotonic()
        with pytest.raises(KeyboardInterrupt):
            wsg_client.width_mm()
        interrupted_after = time.monotonic() - start - 0.2
        timer.join()
    finally:
        signal.signal(signal.SIGINT, previous)
    # The wait wakes every 50 ms to run signal handlers; 1 s is a bound that a busy CI machine
    # keeps and that a wait ignoring Ctrl-C (5 s) cannot.
    assert interrupted_after < 1.0
    # The dropped call did not shift the pairing: the delayed reply is not taken for this one.
    assert wsg_client.grip_state() is wsg.GripState.IDLE


def test_status_enum_matches_the_rust_table() -> None:
    rust = _native.wsg.status_codes()
    assert [(s.value, "E_" + s.name) for s in wsg.Status] == [(c, n) for c, n, _ in rust]
    assert wsg.Status(99).name == "UNKNOWN_99"
    assert not wsg.Status(99).known and wsg.Status(0).known
    assert wsg.GripState(200) == 200
    assert wsg.SystemState(1 << 30) == 1 << 30


def test_sim_options(wsg_sim: SimServer) -> None:
    with SimServer(model=wsg.sim.Model.WSG32, time_scale=0.0, temperature_c=30.0) as sim:
        with wsg.Client.connect_tcp(sim.address) as client:
            assert client.system_info().device_type is wsg.DeviceType.WSG32
            assert client.temperature_c() == 30.0
    assert repr(wsg_sim).startswith("<gripper_rs.wsg.sim.SimServer at 127.0.0.1:")
    wsg_sim.shutdown()
    with pytest.raises(gripper_rs.ClosedError):
        wsg_sim.snapshot()
