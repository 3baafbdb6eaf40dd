"""The one exception hierarchy of every protocol (Rust: each module's ``Error``).

``GripperError`` is the base. The device said no: ``DeviceError`` (with the device's status
``code``, its manual ``name`` and ``description``). No answer in time: ``TimeoutError`` (also the
builtin ``TimeoutError``). The connection: ``ConnectionLostError`` (also ``ConnectionError``),
``ClosedError`` (closed by this side), ``TransportError`` (also ``OSError``: connecting or
configuring the transport failed). The bytes: ``MalformedReplyError``. This side refused before
sending: ``InvalidArgumentError`` (also ``ValueError``).
"""

from __future__ import annotations

import builtins
from typing import Any

__all__ = [
    "GripperError",
    "DeviceError",
    "TimeoutError",
    "ConnectionLostError",
    "ClosedError",
    "TransportError",
    "MalformedReplyError",
    "InvalidArgumentError",
    "ProtocolError",
]


class GripperError(Exception):
    """Base class of every error the package raises."""

    def __init__(self, message: str, **attrs: Any) -> None:
        super().__init__(message)
        self.message = message
        for key, value in attrs.items():
            setattr(self, key, value)


class DeviceError(GripperError):
    """The device refused the command.

    ``code`` is the status code on the wire, ``name`` the manual's symbol (``E_CMD_FAILED``; None
    for a code the manual does not list), ``description`` the manual's text, ``command`` what was
    refused (WSG: the command id; GRIPLINK: the command line; SmartGrasp: the message type).
    """

    code: int
    name: str | None
    description: str | None
    command: object

    def __init__(
        self,
        message: str,
        *,
        code: int,
        name: str | None = None,
        description: str | None = None,
        command: object = None,
    ) -> None:
        super().__init__(message, code=code, name=name, description=description, command=command)


class TimeoutError(GripperError, builtins.TimeoutError):
    """No reply within the call's timeout (``timeout_s`` seconds); the client stays usable."""

    timeout_s: float

    def __init__(self, message: str, *, timeout_s: float) -> None:
        super().__init__(message, timeout_s=timeout_s)


class ConnectionLostError(GripperError, ConnectionError):
    """The connection broke, or the client gave up on it; later calls get this too."""


class ClosedError(GripperError):
    """The client was closed by this side (``close()`` or ``with``)."""


class TransportError(GripperError, OSError):
    """Opening or configuring the transport failed (refused, unreachable, no such port)."""


class MalformedReplyError(GripperError):
    """A reply arrived that does not have the documented layout, or does not answer the call."""


class InvalidArgumentError(GripperError, ValueError):
    """An argument was refused before anything was sent."""


class ProtocolError(GripperError):
    """The peer broke the protocol in another way (SmartGrasp: too old, not operational, a
    response lost)."""
