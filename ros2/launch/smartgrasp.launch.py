"""The SCHUNK 2D Grasping-Kit: gripper-ros2 alone (the kit is a camera and its grasp planner;
it has no joints to describe). `prefix` goes before the frame of the grasp poses.

    ros2 launch gripper_ros2 smartgrasp.launch.py sim:=true
    ros2 launch gripper_ros2 smartgrasp.launch.py address:=192.168.1.50:42001

Arguments: sim, namespace, prefix, address, params_file (launch/gripper_ros2_common.py).
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gripper_ros2_common as common  # noqa: E402  (beside this file, installed with it)


def generate_launch_description():
    return common.launch_description(
        "smartgrasp",
        address_help="HOST:PORT of the Grasping-Kit (its port is 42001 by default)",
        description_args=None,
    )
