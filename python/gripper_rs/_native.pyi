# Types of the compiled half (python/src/*.rs). The classes are re-exported under the Rust API's
# module names: gripper_rs.wsg.Client is wsg.Client here, gripper_rs.aio.wsg.Client is
# wsg.AioClient.
from collections.abc import Awaitable, Mapping, Sequence
from types import TracebackType
from typing import Generic, Self, TypeVar

from gripper_rs.griplink import Answer, DeviceState, GripConfig, GripConfigF, GripOutcome, ReleaseOutcome
from gripper_rs.smartgrasp import GraspResult, ObjectCount, Pose, RobotSystem, ServerState
from gripper_rs.reconnect import ConnectionEvent, ReconnectPolicy
from gripper_rs.wsg import (
    Reply,
    FingerFlags,
    FingerInfo,
    GraspingStatistics,
    GripState,
    SoftLimits,
    SystemInfo,
    SystemLimits,
    SystemState,
)
from gripper_rs.wsg.sim import SimSnapshot
from gripper_rs.wsg.text import Push

_T = TypeVar("_T")

__version__: str

def _quiesce() -> None: ...
def reset_logging_cache() -> None:
    """Forgets the cached ``logging`` levels of the ``gripper`` loggers: call it after changing
    the ``logging`` configuration once the package has logged."""
def _set_future(fut: object, ok: bool, value: object) -> None: ...

