"""Fixtures: each protocol's in-process simulator on a free loopback port, and a client on it;
a relay the tests can cut (a pulled cable); an asyncio runner with a watchdog."""

from __future__ import annotations

import asyncio
import socket
import threading
import time
from collections.abc import Callable, Coroutine, Iterator
from typing import Any, TypeVar

import pytest

from gripper_rs import griplink, smartgrasp, wsg


@pytest.fixture
def wsg_sim() -> Iterator[wsg.sim.SimServer]:
    with wsg.sim.SimServer(part_width_mm=40.0) as server:
        yield server


@pytest.fixture
def wsg_client(wsg_sim: wsg.sim.SimServer) -> Iterator[wsg.Client]:
    with wsg.Client.connect_tcp(wsg_sim.address) as client:
        yield client


@pytest.fixture
def griplink_sim() -> Iterator[griplink.sim.SimServer]:
    # time scale 0: motion takes no time.
    with griplink.sim.SimServer(time_scale=0.0, parts={0: 12.0}) as server:
        yield server


@pytest.fixture
def griplink_client(griplink_sim: griplink.sim.SimServer) -> Iterator[griplink.Client]:
    with griplink.Client.connect(griplink_sim.address) as client:
        yield client


@pytest.fixture
def kit_sim() -> Iterator[smartgrasp.sim.SimServer]:
    with smartgrasp.sim.SimServer() as server:
        yield server


@pytest.fixture
def kit(kit_sim: smartgrasp.sim.SimServer) -> Iterator[smartgrasp.Client]:
    with smartgrasp.Client.connect(kit_sim.address) as client:
        yield client


class Relay:
    """A TCP relay on a free loopback port in front of ``target`` ("host:port"): the test's
    cable, which ``cut()`` pulls (every relayed connection is closed, both ways). ``sent`` holds
    every byte the clients sent, in order."""

    def __init__(self, target: str) -> None:
        host, port = target.rsplit(":", 1)
        self._target = (host, int(port))
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.address = "127.0.0.1:%d" % self._listener.getsockname()[1]
        self._lock = threading.Lock()
        self._sockets: list[socket.socket] = []
        self._closed = False
        self.sent = bytearray()
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                near, _ = self._listener.accept()
            except OSError:
                return
            far = socket.create_connection(self._target)
            with self._lock:
                if self._closed:
                    near.close()
                    far.close()
                    continue
                self._sockets += [near, far]
            for a, b, log in ((near, far, self.sent), (far, near, None)):
                threading.Thread(target=self._pipe, args=(a, b, log), daemon=True).start()

    def _pipe(self, src: socket.socket, dst: socket.socket, log: bytearray | None) -> None:
        try:
            while data := src.recv(65536):
                if log is not None:
                    with self._lock:
                        log += data
                dst.sendall(data)
        except OSError:
            pass
        finally:
            for s in (src, dst):
                try:
                    s.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass

    def cut(self) -> None:
        """Closes every relayed connection; new ones are still accepted."""
        with self._lock:
            sockets, self._sockets = self._sockets, []
        for s in sockets:
            try:
                s.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            s.close()

    def close(self) -> None:
        """Cuts every relayed connection and refuses new ones (the device is gone)."""
        with self._lock:
            self._closed = True
        # shutdown first: on Linux, close() alone leaves a thread blocked in accept() accepting.
        try:
            self._listener.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self._listener.close()
        self.cut()


@pytest.fixture
def wsg_relay(wsg_sim: wsg.sim.SimServer) -> Iterator[Relay]:
    relay = Relay(wsg_sim.address)
    yield relay
    relay.close()


@pytest.fixture
def griplink_relay(griplink_sim: griplink.sim.SimServer) -> Iterator[Relay]:
    relay = Relay(griplink_sim.address)
    yield relay
    relay.close()


T = TypeVar("T")

#: How long an asyncio test may take before its event loop counts as blocked.
WATCHDOG_S = 10.0


def run_async(main: Callable[[], Coroutine[Any, Any, T]], timeout_s: float = WATCHDOG_S) -> T:
    """``asyncio.run(main())`` with a watchdog: the loop runs in a thread of its own, and a loop
    that is still running after ``timeout_s`` (blocked by a call that waits inside it, say)
    fails the test instead of hanging it."""
    result: list[T] = []
    error: list[BaseException] = []

    def run() -> None:
        try:
            result.append(asyncio.run(main()))
        except BaseException as e:  # noqa: BLE001 (handed to the test's thread)
            error.append(e)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(timeout_s)
    if thread.is_alive():
        pytest.fail(f"the event loop was still busy after {timeout_s} s (blocked?)")
    if error:
        raise error[0]
    return result[0]


def wait_until(condition: Callable[[], bool], timeout_s: float = 5.0) -> None:
    """Polls ``condition`` until it holds; fails the test after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail("condition not reached in time")
        time.sleep(0.005)
