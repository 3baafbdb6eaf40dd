"""WSG pick: home, pre-position, grasp a 40 mm part, check it is held, release.

Runs against an in-process simulated WSG 50 by default; with ``--address host:port`` against a
real gripper (make sure nothing is in the fingers' way).
"""

from __future__ import annotations

import argparse
import contextlib

from gripper_rs import wsg


def pick(address: str) -> None:
    with wsg.Client.connect_tcp(address) as gripper:
        print("gripper:", gripper.system_info())
        gripper.home()
        gripper.pre_position(60.0, 100.0)
        gripper.grasp(40.0, 50.0)
        state = gripper.grip_state()
        print(f"grip state {state.name}, width {gripper.width_mm():.1f} mm")
        if state is not wsg.GripState.HOLDING:
            raise SystemExit(f"no part: the grip state is {state.name}")
        gripper.release(60.0, 100.0)
        print("released at", gripper.width_mm(), "mm")
    # Leaving `with` announced the disconnect (0x07): the gripper does not FAST STOP.


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--address", help="a real gripper's host:port (default: a simulator)")
    args = parser.parse_args()
    with contextlib.ExitStack() as stack:
        address: str | None = args.address
        if address is None:
            sim = stack.enter_context(wsg.sim.SimServer(part_width_mm=40.0, time_scale=0.01))
            address = sim.address
        pick(address)


if __name__ == "__main__":
    main()
