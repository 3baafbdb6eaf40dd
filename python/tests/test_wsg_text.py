"""The WSG text-interface (GCL) client against the simulator's text mode over real TCP."""

from __future__ import annotations

import asyncio
from collections.abc import Iterator

import pytest
from conftest import run_async

import gripper_rs
from gripper_rs import wsg
from gripper_rs.wsg.sim import SimServer


@pytest.fixture
def text_sim() -> Iterator[SimServer]:
    with SimServer(part_width_mm=40.0, text=True) as server:
        yield server


def test_motion_queries_and_errors(text_sim: SimServer) -> None:
    with wsg.text.Client.connect(text_sim.address) as g:
        g.ack_fast_stop()
        with pytest.raises(gripper_rs.DeviceError) as not_homed:
            g.move_to(50.0)
        assert not_homed.value.code == 3  # E_NOT_INITIALIZED
        g.home()
        assert g.position_mm() == 110.0
        g.move_to(60.0, 100.0)
        g.grip_part(30.0, 40.0, 50.0)
        assert g.grip_state() is wsg.GripState.HOLDING
        assert g.force_n() == 30.0
        # RELEASE is relative: it opens BY the pull-back.
        g.release(10.0)
        assert g.position_mm() == 50.0
        with pytest.raises(gripper_rs.DeviceError) as no_part:
            g.grip_part(20.0, 10.0)
        assert no_part.value.code == 18  # E_CMD_FAILED
        g.release()
        assert g.set_verbose(True) is True
        assert g.set_part_width_tolerance_mm(4.5) == 4.5
        assert g.clamping_travel_mm() == 4.0  # twice the simulator's 2 mm
        assert g.temperature_c() == 23.4
        assert g.speed_mm_per_s() == 0.0
        g.fast_stop()
        with pytest.raises(gripper_rs.DeviceError):
            g.home(wsg.HomingDirection.NEGATIVE)
        g.ack_fast_stop()
        g.stop()
    # `with` said BYE(): no FAST STOP.
    assert wsg.SystemState.FAST_STOP not in text_sim.snapshot().system_state


def test_autosend_stream(text_sim: SimServer) -> None:
    with wsg.text.Client.connect(text_sim.address) as g:
        g.home()
        with g.autosend("POS", 10) as pushes:
            first = next(pushes)
            assert first == wsg.text.Push("POS", 110.0)
        g.stop_autosend("POS")
        with pytest.raises(gripper_rs.InvalidArgumentError):
            g.autosend("NOPE", 10)


def test_asyncio_view(text_sim: SimServer) -> None:
    async def main() -> None:
        async with await wsg.text.AioClient.connect(text_sim.address) as g:
            await g.home()
            widths = await asyncio.gather(*(g.position_mm() for _ in range(5)))
            assert widths == [110.0] * 5

    run_async(main)
