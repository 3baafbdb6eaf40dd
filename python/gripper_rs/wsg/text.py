"""The WSG's text interface, GCL (Rust: ``gripper::wsg::text``), for a gripper set to "Use text
based interface".

``Client.connect("host:port")``; the Rust client's methods under the same names: ``home``,
``move_to(width_mm, speed_mm_per_s=None)``, ``grip(force_n=None)``,
``grip_part(force_n, part_width_mm, speed_mm_per_s=None)``,
``release(pull_back_mm=None, speed_mm_per_s=None)`` (relative: GCL's RELEASE opens BY the
pull-back, unlike the binary protocol's release), ``stop``, ``fast_stop``, ``ack_fast_stop``
(``FSACK()``), ``set_verbose``, the PWT/CLT settings, the queries ``position_mm``,
``speed_mm_per_s``, ``force_n``, ``grip_state``, ``temperature_c``, ``autosend`` (a stream of
``Push``) and ``close`` (``BYE()``). ``client.aio`` is the asyncio view of the same connection.
``gripper_rs.wsg.sim.SimServer(text=True)`` serves GCL from the simulated gripper.
"""

from __future__ import annotations

from dataclasses import dataclass

from gripper_rs import _native

__all__ = ["AioClient", "Client", "Push"]

Client = _native.wsg_text.Client
AioClient = _native.wsg_text.AioClient


@dataclass(frozen=True)
class Push:
    """One value pushed by ``AUTOSEND`` (``@NAME=value``)."""

    quantity: str
    """``POS`` (mm), ``SPEED`` (mm/s), ``FORCE`` (N), ``GRIPSTATE`` or ``TEMP`` (°C)."""
    value: float
