"""The asyncio API: the same clients, methods and names as the blocking API, as awaitables.

``client = await gripper_rs.aio.wsg.Client.connect_tcp(addr)``; ``await client.width_mm()``.
Cancelling an awaitable (``asyncio.wait_for``, ``task.cancel()``) drops the call: the client stays
usable and its replies stay paired with their requests. Streams are async iterators. A blocking
client's ``.aio`` (and an asyncio client's ``.blocking``) is the other view of one connection.
"""

from __future__ import annotations

from gripper_rs.aio import griplink, smartgrasp, wsg

__all__ = ["griplink", "smartgrasp", "wsg"]
