"""An independent ROS 2 peer for `gripper-ros2`: Eclipse Cyclone DDS (the DDS under
rmw_cyclonedds_cpp), with the ROS 2 types written here in IDL, and no ROS installation.

Starts `gripper-ros2 --sim wsg` on a domain of its own, on loopback only, with no
RMW_IMPLEMENTATION (the node answers each peer in its own request/reply mapping: this one's is
Cyclone's), then checks over plain DDS what a ROS 2 client would see:
joint_states and diagnostics with the ROS type names; the ~/home service
(rq/gripper/homeRequest, rr/gripper/homeReply); GripperCommand goals through
_action/send_goal and _action/get_result (an opening in metres is reached, a close on a part
ends stalled with effort); a slow goal cancelled through _action/cancel_goal, and the
simulator's log shows the stop. Every joint_states sample from homing to the end is read: each
name must be a movable joint of the description URDF (the node's defaults against the package's
urdf/wsg.urdf.xacro, expanded by the caller) and each position within that joint's limits.
Every wait is bounded. Usage: ros2_peer.py PATH/TO/gripper-ros2 PATH/TO/wsg.urdf
"""

import os
import random
import signal
import subprocess
import sys
import tempfile
import threading
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl import types as t
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

# ---- ROS 2 types (Jazzy), as rosidl maps them to DDS --------------------------------------


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: t.int32
    nanosec: t.uint32


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time
    frame_id: str