class Stream(Generic[_T]):
    """A stream of values: ``for v in stream`` blocks for each (Ctrl-C ends the wait),
    ``async for v in stream`` awaits each.

    A lost connection ends it with ``ConnectionLostError`` (raised once; the stream is then
    exhausted) when the connection is over for good: no ``reconnect`` policy, or the policy
    gave up. A connection the policy restores does not end it: the client asks the device for
    it again on the new connection (WSG auto-updates, GCL pushes; a GRIPLINK watch polls on),
    and values come again once restored; those the device would have sent meanwhile are not
    made up. ``close()`` (or leaving ``with`` / ``async with``) ends it at once, from any
    thread or task: readers waiting on it get ``StopIteration`` / ``StopAsyncIteration``.
    Closing the client ends it the same way. A reader that falls behind misses values
    (``missed``): see ``buffer_size`` and ``latest_only``.
    """

    def __iter__(self) -> Self: ...
    def __next__(self) -> _T:
        """The next value; waits for it with the GIL released."""
    def __aiter__(self) -> Self: ...
    def __anext__(self) -> Awaitable[_T]:
        """The next value, as an awaitable of the running event loop."""
    def close(self) -> None:
        """Ends the stream now: readers waiting on it get ``StopIteration`` /
        ``StopAsyncIteration``, unread values are dropped, and the device is told to stop
        sending (in the background). Never waits; calling it again does nothing."""
    def aclose(self) -> Awaitable[None]:
        """``close()`` as an awaitable (the async generator protocol's name)."""
    @property
    def is_closed(self) -> bool:
        """Whether the stream has ended (closed, or its connection ended) and holds no unread
        value."""
    @property
    def missed(self) -> int:
        """Values dropped so far because the reader fell behind: the buffer was full (the
        newest value was dropped), or with ``latest_only`` an unread value was replaced."""
    @property
    def buffer_size(self) -> int:
        """How many unread values the stream keeps (default 64; at least 1). While it is full,
        pushed values (WSG auto-updates, GCL pushes) are dropped and counted in ``missed``; a
        polling watch (GRIPLINK) polls no faster than it is read."""
    @buffer_size.setter
    def buffer_size(self, size: int) -> None:
        """How many unread items the stream keeps (default 64). While it is full, pushed values (WSG
        auto-updates, GCL pushes) are dropped and counted in `missed`; a polling watch (GRIPLINK)
        instead polls no faster than it is read."""
    @property
    def latest_only(self) -> bool:
        """Keep only the newest unread value: a reader always gets the latest state, and each
        value it never saw counts in ``missed``."""
    @latest_only.setter
    def latest_only(self, on: bool) -> None:
        """Keep only the newest unread value: a reader always gets the latest state, and each value it
        never saw counts in `missed`."""
    def __enter__(self) -> Self: ...
    def __exit__(
        self,
        ty: type[BaseException] | None,
        value: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...
    async def __aenter__(self) -> Self: ...
    async def __aexit__(
        self,
        ty: type[BaseException] | None,
        value: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...

class _SimBase:
    """A simulator serving on loopback in this process; ``with`` stops it at the end."""

    @property
    def address(self) -> str:
        """Where it listens, as "host:port" (the port chosen when port 0 was asked for)."""
    @property
    def port(self) -> int:
        """The port it listens on."""
    def shutdown(self) -> None:
        """Stops the simulator and cuts its connections (idempotent)."""
    def __enter__(self) -> Self: ...
    def __exit__(
        self,
        ty: type[BaseException] | None,
        value: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...

class _Blocking:
    """A blocking client: every call waits with the GIL released (Ctrl-C ends the wait)."""

    @property
    def is_closed(self) -> bool:
        """Whether the connection is closed for good (``close()`` was called, or it was lost
        and is not being restored): every call fails."""
    def __enter__(self) -> Self:
        """The client itself; leaving the block closes it (``close()``)."""
    def __exit__(
        self,
        ty: type[BaseException] | None,
        value: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...

class _Async:
    """An asyncio client: every call is an awaitable of the running event loop; cancelling one
    abandons the wait (the command may still run on the device: see the README)."""

    @property
    def is_closed(self) -> bool:
        """Whether the connection is closed for good (``close()`` was called, or it was lost
        and is not being restored): every call fails."""
    def __aenter__(self) -> Awaitable[Self]:
        """The client itself; leaving the block closes it (``close()``)."""
    def __aexit__(
        self,
        ty: type[BaseException] | None,
        value: BaseException | None,
        tb: TracebackType | None,
    ) -> Awaitable[None]: ...

class wsg:
    DEFAULT_PORT: int
    @staticmethod
    def status_codes() -> list[tuple[int, str, str]]:
        """Every status code the manual lists, as (code, symbol, description): the Python `Status` enum
        is tested against this so the two cannot drift apart."""
    @staticmethod
    def _width_request() -> bytes: ...

    class Client(_Blocking):
        """A WSG gripper (blocking API): every method waits for the device's reply with the GIL
        released; any number of threads may share one client. `with` closes it (announcing the
        disconnect, command 0x07, so the gripper does not FAST STOP)."""

        @staticmethod
        def connect_tcp(
            addr: str,
            *,
            query_timeout_s: float | None = None,
            motion_timeout_s: float | None = None,
            connect_timeout_s: float | None = None,
            late_reply_grace_s: float | None = None,
            reconnect: ReconnectPolicy | None = None,
        ) -> wsg.Client:
            """Connects over TCP to "host:port"."""
        @staticmethod
        def connect_udp(
            addr: str,
            *,
            query_timeout_s: float | None = None,
            motion_timeout_s: float | None = None,
            late_reply_grace_s: float | None = None,
        ) -> wsg.Client:
            """Talks UDP to "host:port" (one frame per datagram)."""
        @staticmethod
        def open_serial(
            path: str,
            baud_rate: int = 115200,
            *,
            query_timeout_s: float | None = None,
            motion_timeout_s: float | None = None,
            late_reply_grace_s: float | None = None,
        ) -> wsg.Client:
            """Opens the serial port `path` (RS-232) at `baud_rate`."""
        @property
        def aio(self) -> wsg.AioClient:
            """The asyncio view of this connection (same connection, same pairing)."""
        def with_timeouts(self, query_s: float, motion_s: float) -> wsg.Client:
            """A handle on the same connection whose calls use other timeouts."""
        def home(self, direction: int = 0) -> None:
            """Command 0x20: reference the fingers (direction 0 = the device's default, 1 = positive, 2
            = negative)."""
        def pre_position(
            self, width_mm: float, speed_mm_per_s: float, *, clamp_on_block: bool = False
        ) -> None:
            """Command 0x21: move to ``width_mm`` at ``speed_mm_per_s``. Blocked on the way, the
            fingers stop (``DeviceError`` E_AXIS_BLOCKED), or with ``clamp_on_block`` clamp with
            50 % of the nominal force."""
        def pre_position_relative(
            self, distance_mm: float, speed_mm_per_s: float, *, clamp_on_block: bool = False
        ) -> None:
            """Command 0x21: move by ``distance_mm`` (negative: close); ``clamp_on_block`` as
            for ``pre_position``."""
        def stop(self) -> None:
            """Command 0x22: stop the current motion."""
        def fast_stop(self) -> None:
            """Command 0x23: FAST STOP (must be acknowledged before the next motion)."""
        def acknowledge_fast_stop(self) -> None:
            """Command 0x24: acknowledge a FAST STOP."""
        def grasp(self, width_mm: float, speed_mm_per_s: float) -> None:
            """Command 0x25: grasp a part of nominal `width_mm` at `speed_mm_per_s`."""
        def release(self, width_mm: float, speed_mm_per_s: float) -> None:
            """Command 0x26: release the part, opening to `width_mm`."""
        def set_acceleration(self, mm_per_s2: float) -> None:
            """Command 0x30: set the acceleration, mm/s²."""
        def acceleration_mm_per_s2(self) -> float:
            """Command 0x31: the acceleration, mm/s²."""
        def set_grasping_force(self, force_n: float) -> None:
            """Command 0x32: set the grasping force, N."""
        def grasping_force_n(self) -> float:
            """Command 0x33: the grasping force, N."""
        def set_soft_limits(self, minus_mm: float, plus_mm: float) -> None:
            """Command 0x34: set the soft limits, mm."""
        def soft_limits(self) -> SoftLimits | None:
            """Command 0x35: the soft limits, or None when none are set."""
        def clear_soft_limits(self) -> None:
            """Command 0x36: clear the soft limits."""
        def set_overdrive(self, on: bool) -> None:
            """Command 0x37: overdrive mode on or off."""
        def tare_force_sensor(self) -> None:
            """Command 0x38: tare the force sensor."""
        def system_state(self) -> SystemState:
            """Command 0x40: the system state flags."""
        def grip_state(self) -> GripState:
            """Command 0x41: the grip state."""
        def grasping_statistics(self, reset: bool = False) -> GraspingStatistics:
            """Command 0x42: the grasping statistics (and reset them when `reset`)."""
        def width_mm(self) -> float:
            """Command 0x43: the opening width, mm."""
        def speed_mm_per_s(self) -> float:
            """Command 0x44: the finger speed, mm/s."""
        def force_n(self) -> float:
            """Command 0x45: the grasping force, N."""
        def temperature_c(self) -> float:
            """Command 0x46: the temperature inside the gripper, °C."""
        def system_info(self) -> SystemInfo:
            """Command 0x50: device type, revision, firmware, serial number."""
        def set_device_tag(self, tag: str) -> None:
            """Command 0x51: set the device tag."""
        def device_tag(self) -> str | None:
            """Command 0x52: the device tag, or None when none is set."""
        def system_limits(self) -> SystemLimits:
            """Command 0x53: the system limits."""
        def finger_info(self, finger: int) -> FingerInfo:
            """Commands 0x60 / 0x70: finger 1 or 2's type and data size."""
        def finger_flags(self, finger: int) -> FingerFlags:
            """Commands 0x61 / 0x71: finger 1 or 2's flags."""
        def set_finger_power(self, finger: int, on: bool) -> None:
            """Commands 0x62 / 0x72: finger 1 or 2's power."""
        def finger_data(self, finger: int) -> bytes:
            """Commands 0x63 / 0x73: finger 1 or 2's data."""
        def loop_back(self, data: bytes) -> bytes:
            """Command 0x06: the device echoes `data`."""
        def request(self, id: int, payload: bytes = b"", *, timeout_s: float | None = None) -> Reply:
            """Any command by id with ``payload`` (one the package has no method for): its final
            reply, whatever its status, within the query timeout or ``timeout_s``. A command that
            was sent runs on the device even if the call is abandoned."""
        def connection_events(self) -> Stream[ConnectionEvent]:
            """The connection's events from now on: each loss, and with a reconnect policy each
            attempt and recovery. Ends when the client has closed or given up."""
        def subscribe_system_state(self, period_s: float, on_change: bool = False) -> Stream[SystemState]:
            """Stream of the system state flags (0x40 auto-update) every `period_s` (or on change)."""
        def subscribe_grip_state(self, period_s: float, on_change: bool = False) -> Stream[GripState]:
            """Stream of the grip state (0x41 auto-update)."""
        def subscribe_width_mm(self, period_s: float, on_change: bool = False) -> Stream[float]:
            """Stream of the opening width, mm (0x43 auto-update)."""
        def subscribe_speed_mm_per_s(self, period_s: float, on_change: bool = False) -> Stream[float]:
            """Stream of the finger speed, mm/s (0x44 auto-update)."""
        def subscribe_force_n(self, period_s: float, on_change: bool = False) -> Stream[float]:
            """Stream of the finger force, N (0x45 auto-update)."""
        def close(self) -> None:
            """Closes the connection (TCP: announces the disconnect, 0x07, first)."""

    class AioClient(_Async):
        """A WSG gripper (asyncio API): the same methods as `gripper_rs.wsg.Client`, as awaitables.
        Cancelling one leaves the client usable and its replies correctly paired."""

        @staticmethod
        def connect_tcp(
            addr: str,
            *,
            query_timeout_s: float | None = None,
            motion_timeout_s: float | None = None,
            connect_timeout_s: float | None = None,
            late_reply_grace_s: float | None = None,
            reconnect: ReconnectPolicy | None = None,
        ) -> Awaitable[wsg.AioClient]:
            """Connects over TCP to "host:port"."""
        @staticmethod
        def connect_udp(
            addr: str,
            *,
            query_timeout_s: float | None = None,
            motion_timeout_s: float | None = None,
            late_reply_grace_s: float | None = None,
        ) -> Awaitable[wsg.AioClient]:
            """Talks UDP to "host:port" (one frame per datagram)."""
        @property
        def blocking(self) -> wsg.Client:
            """The blocking view of this connection (same connection, same pairing)."""
        def with_timeouts(self, query_s: float, motion_s: float) -> wsg.AioClient:
            """A handle on the same connection whose calls use other timeouts."""
        def home(self, direction: int = 0) -> Awaitable[None]:
            """Command 0x20: reference the fingers (direction 0 = the device's default, 1 = positive, 2
            = negative)."""
        def pre_position(
            self, width_mm: float, speed_mm_per_s: float, *, clamp_on_block: bool = False
        ) -> Awaitable[None]:
            """Command 0x21: move to ``width_mm`` at ``speed_mm_per_s``. Blocked on the way, the
            fingers stop (``DeviceError`` E_AXIS_BLOCKED), or with ``clamp_on_block`` clamp with
            50 % of the nominal force."""
        def pre_position_relative(
            self, distance_mm: float, speed_mm_per_s: float, *, clamp_on_block: bool = False
        ) -> Awaitable[None]:
            """Command 0x21: move by ``distance_mm`` (negative: close); ``clamp_on_block`` as
            for ``pre_position``."""
        def stop(self) -> Awaitable[None]:
            """Command 0x22: stop the current motion."""
        def fast_stop(self) -> Awaitable[None]:
            """Command 0x23: FAST STOP (must be acknowledged before the next motion)."""
        def acknowledge_fast_stop(self) -> Awaitable[None]:
            """Command 0x24: acknowledge a FAST STOP."""
        def grasp(self, width_mm: float, speed_mm_per_s: float) -> Awaitable[None]:
            """Command 0x25: grasp a part of nominal `width_mm` at `speed_mm_per_s`."""
        def release(self, width_mm: float, speed_mm_per_s: float) -> Awaitable[None]:
            """Command 0x26: release the part, opening to `width_mm`."""
        def set_acceleration(self, mm_per_s2: float) -> Awaitable[None]:
            """Command 0x30: set the acceleration, mm/s²."""
        def acceleration_mm_per_s2(self) -> Awaitable[float]:
            """Command 0x31: the acceleration, mm/s²."""
        def set_grasping_force(self, force_n: float) -> Awaitable[None]:
            """Command 0x32: set the grasping force, N."""
        def grasping_force_n(self) -> Awaitable[float]:
            """Command 0x33: the grasping force, N."""
        def set_soft_limits(self, minus_mm: float, plus_mm: float) -> Awaitable[None]:
            """Command 0x34: set the soft limits, mm."""
        def soft_limits(self) -> Awaitable[SoftLimits | None]:
            """Command 0x35: the soft limits, or None when none are set."""
        def clear_soft_limits(self) -> Awaitable[None]:
            """Command 0x36: clear the soft limits."""
        def set_overdrive(self, on: bool) -> Awaitable[None]:
            """Command 0x37: overdrive mode on or off."""
        def tare_force_sensor(self) -> Awaitable[None]:
            """Command 0x38: tare the force sensor."""
        def system_state(self) -> Awaitable[SystemState]:
            """Command 0x40: the system state flags."""
        def grip_state(self) -> Awaitable[GripState]:
            """Command 0x41: the grip state."""
        def grasping_statistics(self, reset: bool = False) -> Awaitable[GraspingStatistics]:
            """Command 0x42: the grasping statistics (and reset them when `reset`)."""
        def width_mm(self) -> Awaitable[float]:
            """Command 0x43: the opening width, mm."""
        def speed_mm_per_s(self) -> Awaitable[float]:
            """Command 0x44: the finger speed, mm/s."""
        def force_n(self) -> Awaitable[float]:
            """Command 0x45: the grasping force, N."""
        def temperature_c(self) -> Awaitable[float]:
            """Command 0x46: the temperature inside the gripper, °C."""
        def system_info(self) -> Awaitable[SystemInfo]:
            """Command 0x50: device type, revision, firmware, serial number."""
        def set_device_tag(self, tag: str) -> Awaitable[None]:
            """Command 0x51: set the device tag."""
        def device_tag(self) -> Awaitable[str | None]:
            """Command 0x52: the device tag, or None when none is set."""
        def system_limits(self) -> Awaitable[SystemLimits]:
            """Command 0x53: the system limits."""
        def finger_info(self, finger: int) -> Awaitable[FingerInfo]:
            """Commands 0x60 / 0x70: finger 1 or 2's type and data size."""
        def finger_flags(self, finger: int) -> Awaitable[FingerFlags]:
            """Commands 0x61 / 0x71: finger 1 or 2's flags."""
        def set_finger_power(self, finger: int, on: bool) -> Awaitable[None]:
            """Commands 0x62 / 0x72: finger 1 or 2's power."""
        def finger_data(self, finger: int) -> Awaitable[bytes]:
            """Commands 0x63 / 0x73: finger 1 or 2's data."""
        def loop_back(self, data: bytes) -> Awaitable[bytes]:
            """Command 0x06: the device echoes `data`."""
        def request(
            self, id: int, payload: bytes = b"", *, timeout_s: float | None = None
        ) -> Awaitable[Reply]:
            """Any command by id with ``payload``: its final reply, whatever its status."""
        def connection_events(self) -> Stream[ConnectionEvent]:
            """The connection's events from now on (see the blocking client)."""
        def subscribe_system_state(self, period_s: float, on_change: bool = False) -> Awaitable[Stream[SystemState]]:
            """Stream of the system state flags (0x40 auto-update) every `period_s` (or on change)."""
        def subscribe_grip_state(self, period_s: float, on_change: bool = False) -> Awaitable[Stream[GripState]]:
            """Stream of the grip state (0x41 auto-update)."""
        def subscribe_width_mm(self, period_s: float, on_change: bool = False) -> Awaitable[Stream[float]]:
            """Stream of the opening width, mm (0x43 auto-update)."""
        def subscribe_speed_mm_per_s(self, period_s: float, on_change: bool = False) -> Awaitable[Stream[float]]:
            """Stream of the finger speed, mm/s (0x44 auto-update)."""
        def subscribe_force_n(self, period_s: float, on_change: bool = False) -> Awaitable[Stream[float]]:
            """Stream of the finger force, N (0x45 auto-update)."""
        def close(self) -> Awaitable[None]:
            """Closes the connection (TCP: announces the disconnect, 0x07, first)."""

    class SimServer(_SimBase):
        """A simulated WSG gripper serving TCP (or UDP) in this process, for tests and examples.
        `with SimServer() as sim:` stops it at the end of the block."""

        def __init__(
            self,
            *,
            model: str = "WSG50",
            part_width_mm: float | None = None,
            part_tolerance_mm: float = 2.0,
            time_scale: float = 0.0,
            force_sensor: bool = False,
            temperature_c: float | None = None,
            addr: str = "127.0.0.1:0",
            udp: bool = False,
            text: bool = False,
            fast_stop_on_close: bool = True,
        ) -> None: ...
        def snapshot(self) -> SimSnapshot:
            """The simulated gripper now: grip state, system state, width, connections, streams."""
        def received_ids(self) -> list[int]:
            """Command ids received, oldest first."""
        def drop_next_reply(self, id: int) -> None:
            """The next reply to command `id` is not sent."""
        def corrupt_next_reply(self, id: int) -> None:
            """The next reply to command `id` has a wrong checksum."""
        def delay_next_reply(self, id: int, delay_s: float) -> None:
            """The next reply to command `id` is sent `delay_s` late."""
        def force_status(self, id: int, code: int) -> None:
            """The next reply to command `id` carries status `code` instead."""
        def lose_part(self) -> None:
            """The held part slips out of the fingers."""
        def set_time_scale(self, time_scale: float) -> None:
            """Changes the time scale (0: instant motion, 1: real time)."""
        def unplug(self) -> None:
            """Cuts every connection (the cable is pulled)."""

class wsg_text:
    class Client(_Blocking):
        """A WSG in text mode (blocking API): every method waits for the gripper's reply with the
        GIL released; any number of threads may share one client. `with` closes it with `BYE()`,
        so the gripper does not FAST STOP."""

        @staticmethod
        def connect(
            addr: str,
            *,
            query_timeout_s: float | None = None,
            motion_timeout_s: float | None = None,
            connect_timeout_s: float | None = None,
        ) -> wsg_text.Client:
            """Connects over TCP to "host:port"."""
        @property
        def aio(self) -> wsg_text.AioClient:
            """The asyncio view of this connection (same connection, same pairing)."""
        def home(self, direction: int = 0) -> None:
            """`HOME()` (direction 0, the default), `HOME(1)` (1, positive) or `HOME(0)` (2, negative):
            the same numbers as `gripper_rs.wsg.HomingDirection`, written in GCL's form."""
        def move_to(self, width_mm: float, speed_mm_per_s: float | None = None) -> None:
            """`MOVE(p[,v])`: move to `width_mm`, with an optional speed limit."""
        def grip(self, force_n: float | None = None) -> None:
            """`GRIP()` or `GRIP(f)`: grip inward until a part is found."""
        def grip_part(
            self, force_n: float, part_width_mm: float, speed_mm_per_s: float | None = None
        ) -> None:
            """`GRIP(f,w[,v])`: grip a part expected at `part_width_mm`."""
        def release(
            self, pull_back_mm: float | None = None, speed_mm_per_s: float | None = None
        ) -> None:
            """`RELEASE([d[,v]])`: open BY `pull_back_mm` from where the fingers are (relative, unlike
            the binary protocol's release)."""
        def stop(self) -> None:
            """`STOP()`: stop the running motion (its call raises with E_CMD_ABORTED)."""
        def fast_stop(self) -> None:
            """`FASTSTOP()`: stop and refuse motion until `ack_fast_stop()`."""
        def ack_fast_stop(self) -> None:
            """`FSACK()`: acknowledge FAST STOP (answered also with none pending)."""
        def set_verbose(self, on: bool) -> bool:
            """`VERBOSE=0|1`: returns the mode the gripper reports."""
        def part_width_tolerance_mm(self) -> float:
            """`PWT?`: the part width tolerance of this connection, mm."""
        def set_part_width_tolerance_mm(self, mm: float) -> float:
            """`PWT=x`: returns the value the gripper reports."""
        def clamping_travel_mm(self) -> float:
            """`CLT?`: the clamping travel of this connection, mm."""
        def set_clamping_travel_mm(self, mm: float) -> float:
            """`CLT=x`: returns the value the gripper reports."""
        def position_mm(self) -> float:
            """`POS?`: the opening width, mm."""
        def speed_mm_per_s(self) -> float:
            """`SPEED?`: the finger speed, mm/s."""
        def force_n(self) -> float:
            """`FORCE?`: the grip force, N."""
        def temperature_c(self) -> float:
            """`TEMP?`: the temperature, °C."""
        def grip_state(self) -> GripState:
            """`GRIPSTATE?`: the grip state (`gripper_rs.wsg.GripState`)."""
        def autosend(
            self, quantity: str, interval_ms: int, only_on_change: bool = False
        ) -> Stream[Push]:
            """`AUTOSEND("NAME",ms[,true])`: a stream of `Push(quantity, value)` for `quantity` ("POS",
            "SPEED", "FORCE", "GRIPSTATE", "TEMP")."""
        def stop_autosend(self, quantity: str) -> None:
            """`AUTOSEND("NAME",0)`: stop pushing `quantity`."""
        def close(self) -> None:
            """`BYE()`: announce the disconnect and close."""

    class AioClient(_Async):
        """A WSG in text mode (asyncio API): the same methods as `gripper_rs.wsg.text.Client`, as
        awaitables."""

        @staticmethod
        def connect(
            addr: str,
            *,
            query_timeout_s: float | None = None,
            motion_timeout_s: float | None = None,
            connect_timeout_s: float | None = None,
        ) -> Awaitable[wsg_text.AioClient]:
            """Connects over TCP to "host:port"."""
        @property
        def blocking(self) -> wsg_text.Client:
            """The blocking view of this connection (same connection, same pairing)."""
        def home(self, direction: int = 0) -> Awaitable[None]:
            """`HOME()` (direction 0, the default), `HOME(1)` (1, positive) or `HOME(0)` (2, negative):
            the same numbers as `gripper_rs.wsg.HomingDirection`, written in GCL's form."""
        def move_to(
            self, width_mm: float, speed_mm_per_s: float | None = None
        ) -> Awaitable[None]:
            """`MOVE(p[,v])`: move to `width_mm`, with an optional speed limit."""
        def grip(self, force_n: float | None = None) -> Awaitable[None]:
            """`GRIP()` or `GRIP(f)`: grip inward until a part is found."""
        def grip_part(
            self, force_n: float, part_width_mm: float, speed_mm_per_s: float | None = None
        ) -> Awaitable[None]:
            """`GRIP(f,w[,v])`: grip a part expected at `part_width_mm`."""
        def release(
            self, pull_back_mm: float | None = None, speed_mm_per_s: float | None = None
        ) -> Awaitable[None]:
            """`RELEASE([d[,v]])`: open BY `pull_back_mm` from where the fingers are (relative, unlike
            the binary protocol's release)."""
        def stop(self) -> Awaitable[None]:
            """`STOP()`: stop the running motion (its call raises with E_CMD_ABORTED)."""
        def fast_stop(self) -> Awaitable[None]:
            """`FASTSTOP()`: stop and refuse motion until `ack_fast_stop()`."""
        def ack_fast_stop(self) -> Awaitable[None]:
            """`FSACK()`: acknowledge FAST STOP (answered also with none pending)."""
        def set_verbose(self, on: bool) -> Awaitable[bool]:
            """`VERBOSE=0|1`: returns the mode the gripper reports."""
        def part_width_tolerance_mm(self) -> Awaitable[float]:
            """`PWT?`: the part width tolerance of this connection, mm."""
        def set_part_width_tolerance_mm(self, mm: float) -> Awaitable[float]:
            """`PWT=x`: returns the value the gripper reports."""
        def clamping_travel_mm(self) -> Awaitable[float]:
            """`CLT?`: the clamping travel of this connection, mm."""
        def set_clamping_travel_mm(self, mm: float) -> Awaitable[float]:
            """`CLT=x`: returns the value the gripper reports."""
        def position_mm(self) -> Awaitable[float]:
            """`POS?`: the opening width, mm."""
        def speed_mm_per_s(self) -> Awaitable[float]:
            """`SPEED?`: the finger speed, mm/s."""
        def force_n(self) -> Awaitable[float]:
            """`FORCE?`: the grip force, N."""
        def temperature_c(self) -> Awaitable[float]:
            """`TEMP?`: the temperature, °C."""
        def grip_state(self) -> Awaitable[GripState]:
            """`GRIPSTATE?`: the grip state (`gripper_rs.wsg.GripState`)."""
        def autosend(
            self, quantity: str, interval_ms: int, only_on_change: bool = False
        ) -> Awaitable[Stream[Push]]:
            """`AUTOSEND("NAME",ms[,true])`: a stream of `Push(quantity, value)` for `quantity` ("POS",
            "SPEED", "FORCE", "GRIPSTATE", "TEMP")."""
        def stop_autosend(self, quantity: str) -> Awaitable[None]:
            """`AUTOSEND("NAME",0)`: stop pushing `quantity`."""
        def close(self) -> Awaitable[None]:
            """`BYE()`: announce the disconnect and close."""

class griplink:
    DEFAULT_PORT: int
    @staticmethod
    def status_codes() -> list[tuple[int, str, str]]:
        """Every status code the manual lists, as (code, identifier, description)."""

    class Client(_Blocking):
        """A GRIPLINK controller (blocking API). `client.port(n)` is the device on port n. `with`
        closes the connection (BYE)."""

        @staticmethod
        def connect(
            addr: str,
            *,
            query_timeout_s: float | None = None,
            motion_timeout_s: float | None = None,
            connect_timeout_s: float | None = None,
            reconnect: ReconnectPolicy | None = None,
        ) -> griplink.Client:
            """Connects to "host:port"."""
        def port(self, n: int) -> griplink.Port:
            """The device on port `n` (0..=31)."""
        @property
        def aio(self) -> griplink.AioClient:
            """The asyncio view of this connection (same connection, same pairing)."""
        def with_timeout(self, timeout_s: float) -> griplink.Client:
            """A handle on the same connection whose calls use another timeout."""
        def command(self, line: str) -> Answer | None:
            """A raw command line (printable ASCII, without LF) the package has no method for:
            None for ``ACK``, an ``Answer`` for ``KEY[...]=value``; ``ERR`` raises
            ``DeviceError``. Do not send ``BYE`` this way: use ``close()``."""
        def connection_events(self) -> Stream[ConnectionEvent]:
            """The connection's events from now on: each loss, and with a reconnect policy each
            attempt and recovery. Ends when the connection is closed for good."""
        def id(self) -> str:
            """`ID?`: the controller's identifier."""
        def protocol(self) -> str:
            """`PROTOCOL?`: the protocol identifier and version."""
        def protocol_assert(self, identifier: str, min_version: int) -> None:
            """`PROTOCOL?` checked: `identifier` at version `min_version` or later."""
        def serial_number(self) -> str:
            """`SN?`: the controller's serial number."""
        def label(self) -> str:
            """`LABEL?`."""
        def set_label(self, label: str) -> str:
            """`LABEL=`: returns the label the controller stored."""
        def version(self) -> str:
            """`VER?`: the firmware version."""
        def set_verbose(self, on: bool) -> bool:
            """`VERBOSE=`: error replies with text."""
        def close(self) -> None:
            """`BYE`, then closes the connection."""

    class AioClient(_Async):
        """A GRIPLINK controller (asyncio API): the methods of `gripper_rs.griplink.Client` as
        awaitables."""

        @staticmethod
        def connect(
            addr: str,
            *,
            query_timeout_s: float | None = None,
            motion_timeout_s: float | None = None,
            connect_timeout_s: float | None = None,
            reconnect: ReconnectPolicy | None = None,
        ) -> Awaitable[griplink.AioClient]:
            """Connects to "host:port"."""
        def port(self, n: int) -> griplink.AioPort:
            """The device on port `n` (0..=31)."""
        @property
        def blocking(self) -> griplink.Client:
            """The blocking view of this connection (same connection, same pairing)."""
        def with_timeout(self, timeout_s: float) -> griplink.AioClient:
            """A handle on the same connection whose calls use another timeout."""
        def command(self, line: str) -> Awaitable[Answer | None]:
            """A raw command line: None for ``ACK``, an ``Answer`` for data (see the blocking
            client)."""
        def connection_events(self) -> Stream[ConnectionEvent]:
            """The connection's events from now on (see the blocking client)."""
        def id(self) -> Awaitable[str]:
            """`ID?`: the controller's identifier."""
        def protocol(self) -> Awaitable[str]:
            """`PROTOCOL?`: the protocol identifier and version."""
        def protocol_assert(self, identifier: str, min_version: int) -> Awaitable[None]:
            """`PROTOCOL?` checked: `identifier` at version `min_version` or later."""
        def serial_number(self) -> Awaitable[str]:
            """`SN?`: the controller's serial number."""
        def label(self) -> Awaitable[str]:
            """`LABEL?`."""
        def set_label(self, label: str) -> Awaitable[str]:
            """`LABEL=`: returns the label the controller stored."""
        def version(self) -> Awaitable[str]:
            """`VER?`: the firmware version."""
        def set_verbose(self, on: bool) -> Awaitable[bool]:
            """`VERBOSE=`: error replies with text."""
        def close(self) -> Awaitable[None]:
            """`BYE`, then closes the connection."""

    class Port:
        """The device on one port of a GRIPLINK controller (blocking API)."""

        @property
        def number(self) -> int:
            """The port number."""
        def with_timeout(self, timeout_s: float) -> griplink.Port:
            """The same port with another timeout for its calls."""
        def watch_state(self, interval_s: float) -> Stream[DeviceState]:
            """Polls DEVSTATE every `interval_s`: a stream of device states."""
        def watch_value(self, index: int, interval_s: float) -> Stream[float]:
            """Polls VALUEF[index] every `interval_s`: a stream of values."""
        def vendor_id(self) -> int | None:
            """`VENDORID[p]?` (None: no device)."""
        def product_id(self) -> int:
            """`PRODUCTID[p]?`."""
        def assert_device(self, vendor_id: int, product_id: int) -> None:
            """Checks the device's vendor and product id."""
        def name(self) -> str:
            """`DEVNAME[p]?`."""
        def vendor(self) -> str:
            """`DEVVENDOR[p]?`."""
        def serial_number(self) -> str:
            """`DEVSN[p]?`."""
        def tag(self) -> str:
            """`DEVTAG[p]?`."""
        def set_tag(self, tag: str) -> str:
            """`DEVTAG[p]=`: returns the stored tag."""
        def version(self) -> str:
            """`DEVVER[p]?`."""
        def enable(self) -> None:
            """`ENABLE(p)`."""
        def disable(self) -> None:
            """`DISABLE(p)`."""
        def home(self) -> None:
            """`HOME(p)`: the reference drive; waits until done."""
        def grip(self, index: int, until_done: bool = False) -> None:
            """`GRIP(p, index)` with recipe `index`; `until_done` holds the reply until the motion
            ends."""
        def release(self, index: int, until_done: bool = False) -> None:
            """`RELEASE(p, index)`."""
        def flex_grip(self, position_mm: float, force_n: float, speed_mm_per_s: float, acceleration_mm_per_s2: float, until_done: bool = False) -> None:
            """`FLEXGRIPF(p, ...)` in mm, N, mm/s, mm/s²."""
        def flex_release(self, position_mm: float, speed_mm_per_s: float, acceleration_mm_per_s2: float, until_done: bool = False) -> None:
            """`FLEXRELEASEF(p, ...)` in mm, mm/s, mm/s²."""
        def led(self, index: int) -> None:
            """`LED(p, index)`."""
        def clamp(self, enable: bool) -> None:
            """`CLAMP(p, enable)`."""
        def wait_for_transition(self) -> DeviceState:
            """`WSTR[p]?`: the state after the next transition."""
        def set_value(self, index: int, value: int) -> None:
            """`SETVAL(p, index, value)`."""
        def set_value_f(self, index: int, value: float) -> None:
            """`SETVALF(p, index, value)`."""
        def state(self) -> DeviceState:
            """`DEVSTATE[p]?`."""
        def value(self, index: int) -> int:
            """`VALUE[p][index]?`."""
        def value_f(self, index: int) -> float:
            """`VALUEF[p][index]?`."""
        def position_um(self) -> int:
            """The position, µm."""
        def position_mm(self) -> float:
            """The position, mm."""
        def grip_config(self, index: int) -> GripConfig:
            """`GRIPCFG[p][index]?`."""
        def set_grip_config(self, index: int, tag: str, params: Sequence[int]) -> GripConfig:
            """`GRIPCFG[p][index]=`: returns the stored recipe."""
        def grip_config_f(self, index: int) -> GripConfigF:
            """`GRIPCFGF[p][index]?`."""
        def set_grip_config_f(self, index: int, tag: str, params: Sequence[float]) -> GripConfigF:
            """`GRIPCFGF[p][index]=`: returns the stored recipe."""
        def grip_and_wait(self, index: int, poll_interval_s: float | None = None) -> GripOutcome:
            """GRIP with recipe `index`, then wait for its end: by the state transition (WSTR), or by
            polling DEVSTATE every `poll_interval_s`."""
        def release_and_wait(self, index: int, poll_interval_s: float | None = None) -> ReleaseOutcome:
            """RELEASE with recipe `index`, then wait for its end."""

    class AioPort:
        """The device on one port of a GRIPLINK controller (asyncio API)."""

        @property
        def number(self) -> int:
            """The port number."""
        def with_timeout(self, timeout_s: float) -> griplink.AioPort:
            """The same port with another timeout for its calls."""
        def watch_state(self, interval_s: float) -> Stream[DeviceState]:
            """Polls DEVSTATE every `interval_s`: an async stream of device states."""
        def watch_value(self, index: int, interval_s: float) -> Stream[float]:
            """Polls VALUEF[index] every `interval_s`: an async stream of values."""
        def vendor_id(self) -> Awaitable[int | None]:
            """`VENDORID[p]?` (None: no device)."""
        def product_id(self) -> Awaitable[int]:
            """`PRODUCTID[p]?`."""
        def assert_device(self, vendor_id: int, product_id: int) -> Awaitable[None]:
            """Checks the device's vendor and product id."""
        def name(self) -> Awaitable[str]:
            """`DEVNAME[p]?`."""
        def vendor(self) -> Awaitable[str]:
            """`DEVVENDOR[p]?`."""
        def serial_number(self) -> Awaitable[str]:
            """`DEVSN[p]?`."""
        def tag(self) -> Awaitable[str]:
            """`DEVTAG[p]?`."""
        def set_tag(self, tag: str) -> Awaitable[str]:
            """`DEVTAG[p]=`: returns the stored tag."""
        def version(self) -> Awaitable[str]:
            """`DEVVER[p]?`."""
        def enable(self) -> Awaitable[None]:
            """`ENABLE(p)`."""
        def disable(self) -> Awaitable[None]:
            """`DISABLE(p)`."""
        def home(self) -> Awaitable[None]:
            """`HOME(p)`: the reference drive; waits until done."""
        def grip(self, index: int, until_done: bool = False) -> Awaitable[None]:
            """`GRIP(p, index)` with recipe `index`; `until_done` holds the reply until the motion
            ends."""
        def release(self, index: int, until_done: bool = False) -> Awaitable[None]:
            """`RELEASE(p, index)`."""
        def flex_grip(self, position_mm: float, force_n: float, speed_mm_per_s: float, acceleration_mm_per_s2: float, until_done: bool = False) -> Awaitable[None]:
            """`FLEXGRIPF(p, ...)` in mm, N, mm/s, mm/s²."""
        def flex_release(self, position_mm: float, speed_mm_per_s: float, acceleration_mm_per_s2: float, until_done: bool = False) -> Awaitable[None]:
            """`FLEXRELEASEF(p, ...)` in mm, mm/s, mm/s²."""
        def led(self, index: int) -> Awaitable[None]:
            """`LED(p, index)`."""
        def clamp(self, enable: bool) -> Awaitable[None]:
            """`CLAMP(p, enable)`."""
        def wait_for_transition(self) -> Awaitable[DeviceState]:
            """`WSTR[p]?`: the state after the next transition."""
        def set_value(self, index: int, value: int) -> Awaitable[None]:
            """`SETVAL(p, index, value)`."""
        def set_value_f(self, index: int, value: float) -> Awaitable[None]:
            """`SETVALF(p, index, value)`."""
        def state(self) -> Awaitable[DeviceState]:
            """`DEVSTATE[p]?`."""
        def value(self, index: int) -> Awaitable[int]:
            """`VALUE[p][index]?`."""
        def value_f(self, index: int) -> Awaitable[float]:
            """`VALUEF[p][index]?`."""
        def position_um(self) -> Awaitable[int]:
            """The position, µm."""
        def position_mm(self) -> Awaitable[float]:
            """The position, mm."""
        def grip_config(self, index: int) -> Awaitable[GripConfig]:
            """`GRIPCFG[p][index]?`."""
        def set_grip_config(self, index: int, tag: str, params: Sequence[int]) -> Awaitable[GripConfig]:
            """`GRIPCFG[p][index]=`: returns the stored recipe."""
        def grip_config_f(self, index: int) -> Awaitable[GripConfigF]:
            """`GRIPCFGF[p][index]?`."""
        def set_grip_config_f(self, index: int, tag: str, params: Sequence[float]) -> Awaitable[GripConfigF]:
            """`GRIPCFGF[p][index]=`: returns the stored recipe."""
        def grip_and_wait(self, index: int, poll_interval_s: float | None = None) -> Awaitable[GripOutcome]:
            """GRIP with recipe `index`, then wait for its end: by the state transition (WSTR), or by
            polling DEVSTATE every `poll_interval_s`."""
        def release_and_wait(self, index: int, poll_interval_s: float | None = None) -> Awaitable[ReleaseOutcome]:
            """RELEASE with recipe `index`, then wait for its end."""

    class SimServer(_SimBase):
        """A simulated GRIPLINK controller serving TCP in this process."""

        def __init__(
            self,
            *,
            preset: str = "ET4",
            devices: Mapping[int, str | None] | None = None,
            parts: Mapping[int, float] | None = None,
            time_scale: float = 1.0,
            addr: str = "127.0.0.1:0",
        ) -> None: ...
        def device_state(self, port: int) -> DeviceState | None:
            """The state of the device on `port` (None: no device)."""
        def set_part(self, port: int, width_mm: float | None) -> None:
            """Puts a part of `width_mm` between the fingers on `port` (None: takes it away)."""
        def inject_device_fault(self, port: int) -> None:
            """The device on `port` goes into DS_FAULT now."""
        def fault_next_motion(self, port: int) -> None:
            """The next motion on `port` ends in DS_FAULT."""
        def drop_next_reply(self) -> None:
            """The next command is executed but not answered."""
        def delay_next_reply(self, delay_s: float) -> None:
            """The next command's reply comes `delay_s` late."""
        def fail_next(self, code: int) -> None:
            """The next command is refused with `ERR <code>`."""
        def raw_next_reply(self, data: bytes) -> None:
            """The next command is executed and answered with `data` (include the LF)."""
        def close_next(self) -> None:
            """The connection is closed instead of executing the next command."""

class smartgrasp:
    DEFAULT_PORT: int

    class Client(_Blocking):
        """A SCHUNK 2D Grasping-Kit (blocking API). `with` closes the connection."""

        @staticmethod
        def connect(
            addr: str,
            *,
            query_timeout_s: float | None = None,
            detection_timeout_s: float | None = None,
            connect_timeout_s: float | None = None,
            robot_system: int | None = None,
            project_index: int | None = None,
            protocol_version: int | None = None,
            tool_id: int | None = None,
            workspace_id: int | None = None,
            reconnect: ReconnectPolicy | None = None,
        ) -> smartgrasp.Client:
            """Connects to "host:port" and opens the session (protocol version, state, and the
            `robot_system` registration and `project_index` when given)."""
        @property
        def aio(self) -> smartgrasp.AioClient:
            """The asyncio view of this connection (same connection, same pairing)."""
        def with_timeout(self, timeout_s: float) -> smartgrasp.Client:
            """A handle on the same connection whose calls use another timeout."""
        def connection_events(self) -> Stream[ConnectionEvent]:
            """The connection's events from now on: each loss, and with a reconnect policy each
            attempt and recovery. Ends when the connection is closed for good."""
        def protocol_version(self) -> int:
            """The protocol version this connection speaks (3 or 4)."""
        def server_version(self) -> int:
            """The server's highest protocol version, as it answered when connecting."""
        def counter_gaps(self) -> int:
            """How many gaps in the response counter were seen (recorded, not fatal by default)."""
        def get_protocol_version(self) -> int:
            """GET_PROTOCOL_VERSION."""
        def get_state(self) -> ServerState:
            """GET_STATE."""
        def register_client(self, robot: int) -> None:
            """REGISTER_CLIENT (a `RobotSystem`)."""
        def set_project(self, project_index: int) -> None:
            """SET_PROJECT (V3: the project index; V4: the project ID)."""
        def set_tool(self, tool_id: int) -> None:
            """SET_TOOL (V4 only): the tool ID seen in the web frontend."""
        def set_workspace(self, workspace_id: int) -> None:
            """SET_WORKSPACE (V4 only): the workspace ID seen in the web frontend."""
        def get_grasp(self, grasp_mode: int, object_class: int, tool: int, pose_format: int, selection_criterion: int = 1) -> GraspResult:
            """GET_GRASP: a `GraspResult` (its `grasp` is None when the outcome is not GRASP). `tool`
            is sent in V3 only, `selection_criterion` in V4 only (its values are not public;
            SCHUNK's example sends 1 to 3)."""
        def grasp_feedback(self, ok: bool) -> None:
            """GRASP_FEEDBACK: whether the last grasp was fine."""
        def get_object_count(self, object_class: int) -> ObjectCount:
            """GET_OBJECT_COUNT (class 0: all)."""
        def robot_pose(self, format: int, wire: Sequence[int]) -> None:
            """ROBOT_POSE: the robot's pose, in `format` with the seven wire values."""
        def close(self) -> None:
            """Closes the connection."""

    class AioClient(_Async):
        """A SCHUNK 2D Grasping-Kit (asyncio API)."""

        @staticmethod
        def connect(
            addr: str,
            *,
            query_timeout_s: float | None = None,
            detection_timeout_s: float | None = None,
            connect_timeout_s: float | None = None,
            robot_system: int | None = None,
            project_index: int | None = None,
            protocol_version: int | None = None,
            tool_id: int | None = None,
            workspace_id: int | None = None,
            reconnect: ReconnectPolicy | None = None,
        ) -> Awaitable[smartgrasp.AioClient]:
            """Connects to "host:port" and opens the session."""
        @property
        def blocking(self) -> smartgrasp.Client:
            """The blocking view of this connection (same connection, same pairing)."""
        def with_timeout(self, timeout_s: float) -> smartgrasp.AioClient:
            """A handle on the same connection whose calls use another timeout."""
        def connection_events(self) -> Stream[ConnectionEvent]:
            """The connection's events from now on: each loss, and with a reconnect policy each
            attempt and recovery. Ends when the connection is closed for good."""
        def protocol_version(self) -> int:
            """The protocol version this connection speaks (3 or 4)."""
        def server_version(self) -> int:
            """The server's highest protocol version, as it answered when connecting."""
        def counter_gaps(self) -> int:
            """How many gaps in the response counter were seen (recorded, not fatal by default)."""
        def get_protocol_version(self) -> Awaitable[int]:
            """GET_PROTOCOL_VERSION."""
        def get_state(self) -> Awaitable[ServerState]:
            """GET_STATE."""
        def register_client(self, robot: int) -> Awaitable[None]:
            """REGISTER_CLIENT (a `RobotSystem`)."""
        def set_project(self, project_index: int) -> Awaitable[None]:
            """SET_PROJECT (V3: the project index; V4: the project ID)."""
        def set_tool(self, tool_id: int) -> Awaitable[None]:
            """SET_TOOL (V4 only): the tool ID seen in the web frontend."""
        def set_workspace(self, workspace_id: int) -> Awaitable[None]:
            """SET_WORKSPACE (V4 only): the workspace ID seen in the web frontend."""
        def get_grasp(self, grasp_mode: int, object_class: int, tool: int, pose_format: int, selection_criterion: int = 1) -> Awaitable[GraspResult]:
            """GET_GRASP: a `GraspResult` (its `grasp` is None when the outcome is not GRASP). `tool`
            is sent in V3 only, `selection_criterion` in V4 only (its values are not public;
            SCHUNK's example sends 1 to 3)."""
        def grasp_feedback(self, ok: bool) -> Awaitable[None]:
            """GRASP_FEEDBACK: whether the last grasp was fine."""
        def get_object_count(self, object_class: int) -> Awaitable[ObjectCount]:
            """GET_OBJECT_COUNT (class 0: all)."""
        def robot_pose(self, format: int, wire: Sequence[int]) -> Awaitable[None]:
            """ROBOT_POSE: the robot's pose, in `format` with the seven wire values."""
        def close(self) -> Awaitable[None]:
            """Closes the connection."""

    class SimServer(_SimBase):
        """A simulated Grasping-Kit serving TCP in this process (the Rust `SimConfig::default()`:
        the demo project, operational)."""

        def __init__(
            self,
            *,
            server_state: int | None = None,
            max_version: int | None = None,
            addr: str = "127.0.0.1:0",
        ) -> None: ...
        def registered_clients(self) -> list[RobotSystem]:
            """The robot systems registered so far (numbers of `RobotSystem`)."""
        def robot_poses(self) -> list[Pose]:
            """The robot poses received so far."""
        def set_server_state(self, state: int) -> None:
            """The server goes into `state` (a `ServerState`)."""
        def drop_next_reply(self) -> None:
            """The next request is processed but not answered."""
        def delay_next_reply(self, delay_s: float) -> None:
            """The next response comes `delay_s` late."""
        def corrupt_next_length(self, length: int) -> None:
            """The next response has `length` in its length field."""
        def close_next(self) -> None:
            """The connection is closed instead of the next response."""
        def refuse_next(self, code: int) -> None:
            """The next request is not carried out but answered with response code `code` (a
            `ResponseCode`, or a number the manual does not define)."""
