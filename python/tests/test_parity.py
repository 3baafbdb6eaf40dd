"""What the Rust crate has and Python reaches too (issue 32): raw requests, clamp_on_block,
reconnect policies and connection events, tracing in logging, conversions off the runtime."""

from __future__ import annotations

import asyncio
import logging
import struct
import sys
import threading
from collections.abc import Iterable
from pathlib import Path

import pytest

import gripper_rs
import gripper_rs.aio
from conftest import Relay, run_async, wait_until
from gripper_rs import ConnectionEvent, ReconnectPolicy, griplink, smartgrasp, wsg
from gripper_rs.reconnect import EventKind

PRE_POSITION_ID = 0x21
GRASP_ID = 0x25
FAST = ReconnectPolicy(initial_delay_s=0.01, max_delay_s=0.01)


def test_wsg_raw_request(wsg_client: wsg.Client) -> None:
    reply = wsg_client.request(0x06, b"raw")  # loop-back
    assert reply == wsg.Reply(id=0x06, status=wsg.Status.SUCCESS, data=b"raw")
    # A refusal is a reply like any other, not an exception.
    unknown = wsg_client.request(0x99, timeout_s=2.0)
    assert unknown.id == 0x99
    assert unknown.status is wsg.Status.CMD_UNKNOWN
    assert unknown.data == b""

    async def main() -> wsg.Reply:
        return await wsg_client.aio.request(0x06, b"aio")

    assert run_async(main).data == b"aio"


def test_griplink_raw_command(griplink_client: griplink.Client) -> None:
    answer = griplink_client.command("ID?")
    assert answer == griplink.Answer(key="ID", indices=(), value="GRIPLINK-ET4")
    state = griplink_client.command("DEVSTATE[0]?")
    assert state is not None and state.indices == (0,)
    assert isinstance(state.value, int)
    with pytest.raises(gripper_rs.DeviceError):
        griplink_client.command("NOSUCHCOMMAND?")


def pre_position_flags(sent: bytes) -> list[int]:
    """The flags byte (D0 relative, D1 stop on block) of each 0x21 frame the client sent:
    preamble AA AA AA, id, a 16-bit size, then the payload (manual 1.2)."""
    flags = []
    at = sent.find(b"\xaa\xaa\xaa\x21")
    while at >= 0:
        flags.append(sent[at + 6])
        at = sent.find(b"\xaa\xaa\xaa\x21", at + 1)
    return flags


def test_clamp_on_block(wsg_relay: Relay) -> None:
    with wsg.Client.connect_tcp(wsg_relay.address) as client:
        client.home()
        client.pre_position(60.0, 100.0)
        client.pre_position(50.0, 100.0, clamp_on_block=True)
        client.pre_position_relative(-5.0, 100.0, clamp_on_block=True)
        client.pre_position_relative(5.0, 100.0)
        assert client.width_mm() == 50.0
    assert pre_position_flags(bytes(wsg_relay.sent)) == [0b10, 0b00, 0b01, 0b11]


def until_restored(events: Iterable[ConnectionEvent]) -> list[ConnectionEvent]:
    """The connection events up to and including the first RESTORED."""
    seen: list[ConnectionEvent] = []
    for event in events:
        seen.append(event)
        if event.kind is EventKind.RESTORED:
            break
    return seen


def kinds(events: list[ConnectionEvent]) -> list[EventKind]:
    return [e.kind for e in events]


def test_wsg_reconnects_and_reports_its_events(wsg_relay: Relay) -> None:
    client = wsg.Client.connect_tcp(wsg_relay.address, reconnect=FAST)
    events = client.connection_events()
    client.home()
    wsg_relay.cut()
    seen = until_restored(events)
    assert kinds(seen)[0] is EventKind.LOST
    assert seen[0].reason
    assert EventKind.RECONNECTING in kinds(seen) and EventKind.CONNECTED in kinds(seen)
    assert not client.is_closed
    assert client.width_mm() == 110.0  # the new connection answers
    client.close()
    assert list(events) == []  # the stream ends with the client
    assert client.is_closed


def test_a_policy_that_gives_up_closes_the_client(wsg_relay: Relay) -> None:
    client = wsg.Client.connect_tcp(
        wsg_relay.address, reconnect=ReconnectPolicy(0.01, 0.01, 1.0, max_attempts=2)
    )
    events = client.connection_events()
    stream = client.subscribe_grip_state(0.01, on_change=True)
    next(stream)
    wsg_relay.close()  # cut, and no new connection is accepted
    assert kinds(list(events)) == [
        EventKind.LOST,
        EventKind.RECONNECTING,
        EventKind.RECONNECTING,
        EventKind.GAVE_UP,
    ]
    assert client.is_closed
    with pytest.raises(gripper_rs.ConnectionLostError, match="gave up"):
        next(stream)
    client.close()


