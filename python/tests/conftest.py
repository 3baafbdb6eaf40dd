"""Fixtures: each protocol's in-process simulator on a free loopback port, and a client on it."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from gripper_rs import griplink, smartgrasp, wsg


@pytest.fixture
def wsg_sim() -> Iterator[wsg.sim.SimServer]:
    with wsg.sim.SimServer(part_width_mm=40.0) as server:
        yield server


@pytest.fixture
def wsg_client(wsg_sim: wsg.sim.SimServer) -> Iterator[wsg.Client]:
    with wsg.Client.connect_tcp(wsg_sim.address) as client:
        yield client


@pytest.fixture
def griplink_sim() -> Iterator[griplink.sim.SimServer]:
    # time scale 0: motion takes no time.
    with griplink.sim.SimServer(time_scale=0.0, parts={0: 12.0}) as server:
        yield server


@pytest.fixture
def griplink_client(griplink_sim: griplink.sim.SimServer) -> Iterator[griplink.Client]:
    with griplink.Client.connect(griplink_sim.address) as client:
        yield client


@pytest.fixture
def kit_sim() -> Iterator[smartgrasp.sim.SimServer]:
    with smartgrasp.sim.SimServer() as server:
        yield server


@pytest.fixture
def kit(kit_sim: smartgrasp.sim.SimServer) -> Iterator[smartgrasp.Client]:
    with smartgrasp.Client.connect(kit_sim.address) as client:
        yield client
