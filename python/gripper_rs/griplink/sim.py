"""The simulated GRIPLINK controller (Rust: ``gripper::griplink::sim``)."""

from __future__ import annotations

from gripper_rs import _native

__all__ = ["SimServer"]

SimServer = _native.griplink.SimServer