def test_griplink_reconnect_events_async(griplink_relay: Relay) -> None:
    async def main() -> list[EventKind]:
        client = await gripper_rs.aio.griplink.Client.connect(
            griplink_relay.address, reconnect=FAST
        )
        events = client.connection_events()
        assert await client.id() == "GRIPLINK-ET4"
        griplink_relay.cut()
        seen = []
        async for event in events:
            seen.append(event.kind)
            if event.kind is EventKind.RESTORED:
                break
        assert await client.id() == "GRIPLINK-ET4"
        await client.close()
        return seen

    seen = run_async(main)
    assert seen[0] is EventKind.LOST and seen[-1] is EventKind.RESTORED


def test_smartgrasp_reconnects_and_reports_its_events(kit_sim: smartgrasp.sim.SimServer) -> None:
    relay = Relay(kit_sim.address)
    try:
        kit = smartgrasp.Client.connect(relay.address, reconnect=FAST)
        events = kit.connection_events()
        assert kit.get_protocol_version() == 4
        relay.cut()
        seen = until_restored(events)
        assert kinds(seen)[0] is EventKind.LOST
        assert not kit.is_closed
        assert kit.get_protocol_version() == 4  # the new connection answers
        kit.close()
        assert kit.is_closed
    finally:
        relay.close()


def test_invalid_policies_are_refused(wsg_sim: wsg.sim.SimServer) -> None:
    with pytest.raises(gripper_rs.InvalidArgumentError):
        wsg.Client.connect_tcp(wsg_sim.address, reconnect=ReconnectPolicy(initial_delay_s=-1.0))
    with pytest.raises(gripper_rs.InvalidArgumentError):
        wsg.Client.connect_tcp(wsg_sim.address, reconnect=ReconnectPolicy(max_attempts=-1))


def test_tracing_reaches_logging(wsg_relay: Relay, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="gripper")
    gripper_rs.reset_logging_cache()
    # Which thread hands each record to `logging` (Linux: the thread's OS name).
    emitters: list[str] = []

    def note(record: logging.LogRecord) -> bool:
        if sys.platform == "linux":
            emitters.append(native_thread_name())
        return True

    logging.getLogger("gripper.reconnect").addFilter(note)
    client = wsg.Client.connect_tcp(wsg_relay.address)
    client.width_mm()
    wsg_relay.cut()
    wait_until(lambda: client.is_closed)
    wait_until(lambda: any(r.name.startswith("gripper.") for r in caplog.records))
    record = next(r for r in caplog.records if r.name.startswith("gripper."))
    assert record.levelno == logging.WARNING
    assert "connection lost" in record.getMessage()
    client.close()
    logging.getLogger("gripper.reconnect").removeFilter(note)
    # Handed over by the delivery thread, never by a tokio worker (which would take the GIL).
    if sys.platform == "linux":
        assert emitters and set(emitters) == {"gripper-rs-deli"}


def native_thread_name() -> str:
    """The OS name of the calling thread (Linux)."""
    tid = threading.get_native_id()
    return Path(f"/proc/self/task/{tid}/comm").read_text().strip()


@pytest.mark.skipif(sys.platform != "linux", reason="thread names from /proc")
def test_async_results_are_made_off_the_runtime_threads(
    wsg_sim: wsg.sim.SimServer, monkeypatch: pytest.MonkeyPatch
) -> None:
    # An exception is built, like every result, by the thread that hands it to the event loop:
    # the package's delivery thread, never a tokio worker (which a busy Python thread holding
    # the GIL would stall, the connections' tasks with it).
    builders: list[str] = []
    original = gripper_rs.DeviceError.__init__

    def recording(self: gripper_rs.DeviceError, *args: object, **kwargs: object) -> None:
        builders.append(native_thread_name())
        original(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(gripper_rs.DeviceError, "__init__", recording)

    async def main() -> None:
        client = await gripper_rs.aio.wsg.Client.connect_tcp(wsg_sim.address)
        await client.home()
        wsg_sim.force_status(GRASP_ID, int(wsg.Status.AXIS_BLOCKED))
        with pytest.raises(gripper_rs.DeviceError):
            await client.grasp(40.0, 50.0)
        await asyncio.gather(*(client.width_mm() for _ in range(10)))
        await client.close()

    run_async(main)
    assert builders == ["gripper-rs-deli"]  # "gripper-rs-deliver", cut to 15 bytes by Linux