@dataclass
class JointState(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    header: Header
    name: t.sequence[str]
    position: t.sequence[t.float64]
    velocity: t.sequence[t.float64]
    effort: t.sequence[t.float64]


@dataclass
class KeyValue(IdlStruct, typename="diagnostic_msgs::msg::dds_::KeyValue_"):
    key: str
    value: str


@dataclass
class DiagnosticStatus(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticStatus_"):
    level: t.uint8
    name: str
    message: str
    hardware_id: str
    values: t.sequence[KeyValue]


@dataclass
class DiagnosticArray(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticArray_"):
    header: Header
    status: t.sequence[DiagnosticStatus]


# rmw_cyclonedds_cpp puts a request header before each request and reply: the client's
# 64-bit id and the request's sequence number (16 bytes).


@dataclass
class TriggerRequest(IdlStruct, typename="std_srvs::srv::dds_::Trigger_Request_"):
    client_id: t.uint64
    seq: t.int64
    structure_needs_at_least_one_member: t.uint8


@dataclass
class TriggerReply(IdlStruct, typename="std_srvs::srv::dds_::Trigger_Response_"):
    client_id: t.uint64
    seq: t.int64
    success: bool
    message: str


@dataclass
class UUID(IdlStruct, typename="unique_identifier_msgs::msg::dds_::UUID_"):
    uuid: t.array[t.uint8, 16]


@dataclass
class GripperCommand(IdlStruct, typename="control_msgs::msg::dds_::GripperCommand_"):
    position: t.float64
    max_effort: t.float64


@dataclass
class Goal(IdlStruct, typename="control_msgs::action::dds_::GripperCommand_Goal_"):
    command: GripperCommand


@dataclass
class Result(IdlStruct, typename="control_msgs::action::dds_::GripperCommand_Result_"):
    position: t.float64
    effort: t.float64
    stalled: bool
    reached_goal: bool


@dataclass
class SendGoalRequest(
    IdlStruct, typename="control_msgs::action::dds_::GripperCommand_SendGoal_Request_"
):
    client_id: t.uint64
    seq: t.int64
    goal_id: UUID
    goal: Goal


@dataclass
class SendGoalReply(
    IdlStruct, typename="control_msgs::action::dds_::GripperCommand_SendGoal_Response_"
):
    client_id: t.uint64
    seq: t.int64
    accepted: bool
    stamp: Time


@dataclass
class GetResultRequest(
    IdlStruct, typename="control_msgs::action::dds_::GripperCommand_GetResult_Request_"
):
    client_id: t.uint64
    seq: t.int64
    goal_id: UUID


@dataclass
class GetResultReply(
    IdlStruct, typename="control_msgs::action::dds_::GripperCommand_GetResult_Response_"
):
    client_id: t.uint64
    seq: t.int64
    status: t.int8
    result: Result


@dataclass
class GoalInfo(IdlStruct, typename="action_msgs::msg::dds_::GoalInfo_"):
    goal_id: UUID
    stamp: Time


@dataclass
class CancelRequest(IdlStruct, typename="action_msgs::srv::dds_::CancelGoal_Request_"):
    client_id: t.uint64
    seq: t.int64
    goal_info: GoalInfo


@dataclass
class CancelReply(IdlStruct, typename="action_msgs::srv::dds_::CancelGoal_Response_"):
    client_id: t.uint64
    seq: t.int64
    return_code: t.int8
    goals_canceling: t.sequence[GoalInfo]


# rcl_interfaces (parameters and the log), as rosidl maps them.


@dataclass
class ParameterValue(IdlStruct, typename="rcl_interfaces::msg::dds_::ParameterValue_"):
    type: t.uint8
    bool_value: bool
    integer_value: t.int64
    double_value: t.float64
    string_value: str
    byte_array_value: t.sequence[t.uint8]
    bool_array_value: t.sequence[bool]
    integer_array_value: t.sequence[t.int64]
    double_array_value: t.sequence[t.float64]
    string_array_value: t.sequence[str]


def bool_value(b):
    return ParameterValue(1, b, 0, 0.0, "", [], [], [], [], [])


def double_value(x):
    return ParameterValue(3, False, 0, x, "", [], [], [], [], [])


@dataclass
class Parameter(IdlStruct, typename="rcl_interfaces::msg::dds_::Parameter_"):
    name: str
    value: ParameterValue


@dataclass
class SetParametersResult(IdlStruct, typename="rcl_interfaces::msg::dds_::SetParametersResult_"):
    successful: bool
    reason: str


@dataclass
class FloatingPointRange(IdlStruct, typename="rcl_interfaces::msg::dds_::FloatingPointRange_"):
    from_value: t.float64
    to_value: t.float64
    step: t.float64


@dataclass
class IntegerRange(IdlStruct, typename="rcl_interfaces::msg::dds_::IntegerRange_"):
    from_value: t.int64
    to_value: t.int64
    step: t.uint64


@dataclass
class ParameterDescriptor(IdlStruct, typename="rcl_interfaces::msg::dds_::ParameterDescriptor_"):
    name: str
    type: t.uint8
    description: str
    additional_constraints: str
    read_only: bool
    dynamic_typing: bool
    floating_point_range: t.sequence[FloatingPointRange]
    integer_range: t.sequence[IntegerRange]


@dataclass
class ListParametersResult(IdlStruct, typename="rcl_interfaces::msg::dds_::ListParametersResult_"):
    names: t.sequence[str]
    prefixes: t.sequence[str]


@dataclass
class ListParametersRequest(
    IdlStruct, typename="rcl_interfaces::srv::dds_::ListParameters_Request_"
):
    client_id: t.uint64
    seq: t.int64
    prefixes: t.sequence[str]
    depth: t.uint64


@dataclass
class ListParametersReply(
    IdlStruct, typename="rcl_interfaces::srv::dds_::ListParameters_Response_"
):
    client_id: t.uint64
    seq: t.int64
    result: ListParametersResult


@dataclass
class GetParametersRequest(IdlStruct, typename="rcl_interfaces::srv::dds_::GetParameters_Request_"):
    client_id: t.uint64
    seq: t.int64
    names: t.sequence[str]


@dataclass
class GetParametersReply(IdlStruct, typename="rcl_interfaces::srv::dds_::GetParameters_Response_"):
    client_id: t.uint64
    seq: t.int64
    values: t.sequence[ParameterValue]


@dataclass
class SetParametersRequest(IdlStruct, typename="rcl_interfaces::srv::dds_::SetParameters_Request_"):
    client_id: t.uint64
    seq: t.int64
    parameters: t.sequence[Parameter]


@dataclass
class SetParametersReply(IdlStruct, typename="rcl_interfaces::srv::dds_::SetParameters_Response_"):
    client_id: t.uint64
    seq: t.int64
    results: t.sequence[SetParametersResult]


@dataclass
class DescribeParametersRequest(
    IdlStruct, typename="rcl_interfaces::srv::dds_::DescribeParameters_Request_"
):
    client_id: t.uint64
    seq: t.int64
    names: t.sequence[str]


@dataclass
class DescribeParametersReply(
    IdlStruct, typename="rcl_interfaces::srv::dds_::DescribeParameters_Response_"
):
    client_id: t.uint64
    seq: t.int64
    descriptors: t.sequence[ParameterDescriptor]


@dataclass
class ParameterEvent(IdlStruct, typename="rcl_interfaces::msg::dds_::ParameterEvent_"):
    stamp: Time
    node: str
    new_parameters: t.sequence[Parameter]
    changed_parameters: t.sequence[Parameter]
    deleted_parameters: t.sequence[Parameter]


@dataclass
class Log(IdlStruct, typename="rcl_interfaces::msg::dds_::Log_"):
    stamp: Time
    level: t.uint8
    name: str
    msg: str
    file: str
    function: str
    line: t.uint32


SUCCEEDED, ABORTED, CANCELED = 4, 6, 5
# The node's default joint names: the finger joints of the description it ships (ros2/urdf/).
JOINTS = ["base_joint_gripper_left", "base_joint_gripper_right"]
# Where the peer has the node publish them (a remap, as launch files do).
JOINT_STATES = "rt/arm/joint_states"
RELIABLE = Qos(
    Policy.Reliability.Reliable(duration(seconds=1)),
    Policy.History.KeepLast(10),
    # XCDR1, as every ROS 2 RMW writes it.
    Policy.DataRepresentation(use_cdrv0_representation=True),
)
WAIT_S = 30.0


def fail(msg):
    raise SystemExit(f"ros2 peer: FAILED: {msg}")


PASSED = []


def ok(msg):
    PASSED.append(msg)
    print(f"ros2 peer: ok {msg}")


class Service:
    """A client of one service with the Cyclone request/reply mapping."""

    def __init__(self, dp, name, req_type, rep_type):
        self.writer = DataWriter(dp, Topic(dp, f"rq/{name}Request", req_type), qos=RELIABLE)
        self.reader = DataReader(dp, Topic(dp, f"rr/{name}Reply", rep_type), qos=RELIABLE)
        self.client_id = random.getrandbits(63)
        self.seq = 0
        self.name = name

    def call(self, make, timeout=WAIT_S, attempt_s=None):
        """Sends a request and returns its reply. With `attempt_s`, the request is sent again
        after each `attempt_s` without a reply: only for requests that may be repeated. The
        node's reply writer may not have discovered our reader yet when we discovered it, and a
        reply sent before then is lost (volatile QoS)."""
        deadline = time.monotonic() + WAIT_S
        # Both directions must be matched on our side first.
        while (
            self.writer.get_publication_matched_status().current_count == 0
            or self.reader.get_subscription_matched_status().current_count == 0
        ):
            if time.monotonic() > deadline:
                fail(f"{self.name}: the node's service was not discovered")
            time.sleep(0.05)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.seq += 1
            self.writer.write(make(self.client_id, self.seq))
            retry_at = time.monotonic() + (attempt_s or timeout)
            while time.monotonic() < min(deadline, retry_at):
                for reply in self.reader.take(N=16):
                    if reply.client_id == self.client_id and reply.seq == self.seq:
                        return reply
                time.sleep(0.02)
            if attempt_s is None:
                break
        fail(f"{self.name}: no reply within {timeout} s")


def first_sample(reader, what, check):
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        for s in reader.take(N=16):
            if check(s):
                return s
        time.sleep(0.05)
    fail(f"no {what} within {WAIT_S} s")


def cyclone_config(domain):
    # Loopback only, no multicast: nothing leaves this machine, and parallel runs on other
    # domains do not meet.
    return (
        f'<CycloneDDS><Domain Id="{domain}"><General><Interfaces>'
        '<NetworkInterface address="127.0.0.1"/></Interfaces>'
        "<AllowMulticast>false</AllowMulticast></General>"
        "<Discovery><ParticipantIndex>auto</ParticipantIndex>"
        "<MaxAutoParticipantIndex>20</MaxAutoParticipantIndex>"
        '<Peers><Peer address="127.0.0.1"/></Peers></Discovery></Domain></CycloneDDS>'
    )


def joint_limits(urdf_path):
    """{name: (lower, upper)} of the description's movable joints."""
    limits = {}
    for j in ET.parse(urdf_path).getroot().iter("joint"):
        if j.get("type") in ("prismatic", "revolute"):
            lim = j.find("limit")
            limits[j.get("name")] = (float(lim.get("lower")), float(lim.get("upper")))
        elif j.get("type") != "fixed":
            limits[j.get("name")] = (float("-inf"), float("inf"))
    return limits


class JointStateRecorder(threading.Thread):
    """Takes every joint_states sample (a reader of its own, drained every 10 ms: at 50 Hz
    its history of 10 never overflows) until stopped."""

    def __init__(self, dp):
        super().__init__(daemon=True)
        self.reader = DataReader(dp, Topic(dp, JOINT_STATES, JointState), qos=RELIABLE)
        self.samples = []
        self.done = threading.Event()

    def run(self):
        while not self.done.is_set():
            for s in self.reader.take(N=64):
                self.samples.append((list(s.name), list(s.position)))
            time.sleep(0.01)

    def stop(self):
        self.done.set()
        self.join(5)


def check_against_description(samples, limits):
    """Every published name is a movable joint of the description, every position within its
    limits; and the samples saw the grasp (the fingers on the 40 mm part) and an opening of
    70 mm or more, so that the check covered the motion."""
    if len(samples) < 20:
        fail(f"only {len(samples)} joint_states samples recorded")
    widths = []
    for names, positions in samples:
        unknown = [n for n in names if n not in limits]
        if unknown:
            fail(f"joint_states names {unknown}, not joints of the description {sorted(limits)}")
        for n, p in zip(names, positions):
            lower, upper = limits[n]
            if not lower <= p <= upper:
                fail(f"{n} at {p}, outside its limits [{lower}, {upper}]")
        pos = dict(zip(names, positions))
        widths.append(pos[JOINTS[1]] - pos[JOINTS[0]])
    if min(widths) > 0.041 or max(widths) < 0.07:
        fail(f"the samples span openings {min(widths)}..{max(widths)} m: not the grasp and opening")
    ok(f"{len(samples)} joint_states samples, openings {min(widths):.4f}.."
       f"{max(widths):.4f} m: every name a joint of the description, every position within "
       "its limits")


def cyclone_config(domain):
    # Loopback only, no multicast: nothing leaves this machine, and parallel runs on other
    # domains do not meet.
    return (
        f'<CycloneDDS><Domain Id="{domain}"><General><Interfaces>'
        '<NetworkInterface address="127.0.0.1"/></Interfaces>'
        "<AllowMulticast>false</AllowMulticast></General>"
        "<Discovery><ParticipantIndex>auto</ParticipantIndex>"
        "<MaxAutoParticipantIndex>20</MaxAutoParticipantIndex>"
        '<Peers><Peer address="127.0.0.1"/></Peers></Discovery></Domain></CycloneDDS>'
    )


def main():
    binary, urdf = sys.argv[1], sys.argv[2]
    limits = joint_limits(urdf)
    # A domain of its own (0..=232), from the process id.
    domain = 1 + os.getpid() % 232
    os.environ["CYCLONEDDS_URI"] = cyclone_config(domain)
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
    env.pop("RMW_IMPLEMENTATION", None)
    log = tempfile.NamedTemporaryFile("w+", prefix="gripper-ros2-", suffix=".log", delete=False)
    node = subprocess.Popen(
        [binary, "--sim", "wsg", "--ros-args", "-p", "dds_interfaces:=[127.0.0.1]",
         "-p", "speed_m_per_s:=0.02", "-p", "allow_stalling:=true",
         # As a launch file remaps a topic; and what rclcpp accepts must not stop the node.
         "-r", "joint_states:=/arm/joint_states", "-p", "use_sim_time:=false",
         "-p", "not_ours:=1", "--log-level", "info"],
        env=env, stdout=log, stderr=subprocess.STDOUT,
    )
    try:
        run_checks(domain, log, limits)
    except BaseException:
        node.kill()
        node.wait(10)
        log.seek(0)
        print("---- the node's log ----\n" + log.read(), file=sys.stderr)
        raise
    node.send_signal(signal.SIGINT)
    try:
        code = node.wait(15)
    except subprocess.TimeoutExpired:
        node.kill()
        fail("the node did not stop within 15 s of SIGINT")
    log.seek(0)
    text = log.read()
    if code != 0:
        print(text, file=sys.stderr)
        fail(f"the node exited with {code}")
    if "AXIS_STOPPED" not in text:
        print(text, file=sys.stderr)
        fail("the simulator's log does not show the stop of the cancelled goal")
    ok("the simulator's log shows the stop (AXIS_STOPPED); the node shut down cleanly")
    os.unlink(log.name)
    # Each check fails the run at once: reaching here, every one passed.
    print(f"ros2-peer: {len(PASSED)} passed, 0 failed")


def run_checks(domain, log, limits):
    dp = DomainParticipant(domain)
    recorder = JointStateRecorder(dp)
    recorder.start()
    js = DataReader(dp, Topic(dp, JOINT_STATES, JointState), qos=RELIABLE)
    rosout = DataReader(
        dp, Topic(dp, "rt/rosout", Log),
        qos=Qos(Policy.Reliability.Reliable(duration(seconds=1)), Policy.History.KeepLast(100),
                Policy.Durability.TransientLocal,
                Policy.DataRepresentation(use_cdrv0_representation=True)),
    )
    events = DataReader(dp, Topic(dp, "rt/parameter_events", ParameterEvent), qos=RELIABLE)
    params = "gripper/"
    list_params = Service(dp, params + "list_parameters", ListParametersRequest,
                          ListParametersReply)
    get_params = Service(dp, params + "get_parameters", GetParametersRequest, GetParametersReply)
    set_params = Service(dp, params + "set_parameters", SetParametersRequest, SetParametersReply)
    describe = Service(dp, params + "describe_parameters", DescribeParametersRequest,
                       DescribeParametersReply)
    diag = DataReader(dp, Topic(dp, "rt/diagnostics", DiagnosticArray), qos=RELIABLE)
    home = Service(dp, "gripper/home", TriggerRequest, TriggerReply)
    action = "gripper/gripper_cmd/_action/"
    send_goal = Service(dp, action + "send_goal", SendGoalRequest, SendGoalReply)
    get_result = Service(dp, action + "get_result", GetResultRequest, GetResultReply)
    cancel = Service(dp, action + "cancel_goal", CancelRequest, CancelReply)

    s = first_sample(js, JOINT_STATES, lambda s: list(s.name) == JOINTS)
    ok(f"joint_states remapped to /arm/joint_states: {list(s.name)} at {list(s.position)} m")
    d = first_sample(diag, "rt/diagnostics", lambda d: len(d.status) == 1)
    ok(f"diagnostics: {d.status[0].name!r}: {d.status[0].message!r}")
    if not d.status[0].name.startswith("/gripper"):
        fail(f"diagnostics name {d.status[0].name!r}")

    # Repeatable: homing takes about 1 s here, a second one after 5 s finds it done.
    r = home.call(lambda c, q: TriggerRequest(c, q, 0), attempt_s=5.0)
    if not r.success:
        fail(f"home: {r.message}")
    ok(f"home through rq/gripper/homeRequest: {r.message!r}")

    # Side-effect-free requests, repeated until answered, so that the first goal's reply is not
    # lost to discovery still in progress: a goal with a NaN position is rejected, a result or a
    # cancel of a goal never sent is answered with STATUS_UNKNOWN / ERROR_UNKNOWN_GOAL_ID.
    nobody = UUID(list(random.randbytes(16)))
    nan = Goal(GripperCommand(float("nan"), 0.0))
    if send_goal.call(lambda c, q: SendGoalRequest(c, q, nobody, nan), attempt_s=2.0).accepted:
        fail("a goal with a NaN position was accepted")
    if get_result.call(lambda c, q: GetResultRequest(c, q, nobody), attempt_s=2.0).status != 0:
        fail("the result of an unknown goal is not STATUS_UNKNOWN")
    rep = cancel.call(lambda c, q: CancelRequest(c, q, GoalInfo(nobody, Time(0, 0))), attempt_s=2.0)
    if rep.return_code != 2:
        fail(f"a cancel of an unknown goal answered {rep.return_code}, not ERROR_UNKNOWN_GOAL_ID")
    ok("a NaN goal rejected, unknown goal: STATUS_UNKNOWN, ERROR_UNKNOWN_GOAL_ID")

    def goal(position, max_effort):
        gid = UUID(list(random.randbytes(16)))
        rep = send_goal.call(
            lambda c, q: SendGoalRequest(c, q, gid, Goal(GripperCommand(position, max_effort)))
        )
        if not rep.accepted:
            fail(f"goal {position} m rejected")
        return gid

    def result(gid):
        # Repeatable: a finished goal's result is kept and answered again.
        return get_result.call(lambda c, q: GetResultRequest(c, q, gid), attempt_s=10.0)

    # MoveIt's "close" (0 m) on the simulator's 40 mm part, whose width the goal does not
    # know: the fingers stop on it and hold it, a stall (allow_stalling: SUCCEEDED).
    res = result(goal(0.0, 20.0))
    if (res.status != SUCCEEDED or not res.result.stalled or res.result.reached_goal
            or res.result.effort <= 0.0 or abs(res.result.position - 0.04) > 0.001):
        fail(f"closing on the 40 mm part: status {res.status}, {res.result}")
    ok(f"close (0 m) until contact: stalled at {res.result.position} m "
          f"with {res.result.effort} N")

    # Preemption: a second goal while the first runs (70 -> 100 mm at 20 mm/s takes 1.5 s
    # after the release below): the first ends CANCELED, the second runs to its position.
    res = result(goal(0.07, 0.0))
    if res.status != SUCCEEDED or not res.result.reached_goal:
        fail(f"opening to 0.07 m: status {res.status}, {res.result}")
    first = goal(0.1, 0.0)
    second = goal(0.08, 0.0)
    res = result(first)
    if res.status != CANCELED:
        fail(f"the preempted goal: status {res.status}, {res.result}")
    res = result(second)
    if res.status != SUCCEEDED or abs(res.result.position - 0.08) > 0.001:
        fail(f"the preempting goal: status {res.status}, {res.result}")
    ok("a second goal preempts the first: CANCELED, then the second SUCCEEDED")

    res = result(goal(0.07, 0.0))
    if res.status != SUCCEEDED or not res.result.reached_goal or abs(res.result.position - 0.07) > 0.001:
        fail(f"opening to 0.07 m: status {res.status}, {res.result}")
    ok(f"opening to 0.07 m reached: {res.result}")

    # 70 -> 100 mm at 20 mm/s takes 1.5 s: cancelled after 0.5 s.
    gid = goal(0.1, 0.0)
    time.sleep(0.5)  # let the motion run a little: the point is to stop it midway
    rep = cancel.call(lambda c, q: CancelRequest(c, q, GoalInfo(gid, Time(0, 0))))
    if rep.return_code != 0 or len(rep.goals_canceling) != 1:
        fail(f"cancel: return code {rep.return_code}, {rep.goals_canceling}")
    res = result(gid)
    if res.status != CANCELED or res.result.position >= 0.099:
        fail(f"cancelled goal: status {res.status}, {res.result}")
    ok(f"cancelled goal stopped at {res.result.position} m")

    # The parameter services (what `ros2 param` calls), in this peer's (Cyclone) mapping.
    names = list_params.call(lambda c, q: ListParametersRequest(c, q, [], 0),
                             attempt_s=2.0).result.names
    for name in ["allow_stalling", "speed_m_per_s", "joint_names", "use_sim_time"]:
        if name not in names:
            fail(f"list_parameters: no {name} in {list(names)}")
    ok(f"list_parameters: {len(names)} parameters")
    values = get_params.call(
        lambda c, q: GetParametersRequest(c, q, ["speed_m_per_s", "allow_stalling", "nope"]),
        attempt_s=2.0).values
    if ((values[0].type, values[0].double_value) != (3, 0.02)
            or (values[1].type, values[1].bool_value) != (1, True) or values[2].type != 0):
        fail(f"get_parameters: {values}")
    ok("get_parameters: speed_m_per_s 0.02, allow_stalling true, an unknown name NOT_SET")
    ds = describe.call(
        lambda c, q: DescribeParametersRequest(c, q, ["griplink_port", "joint_states_rate_hz"]),
        attempt_s=2.0).descriptors
    ir, fr = ds[0].integer_range, ds[1].floating_point_range
    if (len(ds) != 2 or not ds[0].read_only or [(r.from_value, r.to_value) for r in ir] != [(0, 3)]
            or [(r.from_value, r.to_value) for r in fr] != [(0.1, 1000.0)]):
        fail(f"describe_parameters: {ds}")
    ok("describe_parameters: types, ranges (griplink_port 0..3, joint_states_rate_hz 0.1..1000)")
    results = set_params.call(
        lambda c, q: SetParametersRequest(c, q, [Parameter("allow_stalling", bool_value(False)),
                                                 Parameter("speed_m_per_s", double_value(0.1))]),
        attempt_s=2.0).results
    if not results[0].successful or results[1].successful or "read-only" not in results[1].reason:
        fail(f"set_parameters: {results}")
    ok(f"set_parameters: allow_stalling set; speed_m_per_s refused: {results[1].reason!r}")

    ev = first_sample(events, "the change on rt/parameter_events",
                      lambda e: e.node == "/gripper" and [
                          (p.name, p.value.bool_value) for p in e.changed_parameters
                      ] == [("allow_stalling", False)])
    ok(f"/parameter_events: {ev.node} changed allow_stalling")

    # allow_stalling is now false: the same close on the part is a stall that ABORTS.
    res = result(goal(0.0, 20.0))
    if res.status != ABORTED or not res.result.stalled or abs(res.result.position - 0.04) > 0.001:
        fail(f"close without allow_stalling: status {res.status}, {res.result}")
    ok("close until contact without allow_stalling: ABORTED, stalled at the part")

    # The node's log on /rosout (rcl_interfaces/msg/Log), with its logger name.
    rec = first_sample(rosout, "the parameter's record on rt/rosout",
                       lambda r: r.name == "gripper" and "allow_stalling" in r.msg)
    ok(f"/rosout: level {rec.level} from {rec.name!r}: {rec.msg!r}")

    recorder.stop()
    check_against_description(recorder.samples, limits)


if __name__ == "__main__":
    main()
