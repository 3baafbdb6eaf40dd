//! The 80-byte V4 request and response frames. No V4 manual is public: every offset here is read
//! from SCHUNK's own KUKA example (repository `SCHUNK-SE-Co-KG/SCHUNK_2DGrasping_Examples`, files
//! `KUKA-KRC/SCHUNK_GRASPINGKIT.src/.dat`, commit 57ade13 of 2025-06-11), as PROTOCOLS.md section
//! 2b lists it. Prefix and header are V3's (version 4, length 74); every multi-byte field is big
//! endian, every 4-byte field a signed i32.
//!
//! What the example does not pin is kept raw, never given a meaning: the response bytes 10–13
//! (GET_GRASP's grasp mode is at 10 for the example, at 13 in V3), 68–71 and 76–79. Unused request
//! bytes (17, 48–79) are written as zeros and ignored on read.

use super::{
    get_i32s, get_u16, put_i32s, put_u16, read_header, write_prefix_and_header, Header, FRAME_LEN,
};
use crate::smartgrasp::types::{
    CommunicationType, GraspFeedback, GraspMode, MessageType, PoseFormat, ReferenceFrame,
    ResponseCode, RobotSystem, SelectionCriterion, ServerState,
};

/// The V4 protocol version.
pub const PROTOCOL_VERSION: u16 = 4;

/// Byte offsets of the V4 frames (PROTOCOLS.md 2b), frame offsets (body offset + 10).
pub mod offset {
    /// Request: client (robot system), u8 (REGISTER_CLIENT).
    pub const REQ_CLIENT: usize = 10;
    /// Request: grasp mode, u8 (GET_GRASP).
    pub const REQ_GRASP_MODE: usize = 11;
    /// Request: object ID (GET_GRASP) or object class (GET_OBJECT_COUNT), u16.
    pub const REQ_OBJECT_ID: usize = 12;
    /// Request: selection criterion, u8 (GET_GRASP; V3: the tool).
    pub const REQ_SELECTION_CRITERION: usize = 14;
    /// Request: pose format, u8 (GET_GRASP, ROBOT_POSE).
    pub const REQ_POSE_FORMAT: usize = 15;
    /// Request: grasp feedback, u8 (GRASP_FEEDBACK).
    pub const REQ_GRASP_FEEDBACK: usize = 16;
    /// Request: project ID, u16 (SET_PROJECT; V3: a u32 index at 46).
    pub const REQ_PROJECT_ID: usize = 18;
    /// Request: tool ID, u16 (SET_TOOL).
    pub const REQ_TOOL_ID: usize = 20;
    /// Request: workspace ID, u16 (SET_WORKSPACE).
    pub const REQ_WORKSPACE_ID: usize = 22;
    /// Request: robot pose, `i32[6]` (ROBOT_POSE, bytes 24..48; V3: `i32[7]` at 18).
    pub const REQ_ROBOT_POSE: usize = 24;

    /// Response: bytes 10–13, read by message type (see [`ResponseFrame::head`](super::ResponseFrame::head)).
    pub const RESP_HEAD: usize = 10;
    /// Response: object ID, u16 (GET_GRASP).
    pub const RESP_OBJECT_ID: usize = 14;
    /// Response: object instance, u16 (GET_GRASP).
    pub const RESP_OBJECT_INSTANCE: usize = 16;
    /// Response: pose format of the grasp pose, u8 (GET_GRASP; V3: 39).
    pub const RESP_POSE_FORMAT: usize = 18;
    /// Response: reference frame, u8 (GET_GRASP; new in V4).
    pub const RESP_REFERENCE_FRAME: usize = 19;
    /// Response: stroke, i32 µm (GET_GRASP; V3: 18).
    pub const RESP_STROKE: usize = 20;
    /// Response: object offset x, y in µm, rz in µdeg, `i32[3]` (GET_GRASP; new in V4).
    pub const RESP_OBJECT_OFFSET: usize = 24;
    /// Response: centre offset x, y in µm, `i32[2]` (GET_GRASP; V3: x, y, z at 26).
    pub const RESP_CENTER_OFFSET: usize = 36;
    /// Response: grasp pose, `i32[6]` (GET_GRASP, bytes 44..68; V3: `i32[7]` at 40).
    pub const RESP_GRASP_POSE: usize = 44;
    /// Response: bytes 68–71, not read by the example (a 7th pose value would sit here).
    pub const RESP_UNREAD_68: usize = 68;
    /// Response: candidate count, u16 (GET_GRASP, GET_OBJECT_COUNT; V3: objects at 68).
    pub const RESP_CANDIDATE_COUNT: usize = 72;
    /// Response: object count, u16 (GET_GRASP, GET_OBJECT_COUNT; V3: candidates at 70).
    pub const RESP_OBJECT_COUNT: usize = 74;
    /// Response: bytes 76–79, not read by the example.
    pub const RESP_UNREAD_76: usize = 76;
}

