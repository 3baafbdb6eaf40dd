"""The Grasping-Kit client (blocking) against the in-process simulated server."""

from __future__ import annotations

import pytest

import gripper_rs
from gripper_rs import smartgrasp
from gripper_rs.smartgrasp import GetGraspOutcome, GraspMode, PoseFormat, Tool
from gripper_rs.smartgrasp.sim import SimServer


def test_session(kit: smartgrasp.Client, kit_sim: SimServer) -> None:
    assert kit.get_state() is smartgrasp.ServerState.OPERATIONAL
    # The simulator speaks V4, and the client negotiates the highest version both speak.
    assert kit.get_protocol_version() == 4
    assert kit.protocol_version() == 4
    assert kit.server_version() == 4
    assert kit.counter_gaps() == 0
    kit.register_client(smartgrasp.RobotSystem.UR)
    assert kit_sim.registered_clients() == [smartgrasp.RobotSystem.UR]
    kit.set_project(0)
    with pytest.raises(gripper_rs.DeviceError) as caught:
        kit.set_project(99)
    assert caught.value.code == smartgrasp.ResponseCode.ERROR
    assert caught.value.command == "SET_PROJECT"
    # As for every protocol: the status as the protocol's IntEnum, the manual's symbol as name.
    assert caught.value.status is smartgrasp.ResponseCode.ERROR
    assert caught.value.name == "ERROR"


def test_grasp_loop(kit: smartgrasp.Client) -> None:
    result = kit.get_grasp(GraspMode.ACTIVE_GRASP, 1, Tool.EXTERIOR, PoseFormat.QUATERNION)
    assert result.outcome is GetGraspOutcome.GRASP
    grasp = result.grasp
    assert grasp is not None
    assert grasp.object_class == 1
    assert grasp.stroke_mm == 86.0
    assert grasp.pose.format is PoseFormat.QUATERNION
    assert len(grasp.pose.wire) == 7
    assert grasp.pose.orientation_xyzw is not None
    kit.grasp_feedback(True)
    missing = kit.get_grasp(GraspMode.ACTIVE_GRASP, 999, Tool.EXTERIOR, PoseFormat.QUATERNION)
    assert missing.outcome is GetGraspOutcome.INVALID_OBJECT_CLASS
    assert missing.grasp is None
    count = kit.get_object_count(0)
    assert count.object_count >= 1


def test_robot_pose(kit_sim: SimServer) -> None:
    # V3 carries a quaternion pose as it is (V4 poses have six values: the client sends ABC).
    kit = smartgrasp.Client.connect(kit_sim.address, protocol_version=3)
    assert kit.protocol_version() == 3
    wire = [450000, -120000, 50000, 1000000, 0, 0, 0]
    kit.robot_pose(PoseFormat.QUATERNION, wire)
    [received] = kit_sim.robot_poses()
    assert received.format is PoseFormat.QUATERNION
    assert received.wire == wire
    assert received.position_m == pytest.approx([0.45, -0.12, 0.05])
    with pytest.raises(ValueError):
        kit.get_grasp(9, 1, Tool.EXTERIOR, PoseFormat.QUATERNION)


def test_timeout_lost_response_and_close(kit_sim: SimServer) -> None:
    with smartgrasp.Client.connect(kit_sim.address, query_timeout_s=0.2) as kit:
        kit_sim.delay_next_reply(0.5)
        with pytest.raises(TimeoutError):
            kit.get_state()
        assert kit.with_timeout(5.0).get_state() is smartgrasp.ServerState.OPERATIONAL
        kit_sim.close_next()
        with pytest.raises(gripper_rs.ConnectionLostError):
            kit.get_state()
    with smartgrasp.Client.connect(kit_sim.address) as kit:
        kit_sim.corrupt_next_length(5)
        with pytest.raises(gripper_rs.GripperError):
            kit.get_state()


def test_not_operational_is_a_protocol_error() -> None:
    with SimServer(server_state=smartgrasp.ServerState.STOPPED) as sim:
        with pytest.raises(gripper_rs.ProtocolError):
            smartgrasp.Client.connect(sim.address)


def test_v4_tool_workspace_and_grasp_fields(kit_sim: SimServer) -> None:
    with smartgrasp.Client.connect(kit_sim.address, tool_id=1, workspace_id=0) as kit:
        assert kit.protocol_version() == 4
        kit.set_tool(1)
        kit.set_workspace(0)
        result = kit.get_grasp(GraspMode.ACTIVE_GRASP, 1, Tool.EXTERIOR, PoseFormat.ABC, 2)
        grasp = result.grasp
        assert grasp is not None
        # V4 delivers an object offset and a reference frame, and no V3-only fields.
        assert grasp.object_offset is not None
        assert grasp.reference_frame is not None
        assert grasp.tool is None and grasp.angle_offset_udeg is None
    with smartgrasp.Client.connect(kit_sim.address, protocol_version=3) as kit:
        result = kit.get_grasp(GraspMode.ACTIVE_GRASP, 1, Tool.EXTERIOR, PoseFormat.ABC)
        grasp = result.grasp
        assert grasp is not None
        assert grasp.tool is Tool.EXTERIOR and grasp.angle_offset_udeg is not None
        assert grasp.object_offset is None and grasp.reference_frame is None
        # V3 names the tool in each GET_GRASP: SET_TOOL is refused before sending.
        with pytest.raises(ValueError):
            kit.set_tool(1)


def test_v3_only_server_is_served() -> None:
    with SimServer(max_version=3) as sim:
        with smartgrasp.Client.connect(sim.address) as kit:
            assert kit.protocol_version() == 3
            assert kit.server_version() == 3
