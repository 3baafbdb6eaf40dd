"""The simulated WSG gripper (Rust: ``gripper::wsg::sim``), for tests and examples.

A pytest fixture is three lines::

    @pytest.fixture
    def sim() -> Iterator[SimServer]:
        with SimServer(part_width_mm=40.0) as server:
            yield server
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import TYPE_CHECKING

from gripper_rs import _native

if TYPE_CHECKING:
    from gripper_rs.wsg import GripState, SystemState

__all__ = ["Model", "SimServer", "SimSnapshot"]

SimServer = _native.wsg.SimServer


class Model(enum.StrEnum):
    """The simulated model (its limits and device type)."""

    WSG50 = "WSG50"
    WSG32 = "WSG32"
    WSG25 = "WSG25"
    WSG70 = "WSG70"


@dataclass(frozen=True)
class SimSnapshot:
    """The simulated gripper after its last step."""

    grip_state: GripState
    system_state: SystemState
    width_mm: float
    sessions: int
    streams: int
