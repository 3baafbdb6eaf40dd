"""A gripper on a Weiss GRIPLINK port: gripper-ros2 and robot_state_publisher with
urdf/griplink.urdf.xacro.

    ros2 launch gripper_ros2 griplink.launch.py sim:=true
    ros2 launch gripper_ros2 griplink.launch.py address:=192.168.1.40:10001 stroke:=0.085

Arguments: sim, namespace, prefix, address, params_file (launch/gripper_ros2_common.py) and stroke (m).
The port is the griplink_port parameter (config/griplink.yaml).
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gripper_ros2_common as common  # noqa: E402  (beside this file, installed with it)


def generate_launch_description():
    return common.launch_description(
        "griplink",
        address_help="HOST:PORT of the GRIPLINK controller (its port is 10001 by default)",
        description_args={
            "stroke": ("0.020", "the gripper's full stroke, m (0.020: the simulator's IEG 55-020)",
                       None),
        },
    )
