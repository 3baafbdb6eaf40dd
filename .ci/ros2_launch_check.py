"""Checks the installed ROS package gripper_ros2 where no ROS distribution can be installed
(Debian has colcon and ament_cmake, not launch, launch_ros or robot_state_publisher).

For each launch file (share/gripper_ros2/launch/*.launch.py):
- it imports and builds its LaunchDescription against a recording stand-in of the few launch
  and launch_ros classes it uses (below): this checks the file's Python and that it declares
  the arguments sim, namespace, prefix and address (and its device's own), not that ROS's launch
  would run it;
- its nodes are resolved for a few argument sets, as `ros2 launch ... sim:=true prefix:=left_`
  would; the node's executable must be installed in lib/gripper_ros2/, its parameter file in
  share/gripper_ros2/config/;
- the description it gives robot_state_publisher is expanded with the real xacro (PyPI),
  checked by urdfdom's check_urdf, and every joint name the node is given must be a movable
  joint of it, and every movable joint one the node publishes (robot_state_publisher publishes
  no transform for a joint without a state);
- the installed node is started with the command line launch_ros builds from the Node
  (arguments, then --ros-args with the name, the namespace and the parameter files, the dict as
  a `/**` file, as launch_ros writes it), on loopback and a ROS domain of its own; it must come
  up ("ready:") and stop cleanly on SIGINT: the node accepts everything the launch file passes.

Usage: ros2_launch_check.py INSTALL_PREFIX   (the colcon install folder of gripper_ros2)
"""

import os
import signal
import subprocess
import sys
import tempfile
import time
import types
import xml.etree.ElementTree as ET

import xacro  # noqa: F401  (imported by the launch files' helper; fail early if missing)
import yaml

failures = []
passed = [0]


def check(ok, what):
    """Counts a check; prints only a failure (a scenario's line says what passed)."""
    if ok:
        passed[0] += 1
    else:
        print("FAILED " + what)
        failures.append(what)
    return ok


# ---- the stand-in of launch / launch_ros: records what the launch files build ---------------


class LaunchDescription:
    def __init__(self, entities):
        self.entities = list(entities)


class DeclareLaunchArgument:
    def __init__(self, name, default_value=None, description="", choices=None):
        self.name, self.default_value = name, default_value
        self.description, self.choices = description, choices


class OpaqueFunction:
    def __init__(self, function, args=None, kwargs=None):
        self.function, self.args, self.kwargs = function, args or [], kwargs or {}


class LaunchConfiguration:
    def __init__(self, name):
        self.name = name

    def perform(self, context):
        return context.launch_configurations[self.name]


class Node:
    def __init__(self, package, executable, name=None, namespace=None, arguments=None,
                 parameters=None, output=None, condition=None):
        self.package, self.executable, self.name = package, executable, name
        self.namespace, self.arguments = namespace, list(arguments or [])
        self.parameters = list(parameters or [])


class Context:
    def __init__(self, launch_configurations):
        self.launch_configurations = launch_configurations


def install_stand_in():
    modules = {
        "launch": {"LaunchDescription": LaunchDescription},
        "launch.actions": {
            "DeclareLaunchArgument": DeclareLaunchArgument, "OpaqueFunction": OpaqueFunction,
        },
        "launch.substitutions": {"LaunchConfiguration": LaunchConfiguration},
        "launch_ros": {},
        "launch_ros.actions": {"Node": Node},
    }
    for name, attrs in modules.items():
        module = types.ModuleType(name)
        module.__dict__.update(attrs)
        sys.modules[name] = module