/// An 80-byte V4 request frame with every field the example writes. Only the fields the message
/// type uses carry meaning; [`Request`](crate::smartgrasp::Request) is the typed view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RequestFrame {
    /// Prefix version (4).
    pub version: u16,
    /// Header (as V3).
    pub header: Header,
    /// Byte 10: robot system (REGISTER_CLIENT).
    pub client: RobotSystem,
    /// Byte 11: grasp mode (GET_GRASP).
    pub grasp_mode: GraspMode,
    /// Bytes 12–13: object ID (GET_GRASP) or the class to count, 0 = all (GET_OBJECT_COUNT).
    pub object_id: u16,
    /// Byte 14: selection criterion (GET_GRASP).
    pub selection_criterion: SelectionCriterion,
    /// Byte 15: pose format (GET_GRASP: wanted; ROBOT_POSE: of the robot pose).
    pub pose_format: PoseFormat,
    /// Byte 16: grasp feedback (GRASP_FEEDBACK; without effect in V4, PROTOCOLS.md 2b).
    pub grasp_feedback: GraspFeedback,
    /// Bytes 18–19: project ID as seen in the web frontend (SET_PROJECT).
    pub project_id: u16,
    /// Bytes 20–21: tool ID (SET_TOOL).
    pub tool_id: u16,
    /// Bytes 22–23: workspace ID (SET_WORKSPACE).
    pub workspace_id: u16,
    /// Bytes 24–47: robot pose, six values (ROBOT_POSE), layout given by `pose_format`.
    pub robot_pose: [i32; 6],
}

impl RequestFrame {
    /// A V4 request of `message_type` with every body field zero.
    pub fn new(message_type: MessageType) -> RequestFrame {
        RequestFrame {
            version: PROTOCOL_VERSION,
            header: Header {
                communication_type: CommunicationType::Request,
                response_code: ResponseCode::Unknown(0),
                response_counter: 0,
                message_type,
            },
            client: RobotSystem::Unknown(0),
            grasp_mode: GraspMode::Unknown(0),
            object_id: 0,
            selection_criterion: SelectionCriterion(0),
            pose_format: PoseFormat::Unknown(0),
            grasp_feedback: GraspFeedback::Unknown(0),
            project_id: 0,
            tool_id: 0,
            workspace_id: 0,
            robot_pose: [0; 6],
        }
    }

    /// The 80 bytes of the frame; prefix length 74, unused bytes zero.
    pub fn encode(&self) -> [u8; FRAME_LEN] {
        use offset::*;
        let mut b = [0u8; FRAME_LEN];
        write_prefix_and_header(&mut b, self.version, &self.header);
        b[REQ_CLIENT] = self.client.into();
        b[REQ_GRASP_MODE] = self.grasp_mode.into();
        put_u16(&mut b, REQ_OBJECT_ID, self.object_id);
        b[REQ_SELECTION_CRITERION] = self.selection_criterion.into();
        b[REQ_POSE_FORMAT] = self.pose_format.into();
        b[REQ_GRASP_FEEDBACK] = self.grasp_feedback.into();
        put_u16(&mut b, REQ_PROJECT_ID, self.project_id);
        put_u16(&mut b, REQ_TOOL_ID, self.tool_id);
        put_u16(&mut b, REQ_WORKSPACE_ID, self.workspace_id);
        put_i32s(&mut b, REQ_ROBOT_POSE, &self.robot_pose);
        b
    }

    /// Reads every field of a V4 request frame; the prefix length is the codec's business,
    /// unused bytes are ignored.
    pub fn decode(b: &[u8; FRAME_LEN]) -> RequestFrame {
        use offset::*;
        RequestFrame {
            version: get_u16(b, super::offset::VERSION),
            header: read_header(b),
            client: b[REQ_CLIENT].into(),
            grasp_mode: b[REQ_GRASP_MODE].into(),
            object_id: get_u16(b, REQ_OBJECT_ID),
            selection_criterion: b[REQ_SELECTION_CRITERION].into(),
            pose_format: b[REQ_POSE_FORMAT].into(),
            grasp_feedback: b[REQ_GRASP_FEEDBACK].into(),
            project_id: get_u16(b, REQ_PROJECT_ID),
            tool_id: get_u16(b, REQ_TOOL_ID),
            workspace_id: get_u16(b, REQ_WORKSPACE_ID),
            robot_pose: get_i32s(b, REQ_ROBOT_POSE),
        }
    }
}

