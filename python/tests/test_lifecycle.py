"""Lifecycle (issue 32): close() idempotent and is_closed on every client, clients closed at
interpreter exit with the protocol's disconnect announcement, a clear error after fork,
__version__."""

from __future__ import annotations

import importlib.metadata
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import Any

import pytest

import gripper_rs
import gripper_rs.aio
from conftest import Relay, run_async, wait_until
from gripper_rs import griplink, smartgrasp, wsg

ANNOUNCE_DISCONNECT = 0x07


def test_close_is_idempotent_and_is_closed_on_every_client(
    wsg_sim: wsg.sim.SimServer,
    griplink_sim: griplink.sim.SimServer,
    kit_sim: smartgrasp.sim.SimServer,
) -> None:
    with wsg.sim.SimServer(text=True) as text_sim:
        clients: list[Any] = [
            wsg.Client.connect_tcp(wsg_sim.address),
            wsg.text.Client.connect(text_sim.address),
            griplink.Client.connect(griplink_sim.address),
            smartgrasp.Client.connect(kit_sim.address),
        ]
        for client in clients:
            assert not client.is_closed
            assert not client.aio.is_closed
            client.close()
            assert client.is_closed, client
            assert client.aio.is_closed
            client.close()  # again: nothing happens
            with client:  # and leaving `with` neither
                pass


def test_async_close_is_idempotent(wsg_sim: wsg.sim.SimServer) -> None:
    async def main() -> bool:
        client = await gripper_rs.aio.wsg.Client.connect_tcp(wsg_sim.address)
        await client.close()
        await client.close()
        closed: bool = client.is_closed
        return closed

    assert run_async(main)


def test_close_after_a_lost_connection_does_not_raise(wsg_relay: Relay) -> None:
    client = wsg.Client.connect_tcp(wsg_relay.address)
    client.width_mm()
    wsg_relay.cut()
    wait_until(lambda: client.is_closed)
    with pytest.raises(gripper_rs.ConnectionLostError):
        client.width_mm()
    client.close()  # `finally: client.close()` does not hide the error above


def run_child(script: str) -> subprocess.CompletedProcess[str]:
    """Runs ``script`` in a fresh interpreter (this one's, with this sys.path)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(script)],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_clients_left_open_are_closed_at_exit(wsg_sim: wsg.sim.SimServer) -> None:
    child = run_child(
        f"""
        import asyncio
        import gripper_rs.aio
        from gripper_rs import wsg
        client = wsg.Client.connect_tcp({wsg_sim.address!r})
        client.home()
        async def main():
            # An asyncio client whose loop is gone by the time the interpreter exits.
            global aio
            aio = await gripper_rs.aio.wsg.Client.connect_tcp({wsg_sim.address!r})
            await aio.width_mm()
        asyncio.run(main())
        # A daemon thread still holds both when the program ends: they are never dropped (the
        # Rust client would announce the disconnect when dropped), only the process ends.
        import threading, time
        threading.Thread(target=lambda held=(client, aio): time.sleep(1000), daemon=True).start()
        print("leaving without close()")
        """
    )
    assert child.returncode == 0, child.stderr
    assert "leaving" in child.stdout
    # Both connections announced their disconnect, so the simulator is not in FAST STOP.
    assert wsg_sim.received_ids().count(ANNOUNCE_DISCONNECT) == 2
    assert wsg.SystemState.FAST_STOP not in wsg_sim.snapshot().system_state


def test_a_text_client_left_open_says_bye_at_exit() -> None:
    with wsg.sim.SimServer(text=True) as sim:
        child = run_child(
            f"""
            from gripper_rs import wsg
            import threading, time
            client = wsg.text.Client.connect({sim.address!r})
            client.home()
            threading.Thread(target=lambda held=client: time.sleep(1000), daemon=True).start()
            """
        )
        assert child.returncode == 0, child.stderr
        wait_until(lambda: sim.snapshot().sessions == 0)
        assert wsg.SystemState.FAST_STOP not in sim.snapshot().system_state


def test_a_griplink_client_left_open_says_bye_at_exit(griplink_relay: Relay) -> None:
    child = run_child(
        f"""
        from gripper_rs import griplink
        import threading, time
        client = griplink.Client.connect({griplink_relay.address!r})
        client.id()
        threading.Thread(target=lambda held=client: time.sleep(1000), daemon=True).start()
        """
    )
    assert child.returncode == 0, child.stderr
    # The controller's disconnect announcement (BYE), sent once before the socket closed.
    wait_until(lambda: b"BYE()\n" in griplink_relay.sent)
    assert griplink_relay.sent.count(b"BYE()\n") == 1


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform")
def test_a_forked_child_gets_a_clear_error_not_a_hang(wsg_client: wsg.Client) -> None:
    wsg_client.width_mm()  # the runtime is running in this process
    pid = os.fork()
    if pid == 0:  # the child: never returns into pytest
        code = 3
        try:
            wsg_client.width_mm()
            code = 1
        except gripper_rs.GripperError as e:
            code = 0 if "fork" in str(e) else 2
        finally:
            os._exit(code)
    deadline = time.monotonic() + 10.0
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        if time.monotonic() > deadline:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            pytest.fail("the forked child hung on the client call")
        time.sleep(0.01)
    assert os.waitstatus_to_exitcode(status) == 0
    assert isinstance(wsg_client.width_mm(), float)  # the parent's client is unaffected


def test_version() -> None:
    cargo = (Path(__file__).parents[1] / "Cargo.toml").read_text()
    match = re.search(r'^version = "([^"]+)"', cargo, re.M)
    assert match is not None
    assert gripper_rs.__version__ == match.group(1)
    try:
        installed = importlib.metadata.version("gripper-rs")
    except importlib.metadata.PackageNotFoundError:
        return  # a source checkout on sys.path (CI tests the installed wheel)
    assert installed == gripper_rs.__version__

