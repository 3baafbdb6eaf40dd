"""Grasping-Kit loop: ask for grasps of object class 1 until the bin is empty (or 10 picks),
giving feedback after each.

Runs against an in-process simulated Grasping-Kit (its demo bin) by default; ``--address
host:port`` for a real one.
"""

from __future__ import annotations

import argparse
import contextlib

from gripper_rs import smartgrasp
from gripper_rs.smartgrasp import GetGraspOutcome, GraspMode, PoseFormat, RobotSystem, Tool


def loop(address: str, picks: int) -> None:
    with smartgrasp.Client.connect(address, robot_system=RobotSystem.UR) as kit:
        print("server state:", kit.get_state().name)
        for n in range(picks):
            result = kit.get_grasp(GraspMode.ACTIVE_GRASP, 1, Tool.EXTERIOR, PoseFormat.QUATERNION)
            if result.grasp is None:
                print("no more grasps:", result.outcome.name)
                break
            g = result.grasp
            print(
                f"pick {n + 1}: object {g.object_instance} at {g.pose.position_m} m, "
                f"stroke {g.stroke_mm:.1f} mm ({g.object_count} objects left)"
            )
            # A real cell moves the robot and grips here; the simulator just takes the answer.
            kit.grasp_feedback(True)
        if result.outcome is GetGraspOutcome.INVALID_OBJECT_CLASS:
            raise SystemExit("object class 1 is not in the project")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--address", help="a real Grasping-Kit's host:port (default: a simulator)")
    parser.add_argument("--picks", type=int, default=10)
    args = parser.parse_args()
    with contextlib.ExitStack() as stack:
        address: str | None = args.address
        if address is None:
            address = stack.enter_context(smartgrasp.sim.SimServer()).address
        loop(address, args.picks)


if __name__ == "__main__":
    main()
