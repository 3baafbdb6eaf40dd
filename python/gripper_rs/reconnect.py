"""Reconnect policies and connection events (Rust: ``gripper::reconnect``).

``ReconnectPolicy`` is the ``reconnect=`` option of ``wsg.Client.connect_tcp``,
``griplink.Client.connect`` and ``smartgrasp.Client.connect``: after a lost connection the client
connects again, waiting ``initial_delay_s``, growing by ``factor`` up to ``max_delay_s``, for at
most ``max_attempts`` attempts (None: as long as the client is in use). Calls in flight when the
connection broke fail with ``ConnectionLostError`` and are not sent again; later calls wait for
the new connection within their own timeouts. When the policy gives up, the client is closed
(``is_closed``) and every call fails. Without a policy, a lost connection closes the client.

``client.connection_events()`` is a ``Stream[ConnectionEvent]`` of what happens to the
connection from then on; it ends when the client has closed or given up.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

__all__ = ["ConnectionEvent", "EventKind", "ReconnectPolicy"]


@dataclass(frozen=True)
class ReconnectPolicy:
    """When and how often a client connects again after a lost connection (the Rust default:
    100 ms, doubling up to 5 s, forever)."""

    initial_delay_s: float = 0.1
    """The wait before the first attempt."""
    max_delay_s: float = 5.0
    """The longest wait between two attempts."""
    factor: float = 2.0
    """Growth of the wait per attempt (below 1: a constant wait)."""
    max_attempts: int | None = None
    """Attempts before giving up; None: try as long as the client is in use."""


class EventKind(enum.Enum):
    """What happened to the connection."""

    LOST = "lost"
    """The connection broke (``reason``); calls in flight failed and are not sent again."""
    RECONNECTING = "reconnecting"
    """Attempt ``attempt`` follows after ``delay_s`` seconds."""
    CONNECTED = "connected"
    """A new connection is up; the client restores what the program set up."""
    RESTORED = "restored"
    """The connection is back after ``attempt`` attempts; calls go through again."""
    GAVE_UP = "gave_up"
    """The client stopped trying after ``attempt`` attempts: it is closed."""
    MISSED = "missed"
    """Not a connection event: the reader was too slow and ``count`` older events were dropped."""
    OTHER = "other"
    """An event of a newer version of the library (its text in ``reason``)."""


@dataclass(frozen=True)
class ConnectionEvent:
    """One connection event; the fields that do not apply to its ``kind`` are None."""

    kind: EventKind
    reason: str | None = None
    attempt: int | None = None
    delay_s: float | None = None
    count: int | None = None
