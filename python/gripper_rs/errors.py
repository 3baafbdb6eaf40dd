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
import enum
from typing import Any

# `TimeoutError` is left out of `__all__` on purpose: `from gripper_rs.errors import *` would
# shadow the builtin of that name (ours is a subclass of it; `except TimeoutError` catches both).
__all__ = [
    "GripperError",
    "DeviceError",
    "ConnectionLostError",
    "ClosedError",
    "TransportError",
    "MalformedReplyError",
    "InvalidArgumentError",
    "ProtocolError",
]


def _rebuild(cls: type[GripperError], message: str, attrs: dict[str, Any]) -> GripperError:
    """Unpickles an error: the class, its message and its attributes as they were."""
    error = cls.__new__(cls)
    Exception.__init__(error, message)
    error.message = message
    error.__dict__.update(attrs)
    return error


class GripperError(Exception):
    """Base class of every error the package raises.

    Every error pickles (``multiprocessing``, ``concurrent.futures.ProcessPoolExecutor``) and
    copies (``copy.copy``, ``copy.deepcopy``) to an equal one: two errors are equal when they are
    of the same class with the same message and attributes.
    """

    message: str

    def __init__(self, message: str, **attrs: Any) -> None:
        super().__init__(message)
        self.message = message
        for key, value in attrs.items():
            setattr(self, key, value)

    def _attrs(self) -> dict[str, Any]:
        return {k: v for k, v in self.__dict__.items() if k != "message"}

    def __reduce__(self) -> tuple[Any, ...]:
        # The default (`cls(*args)`) cannot rebuild a class whose attributes are keyword-only
        # arguments (DeviceError, TimeoutError): unpickling failed (issue 32).
        return (_rebuild, (type(self), self.message, self._attrs()))

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        assert isinstance(other, GripperError)
        return self.message == other.message and self._attrs() == other._attrs()

    def __hash__(self) -> int:
        return hash((type(self), self.message))


class DeviceError(GripperError):
    """The device refused the command.

    ``code`` is the status code on the wire; ``status`` the same code as the protocol's
    ``IntEnum`` (``gripper_rs.wsg.Status`` for WSG binary and text, ``gripper_rs.griplink.Status``,
    ``gripper_rs.smartgrasp.ResponseCode``; None for a GCL ``ERR`` line without a code, whose
    ``code`` is -1); ``name`` the manual's symbol (WSG ``E_CMD_FAILED``, GRIPLINK ``E_...``,
    SmartGrasp ``ERROR``) and ``description`` the manual's text, both None for a code the manual
    does not list; ``command`` what was refused (WSG: the command id; GCL and GRIPLINK: the
    command line; SmartGrasp: the message type).
    """

    code: int
    status: enum.IntEnum | None
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
        status: enum.IntEnum | None = None,
    ) -> None:
        super().__init__(
            message, code=code, name=name, description=description, command=command, status=status
        )


class TimeoutError(GripperError, builtins.TimeoutError):
    """No reply within the call's timeout (``timeout_s`` seconds); the client stays usable.

    Also connecting that did not finish within the connect timeout: then ``timeout_s`` is None
    (the connect timeout is the caller's own ``connect_timeout_s``).
    """

    timeout_s: float | None

    def __init__(self, message: str, *, timeout_s: float | None) -> None:
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
    """The peer broke the exchange in another way: it is too old for this client (SmartGrasp
    before V3), it cannot serve calls (SmartGrasp not OPERATIONAL), or a reply was lost on the
    wire (WSG: the final reply after E_CMD_PENDING; SmartGrasp: a response the counter skipped)."""