/// An 80-byte V4 response frame: every byte 10–79 is a field, typed where the example pins it,
/// raw where it does not. Only the fields the message type uses carry meaning, and none when the
/// response code is not SUCCESS; [`Response`](crate::smartgrasp::Response) is the typed view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ResponseFrame {
    /// Prefix version: the version the request used (manual 1.3).
    pub version: u16,
    /// Header (as V3).
    pub header: Header,
    /// Bytes 10–13, read by message type: GET_PROTOCOL_VERSION the server's highest version
    /// (u16 at 10), GET_STATE the state (u8 at 12), GET_GRASP the grasp mode (the example reads
    /// byte 10, V3 has it at 13: an open question, so all four bytes are kept). Use the
    /// accessors.
    pub head: [u8; 4],
    /// Bytes 14–15: object ID (GET_GRASP).
    pub object_id: u16,
    /// Bytes 16–17: object instance (GET_GRASP).
    pub object_instance: u16,
    /// Byte 18: format of the returned grasp pose (GET_GRASP).
    pub pose_format: PoseFormat,
    /// Byte 19: reference frame (GET_GRASP); values unknown.
    pub reference_frame: ReferenceFrame,
    /// Bytes 20–23: stroke in µm (GET_GRASP).
    pub stroke_um: i32,
    /// Bytes 24–31: object offset x, y in µm (GET_GRASP); meaning and frame not public.
    pub object_offset_um: [i32; 2],
    /// Bytes 32–35: object offset rz in µdeg (GET_GRASP).
    pub object_offset_rz_udeg: i32,
    /// Bytes 36–43: centre offset x, y in µm (GET_GRASP).
    pub center_offset_um: [i32; 2],
    /// Bytes 44–67: grasp pose, six values (GET_GRASP), layout given by `pose_format`.
    pub grasp_pose: [i32; 6],
    /// Bytes 68–71: not read by the example.
    pub unread_68: [u8; 4],
    /// Bytes 72–73: candidate count (GET_GRASP, GET_OBJECT_COUNT).
    pub candidate_count: u16,
    /// Bytes 74–75: object count (GET_GRASP, GET_OBJECT_COUNT).
    pub object_count: u16,
    /// Bytes 76–79: not read by the example.
    pub unread_76: [u8; 4],
}

impl ResponseFrame {
    /// A V4 response to `message_type` with `code` and `counter`, every body byte zero.
    pub fn new(message_type: MessageType, code: ResponseCode, counter: u8) -> ResponseFrame {
        ResponseFrame {
            version: PROTOCOL_VERSION,
            header: Header {
                communication_type: CommunicationType::Response,
                response_code: code,
                response_counter: counter,
                message_type,
            },
            head: [0; 4],
            object_id: 0,
            object_instance: 0,
            pose_format: PoseFormat::Unknown(0),
            reference_frame: ReferenceFrame(0),
            stroke_um: 0,
            object_offset_um: [0; 2],
            object_offset_rz_udeg: 0,
            center_offset_um: [0; 2],
            grasp_pose: [0; 6],
            unread_68: [0; 4],
            candidate_count: 0,
            object_count: 0,
            unread_76: [0; 4],
        }
    }

    /// GET_PROTOCOL_VERSION: the server's highest version, u16 at 10.
    pub fn server_version(&self) -> u16 {
        let [hi, lo, _, _] = self.head;
        u16::from_be_bytes([hi, lo])
    }

    /// Sets the u16 at 10 (GET_PROTOCOL_VERSION).
    pub fn set_server_version(&mut self, version: u16) {
        let [hi, lo] = version.to_be_bytes();
        self.head[0] = hi;
        self.head[1] = lo;
    }

    /// GET_STATE: the server state, u8 at 12.
    pub fn server_state(&self) -> ServerState {
        self.head[2].into()
    }

    /// Sets the u8 at 12 (GET_STATE).
    pub fn set_server_state(&mut self, state: ServerState) {
        self.head[2] = state.into();
    }

