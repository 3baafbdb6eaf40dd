"""GRIPLINK grip: an IEG 55-020 on port 0 of a GRIPLINK-ET4 grips a 12 mm part with recipe 1 and
releases it.

Runs against an in-process simulated controller by default; ``--address host:port`` for a real
one.
"""

from __future__ import annotations

import argparse
import contextlib

from gripper_rs import griplink


def grip(address: str) -> None:
    with griplink.Client.connect(address) as controller:
        controller.protocol_assert("GRIPLINK", 3)
        print("controller:", controller.id(), controller.version())
        port = controller.port(0)
        print("port 0:", port.name(), "state", port.state().name)
        port.home()
        # Recipe 1: no-part limit 5 mm, release limit 18 mm, 50 % force.
        port.set_grip_config_f(1, "part", [5.0, 18.0, 50.0, 0.0, 0.0, 0.0, 0.0, 0.0])
        outcome = port.grip_and_wait(1, poll_interval_s=0.01)
        print(f"grip: {outcome.name} at {port.position_mm():.2f} mm")
        if outcome is not griplink.GripOutcome.HOLDING:
            raise SystemExit(f"grip ended {outcome.name}")
        print("release:", port.release_and_wait(1).name)
    # Leaving `with` sent BYE.


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--address", help="a real controller's host:port (default: a simulator)")
    args = parser.parse_args()
    with contextlib.ExitStack() as stack:
        address: str | None = args.address
        if address is None:
            sim = stack.enter_context(griplink.sim.SimServer(parts={0: 12.0}, time_scale=0.05))
            address = sim.address
        grip(address)


if __name__ == "__main__":
    main()
