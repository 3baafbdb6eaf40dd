"""What wsg.launch.py, griplink.launch.py and smartgrasp.launch.py share (not a launch file;
its name is its own, since the launch files put this directory on sys.path).

Each launch file declares the arguments below and starts, in the namespace `namespace`:
- the node `gripper` (executable gripper-ros2 of package gripper_ros2), with `--sim DEVICE`
  when `sim` is true (`--sim wsg:MODEL` for a WSG, the description's model), the parameter file `params_file` (default: config/DEVICE.yaml), and
  `address` when given; for a gripper, `joint_names` are the description's joints with `prefix`,
  for the Grasping-Kit `frame_id` is `prefix` + grasping_kit;
- for a gripper, robot_state_publisher with the description (urdf/DEVICE.urdf.xacro expanded
  with `prefix` and the device's own arguments), which reads the node's joint_states.
"""

import os

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

# share/gripper_ros2 when installed, ros2/ in the source tree.
SHARE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE = "gripper_ros2"
EXECUTABLE = "gripper-ros2"
NODE_NAME = "gripper"
# The finger joints of the shipped description (urdf/parallel_gripper.xacro), as the node names
# them by default (ros2/src/joint_map.rs).
FINGER_JOINTS = ("base_joint_gripper_left", "base_joint_gripper_right")


def common_arguments(device, address_help):
    """The arguments every launch file declares."""
    return [
        DeclareLaunchArgument(
            "sim", default_value="false",
            description=f"true: the node starts its own {device} simulator (address ignored)"),
        DeclareLaunchArgument(
            "namespace", default_value="", description="namespace of the nodes, e.g. left"),
        DeclareLaunchArgument(
            "prefix", default_value="",
            description="put before the description's link and joint names, e.g. left_"),
        DeclareLaunchArgument("address", default_value="", description=address_help),
        DeclareLaunchArgument(
            "params_file", default_value=os.path.join(SHARE, "config", f"{device}.yaml"),
            description="the node's parameter file"),
    ]


def is_true(text):
    """A launch argument as a boolean, as launch's own conditions read it."""
    value = text.strip().lower()
    if value in ("true", "1"):
        return True
    if value in ("false", "0"):
        return False
    raise ValueError(f"sim must be true or false, not {text!r}")


def expand_description(device, mappings):
    """The URDF of urdf/DEVICE.urdf.xacro with the xacro arguments `mappings`."""
    import xacro  # the ROS package xacro (pip install xacro outside ROS)

    path = os.path.join(SHARE, "urdf", f"{device}.urdf.xacro")
    return xacro.process_file(path, mappings=mappings).toxml()


def sim_device(device, arg):
    """The node's `--sim` value: a WSG simulated as the model its description gives (its
    stroke then is the description's joint limits), any other device as itself."""
    return f"wsg:{arg('model')}" if device == "wsg" else device


def nodes(context, device, description_args):
    """The nodes, once the arguments are known. `description_args`: the xacro arguments
    besides prefix (launch argument names), or None for a device without a description."""
    arg = lambda name: LaunchConfiguration(name).perform(context)  # noqa: E731
    prefix = arg("prefix")
    namespace = arg("namespace")
    params = {}
    if arg("address"):
        params["address"] = arg("address")
    if description_args is None:
        params["frame_id"] = prefix + "grasping_kit"
    else:
        params["joint_names"] = [prefix + joint for joint in FINGER_JOINTS]
    out = [
        Node(
            package=PACKAGE, executable=EXECUTABLE, name=NODE_NAME, namespace=namespace,
            arguments=["--sim", sim_device(device, arg)] if is_true(arg("sim")) else [],
            parameters=[arg("params_file"), params], output="screen"),
    ]
    if description_args is not None:
        mappings = {"prefix": prefix}
        mappings.update({name: arg(name) for name in description_args})
        out.append(
            Node(
                package="robot_state_publisher", executable="robot_state_publisher",
                namespace=namespace, output="screen",
                parameters=[{"robot_description": expand_description(device, mappings)}]))
    return out


def launch_description(device, address_help, description_args=None):
    """The LaunchDescription of one device kind. `description_args`: the description's own
    xacro arguments, {name: (default, help, choices or None)}, declared as launch arguments too;
    None for a device without a description."""
    own = [
        DeclareLaunchArgument(name, default_value=default, description=help, choices=choices)
        for name, (default, help, choices) in (description_args or {}).items()
    ]
    return LaunchDescription([
        *common_arguments(device, address_help),
        *own,
        OpaqueFunction(
            function=nodes,
            args=[device, None if description_args is None else list(description_args)]),
    ])