    /// GET_GRASP: the grasp mode. The example reads byte 10; V3 has it at 13 and the example's
    /// own V3 version read 13. Until a V4 manual says which, byte 10 is taken when it is not 0,
    /// else byte 13 (0 is no grasp mode in either version).
    pub fn grasp_mode(&self) -> GraspMode {
        let [at_10, _, _, at_13] = self.head;
        if at_10 != 0 { at_10 } else { at_13 }.into()
    }

    /// The 80 bytes of the frame; prefix length 74.
    pub fn encode(&self) -> [u8; FRAME_LEN] {
        use offset::*;
        let mut b = [0u8; FRAME_LEN];
        write_prefix_and_header(&mut b, self.version, &self.header);
        b[RESP_HEAD..RESP_HEAD + 4].copy_from_slice(&self.head);
        put_u16(&mut b, RESP_OBJECT_ID, self.object_id);
        put_u16(&mut b, RESP_OBJECT_INSTANCE, self.object_instance);
        b[RESP_POSE_FORMAT] = self.pose_format.into();
        b[RESP_REFERENCE_FRAME] = self.reference_frame.into();
        put_i32s(&mut b, RESP_STROKE, &[self.stroke_um]);
        put_i32s(&mut b, RESP_OBJECT_OFFSET, &self.object_offset_um);
        put_i32s(
            &mut b,
            RESP_OBJECT_OFFSET + 8,
            &[self.object_offset_rz_udeg],
        );
        put_i32s(&mut b, RESP_CENTER_OFFSET, &self.center_offset_um);
        put_i32s(&mut b, RESP_GRASP_POSE, &self.grasp_pose);
        b[RESP_UNREAD_68..RESP_UNREAD_68 + 4].copy_from_slice(&self.unread_68);
        put_u16(&mut b, RESP_CANDIDATE_COUNT, self.candidate_count);
        put_u16(&mut b, RESP_OBJECT_COUNT, self.object_count);
        b[RESP_UNREAD_76..RESP_UNREAD_76 + 4].copy_from_slice(&self.unread_76);
        b
    }