def load(path):
    import importlib.util

    spec = importlib.util.spec_from_file_location(os.path.basename(path)[:-3], path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.generate_launch_description()


# ---- the checks ------------------------------------------------------------------------------


def movable_joints(urdf_text):
    root = ET.fromstring(urdf_text)
    return {j.get("name"): j for j in root.iter("joint") if j.get("type") != "fixed"}


def launch_ros_command(node, prefix, tmp):
    """The command line launch_ros gives a Node: the executable, its arguments, then
    --ros-args with the name, the namespace (absolute; "" is the root) and each parameter
    source in order, a dict written as a `/**` parameter file."""
    exe = os.path.join(prefix, "lib", node.package, node.executable)
    cmd = [exe, *node.arguments, "--ros-args", "-r", f"__node:={node.name}"]
    ns = node.namespace or ""
    cmd += ["-r", "__ns:=" + (ns if ns.startswith("/") else "/" + ns)]
    for i, p in enumerate(node.parameters):
        if isinstance(p, dict):
            path = os.path.join(tmp, f"launch_params_{i}.yaml")
            with open(path, "w") as f:
                yaml.safe_dump({"/**": {"ros__parameters": p}}, f)
            p = path
        cmd += ["--params-file", p]
    return cmd


def run_node(cmd, label):
    """Starts the node on loopback and a ROS domain of its own; True when it said ready and
    stopped with status 0 on SIGINT."""
    domain = 1 + (os.getpid() + hash(label)) % 232
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
    # Loopback only: nothing leaves this machine.
    cmd = cmd + ["-p", "dds_interfaces:=[127.0.0.1]"]
    with tempfile.TemporaryFile("w+") as log:
        proc = subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + 60
        ready = False
        while time.monotonic() < deadline and proc.poll() is None:
            log.seek(0)
            if "ready:" in log.read():
                ready = True
                break
            time.sleep(0.1)
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        try:
            code = proc.wait(20)
        except subprocess.TimeoutExpired:
            proc.kill()
            code = proc.wait()
        log.seek(0)
        text = log.read()
    ok = check(ready and code == 0, f"{label}: the node came up and stopped cleanly (exit {code})")
    if not ok:
        print(f"  command: {' '.join(cmd)}\n" + "".join(f"  | {l}\n" for l in text.splitlines()))


def check_launch_file(prefix, device, own_args, scenarios):
    share = os.path.join(prefix, "share", "gripper_ros2")
    path = os.path.join(share, "launch", f"{device}.launch.py")
    ld = load(path)
    declared = {e.name: e for e in ld.entities if isinstance(e, DeclareLaunchArgument)}
    wanted = {"sim", "namespace", "prefix", "address", *own_args}
    check(wanted <= set(declared), f"{device}.launch.py declares {sorted(wanted)}")
    opaque = [e for e in ld.entities if isinstance(e, OpaqueFunction)]
    if not check(len(opaque) == 1, f"{device}.launch.py resolves its nodes in one function"):
        return
    for overrides in scenarios:
        label = f"{device}.launch.py " + " ".join(f"{k}:={v}" for k, v in overrides.items())
        configs = {name: arg.default_value for name, arg in declared.items()}
        configs.update(overrides)
        nodes = opaque[0].function(Context(configs), *opaque[0].args, **opaque[0].kwargs)
        grippers = [n for n in nodes if n.package == "gripper_ros2"]
        if not check(len(grippers) == 1, f"{label}: one gripper-ros2 node"):
            continue
        node = grippers[0]
        exe = os.path.join(prefix, "lib", node.package, node.executable)
        check(os.access(exe, os.X_OK), f"{label}: {exe} is installed and executable")
        files = [p for p in node.parameters if isinstance(p, str)]
        check(all(os.path.isfile(p) for p in files) and files,
              f"{label}: parameter file {files} installed")
        check(node.namespace == overrides.get("namespace", ""), f"{label}: namespace")
        # A WSG is simulated as the model its description gives (the joint limits' stroke).
        sim = f"wsg:{configs['model']}" if device == "wsg" else device
        check(node.arguments == (["--sim", sim] if overrides.get("sim") == "true" else []),
              f"{label}: arguments {node.arguments}")
        given = {}
        for p in node.parameters:
            given.update(p if isinstance(p, dict) else {})
        rsp = [n for n in nodes if n.package == "robot_state_publisher"]
        if "joint_names" in given:
            if not check(len(rsp) == 1, f"{label}: one robot_state_publisher"):
                continue
            check(rsp[0].namespace == node.namespace, f"{label}: robot_state_publisher beside it")
            urdf = rsp[0].parameters[0]["robot_description"]
            with tempfile.NamedTemporaryFile("w", suffix=".urdf") as f:
                f.write(urdf)
                f.flush()
                parsed = subprocess.run(["check_urdf", f.name], capture_output=True, text=True)
            check(parsed.returncode == 0, f"{label}: check_urdf parses the description")
            joints = movable_joints(urdf)
            names = given["joint_names"]
            check(set(names) == set(joints),
                  f"{label}: the node's joint_names {names} are the description's movable "
                  f"joints {sorted(joints)}")
            p = overrides.get("prefix", "")
            check(all(n.startswith(p) for n in names), f"{label}: joint names carry the prefix")
        else:
            check(not rsp, f"{label}: no description (nothing to describe)")
            check(given.get("frame_id") == overrides.get("prefix", "") + "grasping_kit",
                  f"{label}: frame_id carries the prefix")
        if overrides.get("sim") == "true":
            with tempfile.TemporaryDirectory() as tmp:
                run_node(launch_ros_command(node, prefix, tmp), label)
        print(f"checked {label}: {', '.join(sorted(given))} given; "
              f"{'node started and stopped' if overrides.get('sim') == 'true' else 'not started'}")


def main():
    if len(sys.argv) != 2:
        raise SystemExit(__doc__)
    prefix = sys.argv[1]
    install_stand_in()
    scenarios = lambda own: [  # noqa: E731
        {"sim": "true"},
        {"sim": "true", "namespace": "left", "prefix": "left_", **own},
        {"sim": "false", "address": "192.0.2.1:1000", "prefix": "right_"},
    ]
    check_launch_file(prefix, "wsg", ["model"], scenarios({"model": "32"}))
    check_launch_file(prefix, "griplink", ["stroke"], scenarios({"stroke": "0.085"}))
    check_launch_file(prefix, "smartgrasp", [], scenarios({}))
    print(f"launch-check: {passed[0]} passed, {len(failures)} failed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
