"""Fixtures: each protocol's in-process simulator on a free loopback port, and a client on it."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from gripper import wsg


@pytest.fixture
def wsg_sim() -> Iterator[wsg.sim.SimServer]:
    with wsg.sim.SimServer(part_width_mm=40.0) as server:
        yield server


@pytest.fixture
def wsg_client(wsg_sim: wsg.sim.SimServer) -> Iterator[wsg.Client]:
    with wsg.Client.connect_tcp(wsg_sim.address) as client:
        yield client
