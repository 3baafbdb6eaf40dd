"""The asyncio API: awaitables, cancellation that keeps the pairing, async streams."""

from __future__ import annotations

import asyncio

import pytest
from conftest import run_async

import gripper_rs
import gripper_rs.aio
from gripper_rs import griplink, smartgrasp, wsg

WIDTH_ID = 0x43


def test_wsg_calls_and_context(wsg_sim: wsg.sim.SimServer) -> None:
    async def main() -> None:
        async with await gripper_rs.aio.wsg.Client.connect_tcp(wsg_sim.address) as client:
            await client.home()
            await client.pre_position(50.0, 100.0)
            assert await client.width_mm() == 50.0
            await client.grasp(40.0, 50.0)
            assert await client.grip_state() is wsg.GripState.HOLDING
            # Concurrent calls on one client each get their own reply.
            widths = await asyncio.gather(*(client.width_mm() for _ in range(20)))
            assert widths == [40.0] * 20
            with pytest.raises(gripper_rs.InvalidArgumentError):
                await client.home(9)
        assert wsg_sim.received_ids()[-1] == 0x07  # the disconnect announcement

    run_async(main)


def test_wsg_cancelled_call_leaves_the_client_paired(wsg_sim: wsg.sim.SimServer) -> None:
    async def main() -> None:
        client = await gripper_rs.aio.wsg.Client.connect_tcp(wsg_sim.address)
        await client.home()
        await client.pre_position(70.0, 100.0)
        wsg_sim.delay_next_reply(WIDTH_ID, 0.3)
        with pytest.raises(asyncio.TimeoutError):
            await asyncio.wait_for(client.width_mm(), 0.05)
        task = asyncio.ensure_future(client.grip_state())
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
        # The usable client answers each later call with its own reply.
        assert await client.grip_state() is wsg.GripState.IDLE
        assert await client.system_state() & wsg.SystemState.REFERENCED
        assert await client.width_mm() == 70.0
        await client.close()

    run_async(main)


def test_wsg_async_stream(wsg_client: wsg.Client) -> None:
    wsg_client.home()

    async def main() -> list[float]:
        values: list[float] = []
        async for width in await wsg_client.aio.subscribe_width_mm(0.01):
            values.append(width)
            if len(values) == 3:
                break
        return values

    assert run_async(main) == [110.0, 110.0, 110.0]


def test_wsg_stream_ends_with_the_connection(wsg_sim: wsg.sim.SimServer) -> None:
    async def main() -> int:
        client = await gripper_rs.aio.wsg.Client.connect_tcp(wsg_sim.address)
        stream = await client.subscribe_grip_state(0.01)
        seen = 0
        async for _ in stream:
            seen += 1
            if seen == 2:
                await client.close()
        return seen

    assert run_async(main) >= 2


def test_griplink_aio(griplink_sim: griplink.sim.SimServer) -> None:
    async def main() -> None:
        async with await gripper_rs.aio.griplink.Client.connect(griplink_sim.address) as client:
            assert await client.id() == "GRIPLINK-ET4"
            port = client.port(0)
            await port.home()
            await port.set_grip_config_f(1, "part", [5.0, 18.0, 50.0, 0, 0, 0, 0, 0])
            assert await port.grip_and_wait(1) is griplink.GripOutcome.HOLDING
            griplink_sim.delay_next_reply(0.3)
            with pytest.raises(asyncio.TimeoutError):
                await asyncio.wait_for(port.position_mm(), 0.05)
            assert await port.with_timeout(5.0).state() is griplink.DeviceState.HOLDING
            async for state in port.watch_state(0.01):
                assert state is griplink.DeviceState.HOLDING
                break

    run_async(main)


def test_smartgrasp_aio(kit_sim: smartgrasp.sim.SimServer) -> None:
    async def main() -> None:
        kit = await gripper_rs.aio.smartgrasp.Client.connect(kit_sim.address)
        # The negotiated version is known at once, on either view of the connection.
        assert kit.protocol_version() == kit.blocking.protocol_version() == 4
        assert kit.counter_gaps() == 0
        async with kit:
            kit_sim.delay_next_reply(0.3)
            with pytest.raises(asyncio.TimeoutError):
                await asyncio.wait_for(kit.get_state(), 0.05)
            result = await kit.get_grasp(
                smartgrasp.GraspMode.ACTIVE_GRASP,
                1,
                smartgrasp.Tool.EXTERIOR,
                smartgrasp.PoseFormat.QUATERNION,
            )
            assert result.outcome is smartgrasp.GetGraspOutcome.GRASP
            assert await kit.get_state() is smartgrasp.ServerState.OPERATIONAL

    run_async(main)
