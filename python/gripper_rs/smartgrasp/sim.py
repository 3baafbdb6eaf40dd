"""The simulated Grasping-Kit (Rust: ``gripper::smartgrasp::sim``)."""

from __future__ import annotations

from gripper_rs import _native

__all__ = ["SimServer"]

SimServer = _native.smartgrasp.SimServer