    /// Reads every byte of a V4 response frame; the prefix length is the codec's business.
    pub fn decode(b: &[u8; FRAME_LEN]) -> ResponseFrame {
        use offset::*;
        let four = |at: usize| [b[at], b[at + 1], b[at + 2], b[at + 3]];
        let [stroke_um] = get_i32s::<1>(b, RESP_STROKE);
        let [x, y, rz] = get_i32s::<3>(b, RESP_OBJECT_OFFSET);
        ResponseFrame {
            version: get_u16(b, super::offset::VERSION),
            header: read_header(b),
            head: four(RESP_HEAD),
            object_id: get_u16(b, RESP_OBJECT_ID),
            object_instance: get_u16(b, RESP_OBJECT_INSTANCE),
            pose_format: b[RESP_POSE_FORMAT].into(),
            reference_frame: b[RESP_REFERENCE_FRAME].into(),
            stroke_um,
            object_offset_um: [x, y],
            object_offset_rz_udeg: rz,
            center_offset_um: get_i32s(b, RESP_CENTER_OFFSET),
            grasp_pose: get_i32s(b, RESP_GRASP_POSE),
            unread_68: four(RESP_UNREAD_68),
            candidate_count: get_u16(b, RESP_CANDIDATE_COUNT),
            object_count: get_u16(b, RESP_OBJECT_COUNT),
            unread_76: four(RESP_UNREAD_76),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bytes 0–8 of every V4 request in PROTOCOLS.md 2b's test vectors, then the message type.
    fn request_head(message_type: u8) -> [u8; FRAME_LEN] {
        let mut b = [0u8; FRAME_LEN];
        b[..10].copy_from_slice(&[
            0x00,
            0x04,
            0x00,
            0x00,
            0x00,
            0x4A,
            0x01,
            0x00,
            0x00,
            message_type,
        ]);
        b
    }

    /// Each vector of PROTOCOLS.md 2b ("Test vectors"), written out byte by byte, against the
    /// encoder and the decoder.
    #[test]
    fn requests_match_the_krl_test_vectors() {
        let mut cases: Vec<(RequestFrame, [u8; FRAME_LEN])> = Vec::new();
        cases.push((
            RequestFrame::new(MessageType::GetProtocolVersion),
            request_head(0x01),
        ));
        cases.push((RequestFrame::new(MessageType::GetState), request_head(0x02)));

        let mut f = RequestFrame::new(MessageType::RegisterClient);
        f.client = RobotSystem::Kuka;
        let mut b = request_head(0x03);
        b[10] = 0x02;
        cases.push((f, b));

        let mut f = RequestFrame::new(MessageType::SetProject);
        f.project_id = 164;
        let mut b = request_head(0x04);
        b[18] = 0x00;
        b[19] = 0xA4;
        cases.push((f, b));

        let mut f = RequestFrame::new(MessageType::SetTool);
        f.tool_id = 32;
        let mut b = request_head(0x05);
        b[20] = 0x00;
        b[21] = 0x20;
        cases.push((f, b));

        let mut f = RequestFrame::new(MessageType::SetWorkspace);
        f.workspace_id = 1;
        let mut b = request_head(0x06);
        b[22] = 0x00;
        b[23] = 0x01;
        cases.push((f, b));

        for (mode, object, criterion, bytes) in [
            (3, 0, 1, [0x00, 0x03, 0x00, 0x00, 0x01, 0x11]),
            (2, 8, 2, [0x00, 0x02, 0x00, 0x08, 0x02, 0x11]),
        ] {
            let mut f = RequestFrame::new(MessageType::GetGrasp);
            f.grasp_mode = GraspMode::from(mode);
            f.object_id = object;
            f.selection_criterion = SelectionCriterion(criterion);
            f.pose_format = PoseFormat::Abc;
            let mut b = request_head(0x10);
            b[10..16].copy_from_slice(&bytes);
            cases.push((f, b));
        }

        // graspFeedback(0): no body byte set.
        let mut f = RequestFrame::new(MessageType::GraspFeedback);
        f.grasp_feedback = GraspFeedback::Unknown(0);
        cases.push((f, request_head(0x11)));

        let mut f = RequestFrame::new(MessageType::GetObjectCount);
        f.object_id = 1;
        let mut b = request_head(0x20);
        b[12] = 0x00;
        b[13] = 0x01;
        cases.push((f, b));

        // X 412.5, Y -35.25, Z 120 mm, A 45, B -0.5, C 179.999 deg.
        let mut f = RequestFrame::new(MessageType::RobotPose);
        f.pose_format = PoseFormat::Abc;
        f.robot_pose = [412_500, -35_250, 120_000, 45_000_000, -500_000, 179_999_000];
        let mut b = request_head(0x30);
        b[15] = 0x11;
        b[24..48].copy_from_slice(&[
            0x00, 0x06, 0x4B, 0x54, 0xFF, 0xFF, 0x76, 0x4E, 0x00, 0x01, 0xD4, 0xC0, 0x02, 0xAE,
            0xA5, 0x40, 0xFF, 0xF8, 0x5E, 0xE0, 0x0A, 0xBA, 0x91, 0x18,
        ]);
        cases.push((f, b));

        for (frame, bytes) in cases {
            assert_eq!(frame.encode(), bytes, "{frame:?}");
            assert_eq!(RequestFrame::decode(&bytes), frame);
        }
    }

    /// A GET_GRASP response laid out byte by byte as the example reads it (PROTOCOLS.md 2b,
    /// "GET_GRASP response"), every field a distinct value.
    #[test]
    fn get_grasp_response_fields_at_the_krl_offsets() {
        let mut b = [0u8; FRAME_LEN];
        b[..10].copy_from_slice(&[0x00, 0x04, 0x00, 0x00, 0x00, 0x4A, 0x02, 0x01, 0x07, 0x10]);
        b[10] = 0x02; // grasp mode
        b[14..16].copy_from_slice(&[0x00, 0x08]); // object ID 8
        b[16..18].copy_from_slice(&[0x01, 0x02]); // instance 258
        b[18] = 0x11; // pose format 17
        b[19] = 0x05; // reference frame 5
        b[20..24].copy_from_slice(&[0x00, 0x01, 0x4F, 0xF0]); // stroke 86 000 µm
        b[24..28].copy_from_slice(&[0xFF, 0xFF, 0xFC, 0x71]); // object offset x -911 µm
        b[28..32].copy_from_slice(&[0x00, 0x00, 0x01, 0x36]); // y 310 µm
        b[32..36].copy_from_slice(&[0xFE, 0x7F, 0x52, 0xE2]); // rz -25 210 142 µdeg
        b[36..40].copy_from_slice(&[0x00, 0x00, 0x00, 0x44]); // centre x 68 µm
        b[40..44].copy_from_slice(&[0xFF, 0xFF, 0xFF, 0xF6]); // centre y -10 µm
        b[44..48].copy_from_slice(&[0x00, 0x06, 0x4B, 0x54]); // x 412 500 µm
        b[48..52].copy_from_slice(&[0xFF, 0xFF, 0x76, 0x4E]); // y -35 250 µm
        b[52..56].copy_from_slice(&[0x00, 0x01, 0xD4, 0xC0]); // z 120 000 µm
        b[56..60].copy_from_slice(&[0x02, 0xAE, 0xA5, 0x40]); // A 45 000 000 µdeg
        b[60..64].copy_from_slice(&[0xFF, 0xF8, 0x5E, 0xE0]); // B -500 000 µdeg
        b[64..68].copy_from_slice(&[0x0A, 0xBA, 0x91, 0x18]); // C 179 999 000 µdeg
        b[72..74].copy_from_slice(&[0x00, 0x02]); // candidates 2
        b[74..76].copy_from_slice(&[0x00, 0x03]); // objects 3
        let f = ResponseFrame::decode(&b);
        assert_eq!(f.header.response_code, ResponseCode::Success);
        assert_eq!(f.header.response_counter, 7);
        assert_eq!(f.header.message_type, MessageType::GetGrasp);
        assert_eq!(f.grasp_mode(), GraspMode::AnyGrasp);
        assert_eq!(f.object_id, 8);
        assert_eq!(f.object_instance, 258);
        assert_eq!(f.pose_format, PoseFormat::Abc);
        assert_eq!(f.reference_frame, ReferenceFrame(5));
        assert_eq!(f.stroke_um, 86_000);
        assert_eq!(f.object_offset_um, [-911, 310]);
        assert_eq!(f.object_offset_rz_udeg, -25_210_142);
        assert_eq!(f.center_offset_um, [68, -10]);
        assert_eq!(
            f.grasp_pose,
            [412_500, -35_250, 120_000, 45_000_000, -500_000, 179_999_000]
        );
        assert_eq!(f.candidate_count, 2);
        assert_eq!(f.object_count, 3);
        assert_eq!(f.encode(), b);
    }

    #[test]
    fn the_head_reads_by_message_type() {
        let mut f = ResponseFrame::new(MessageType::GetProtocolVersion, ResponseCode::Success, 0);
        f.set_server_version(4);
        assert_eq!(f.encode()[10..12], [0x00, 0x04]);
        assert_eq!(f.server_version(), 4);
        let mut f = ResponseFrame::new(MessageType::GetState, ResponseCode::Success, 0);
        f.set_server_state(ServerState::Operational);
        assert_eq!(f.encode()[12], 2);
        assert_eq!(f.server_state(), ServerState::Operational);
        // The grasp mode at 13 (V3's place) when byte 10 is 0.
        let mut f = ResponseFrame::new(MessageType::GetGrasp, ResponseCode::Success, 0);
        f.head = [0, 0, 0, 3];
        assert_eq!(f.grasp_mode(), GraspMode::AutoGrasp);
        f.head = [1, 0, 0, 3];
        assert_eq!(f.grasp_mode(), GraspMode::ActiveGrasp);
    }

    proptest::proptest! {
        /// Every response byte 10–79 is a field: decode → encode gives the frame back.
        #[test]
        fn response_fields_cover_every_byte(body in proptest::collection::vec(proptest::prelude::any::<u8>(), 74)) {
            let mut b = [0u8; FRAME_LEN];
            b[..6].copy_from_slice(&[0, 4, 0, 0, 0, 74]);
            b[6..].copy_from_slice(&body);
            proptest::prop_assert_eq!(ResponseFrame::decode(&b).encode(), b);
        }

        /// The request's fields cover exactly the bytes the example writes: 17 and 48–79 come
        /// back zero, every other byte as it was.
        #[test]
        fn request_fields_cover_exactly_the_layout(body in proptest::collection::vec(proptest::prelude::any::<u8>(), 74)) {
            let mut b = [0u8; FRAME_LEN];
            b[..6].copy_from_slice(&[0, 4, 0, 0, 0, 74]);
            b[6..].copy_from_slice(&body);
            let mut expected = b;
            expected[17] = 0;
            expected[48..].fill(0);
            proptest::prop_assert_eq!(RequestFrame::decode(&b).encode(), expected);
        }
    }
}
