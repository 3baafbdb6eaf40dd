"""The whole cell, with asyncio: a Grasping-Kit says where the part is, a WSG gripper picks it,
a GRIPLINK gripper holds the fixture, and the WSG width is streamed while it moves.

Runs against three in-process simulators by default; ``--wsg``, ``--griplink`` and ``--kit``
give real devices' host:port.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib

import gripper_rs.aio
from gripper_rs import griplink, smartgrasp, wsg
from gripper_rs.smartgrasp import GraspMode, PoseFormat, Tool


async def watch_width(client: gripper_rs.aio.wsg.Client, widths: list[float]) -> None:
    async for width in await client.subscribe_width_mm(0.02, on_change=True):
        widths.append(width)


async def cell(wsg_addr: str, griplink_addr: str, kit_addr: str) -> None:
    kit = await gripper_rs.aio.smartgrasp.Client.connect(kit_addr)
    hand = await gripper_rs.aio.wsg.Client.connect_tcp(wsg_addr)
    fixture_controller = await gripper_rs.aio.griplink.Client.connect(griplink_addr)
    async with kit, hand, fixture_controller:
        fixture = fixture_controller.port(0)
        await asyncio.gather(hand.home(), fixture.home())
        await fixture.set_grip_config_f(1, "fixture", [5.0, 18.0, 50.0, 0, 0, 0, 0, 0])
        clamp = await fixture.grip_and_wait(1, poll_interval_s=0.01)
        print("fixture:", clamp.name)

        result = await kit.get_grasp(GraspMode.ACTIVE_GRASP, 1, Tool.EXTERIOR, PoseFormat.QUATERNION)
        if result.grasp is None:
            raise SystemExit(f"no grasp: {result.outcome.name}")
        stroke_mm = result.grasp.stroke_mm
        print(f"grasp at {result.grasp.pose.position_m} m, stroke {stroke_mm:.1f} mm")

        widths: list[float] = []
        watcher = asyncio.create_task(watch_width(hand, widths))
        await hand.pre_position(stroke_mm + 10.0, 100.0)
        await hand.grasp(stroke_mm, 50.0)
        state = await hand.grip_state()
        print(f"hand: {state.name} at {await hand.width_mm():.1f} mm")
        await hand.release(stroke_mm + 10.0, 100.0)
        watcher.cancel()  # ends the stream; the device stops sending updates
        with contextlib.suppress(asyncio.CancelledError):
            await watcher
        print(f"{len(widths)} width updates while moving")
        await kit.grasp_feedback(state is wsg.GripState.HOLDING)
        print("fixture release:", (await fixture.release_and_wait(1)).name)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--wsg")
    parser.add_argument("--griplink")
    parser.add_argument("--kit")
    args = parser.parse_args()
    with contextlib.ExitStack() as stack:
        wsg_addr: str | None = args.wsg
        griplink_addr: str | None = args.griplink
        kit_addr: str | None = args.kit
        if wsg_addr is None:
            # The demo bin's part is 86 mm wide.
            wsg_addr = stack.enter_context(
                wsg.sim.SimServer(part_width_mm=86.0, time_scale=0.01)
            ).address
        if griplink_addr is None:
            griplink_addr = stack.enter_context(
                griplink.sim.SimServer(parts={0: 12.0}, time_scale=0.05)
            ).address
        if kit_addr is None:
            kit_addr = stack.enter_context(smartgrasp.sim.SimServer()).address
        asyncio.run(cell(wsg_addr, griplink_addr, kit_addr))


if __name__ == "__main__":
    main()
