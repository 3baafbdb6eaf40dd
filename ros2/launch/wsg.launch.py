"""A Weiss WSG 50, 32 or 25: gripper-ros2 and robot_state_publisher with urdf/wsg.urdf.xacro.

    ros2 launch gripper_ros2 wsg.launch.py sim:=true
    ros2 launch gripper_ros2 wsg.launch.py address:=192.168.1.20:1000 model:=32 prefix:=left_

Arguments: sim, namespace, prefix, address, params_file (launch/gripper_ros2_common.py) and model.
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gripper_ros2_common as common  # noqa: E402  (beside this file, installed with it)


def generate_launch_description():
    return common.launch_description(
        "wsg",
        address_help="HOST:PORT of the WSG over TCP (its port is 1000 by default)",
        description_args={
            "model": ("50", "the WSG model, for the description's stroke", ["50", "32", "25"]),
        },
    )
