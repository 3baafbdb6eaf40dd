//! The wire frames as pure code: the 6-byte prefix every protocol version shares (manual 2.2) and
//! the 80-byte V3 request and response frames (manual 3.2), every field at the offset of the
//! layout table, big endian (manual 1.1); the V4 frames in [`v4`]. Padding and unused fields are
//! written as zeros and ignored on read. No I/O here: the codec and the simulator both build on
//! these functions.

pub mod v4;

use super::types::{
    CommunicationType, GraspFeedback, GraspMode, MessageType, PoseFormat, ResponseCode,
    RobotSystem, ServerState, Tool,
};

/// Length of the prefix: version u16 + length u32 (manual 2.2).
pub const PREFIX_LEN: usize = 6;
/// Length of every V3 frame, prefix included (manual 3.1: "Jede Meldung ist 80 Byte lang. Immer."),
/// and of every V4 frame (PROTOCOLS.md 2b).
pub const FRAME_LEN: usize = 80;
/// The prefix's length field of a V3 frame: the bytes after the prefix (manual 3.2.1).
pub const V3_LENGTH: u32 = 74;
/// The V3 protocol version (the frames of this module).
pub const PROTOCOL_VERSION: u16 = 3;

/// Byte offsets of the layout table (manual 3.2), named after the manual's fields.
pub mod offset {
    /// Prefix: protocol version, u16.
    pub const VERSION: usize = 0;
    /// Prefix: length of the rest of the message, u32.
    pub const LENGTH: usize = 2;
    /// Header: communication type, u8.
    pub const COMMUNICATION_TYPE: usize = 6;
    /// Header: response code, u8.
    pub const RESPONSE_CODE: usize = 7;
    /// Header: response counter, u8.
    pub const RESPONSE_COUNTER: usize = 8;
    /// Header: message type, u8.
    pub const MESSAGE_TYPE: usize = 9;

    /// Request: client (robot system), u8.
    pub const REQ_CLIENT: usize = 10;
    /// Request: grasp mode, u8.
    pub const REQ_GRASP_MODE: usize = 11;
    /// Request: object class, u16.
    pub const REQ_OBJECT_CLASS: usize = 12;
    /// Request: tool, u8.
    pub const REQ_TOOL: usize = 14;
    /// Request: pose format, u8.
    pub const REQ_POSE_FORMAT: usize = 15;
    /// Request: grasp feedback, u8 (byte 17 is an unused offset byte).
    pub const REQ_GRASP_FEEDBACK: usize = 16;
    /// Request: robot pose, `i32[7]` (bytes 18..46).
    pub const REQ_ROBOT_POSE: usize = 18;
    /// Request: project index, u32 (bytes 50..80 are padding).
    pub const REQ_PROJECT_INDEX: usize = 46;

    /// Response: the server's protocol version, u16.
    pub const RESP_VERSION: usize = 10;
    /// Response: server state, u8.
    pub const RESP_STATE: usize = 12;
    /// Response: grasp mode, u8.
    pub const RESP_GRASP_MODE: usize = 13;
    /// Response: object class, u16.
    pub const RESP_OBJECT_CLASS: usize = 14;
    /// Response: object instance, u16 (errata: the 6.5 example's "uint8" is wrong).
    pub const RESP_OBJECT_INSTANCE: usize = 16;
    /// Response: stroke, i32 µm.
    pub const RESP_STROKE: usize = 18;
    /// Response: angle offset, i32 µdeg.
    pub const RESP_ANGLE_OFFSET: usize = 22;
    /// Response: center offset, `i32[3]` µm (bytes 26..38).
    pub const RESP_CENTER_OFFSET: usize = 26;
    /// Response: tool, u8.
    pub const RESP_TOOL: usize = 38;
    /// Response: pose format, u8.
    pub const RESP_POSE_FORMAT: usize = 39;
    /// Response: grasp pose, `i32[7]` (bytes 40..68).
    pub const RESP_GRASP_POSE: usize = 40;
    /// Response: object count, u16.
    pub const RESP_OBJECT_COUNT: usize = 68;
    /// Response: candidate count, u16 (bytes 72..80 are padding).
    pub const RESP_CANDIDATE_COUNT: usize = 70;
}

/// The prefix every message starts with, identical in every protocol version (manual 2.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Prefix {
    /// Protocol version of the message.
    pub version: u16,
    /// Size of the rest of the message in bytes, without the prefix itself.
    pub length: u32,
}

impl Prefix {
    /// The prefix of every V3 frame.
    pub const V3: Prefix = Prefix {
        version: PROTOCOL_VERSION,
        length: V3_LENGTH,
    };

    /// The bytes of the prefix.
    pub fn encode(&self) -> [u8; PREFIX_LEN] {
        let mut out = [0; PREFIX_LEN];
        out[..2].copy_from_slice(&self.version.to_be_bytes());
        out[2..].copy_from_slice(&self.length.to_be_bytes());
        out
    }

    /// Reads a prefix from its six bytes.
    pub fn decode(bytes: &[u8; PREFIX_LEN]) -> Prefix {
        let [v0, v1, l0, l1, l2, l3] = *bytes;
        Prefix {
            version: u16::from_be_bytes([v0, v1]),
            length: u32::from_be_bytes([l0, l1, l2, l3]),
        }
    }
}

/// The four header bytes, the same in requests and responses (manual 3.2.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// Request or response.
    pub communication_type: CommunicationType,
    /// Outcome of the request (responses only; ignored in requests).
    pub response_code: ResponseCode,
    /// +1 per response, wrapping 255 → 0 (responses only; ignored in requests).
    pub response_counter: u8,
    /// What the message is about.
    pub message_type: MessageType,
}

/// An 80-byte V3 request frame with every field of the request layout (manual 3.2). Only the
/// fields the message type uses carry meaning; [`Request`](super::Request) is the typed view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RequestFrame {
    /// Prefix version (3 for a V3 client).
    pub version: u16,
    /// Header.
    pub header: Header,
    /// Byte 10: robot system (REGISTER_CLIENT).
    pub client: RobotSystem,
    /// Byte 11: grasp mode (GET_GRASP).
    pub grasp_mode: GraspMode,
    /// Bytes 12–13: object class, 0 = any (GET_GRASP, GET_OBJECT_COUNT).
    pub object_class: u16,
    /// Byte 14: tool (GET_GRASP).
    pub tool: Tool,
    /// Byte 15: pose format (GET_GRASP: wanted in the response; ROBOT_POSE: of the robot pose).
    pub pose_format: PoseFormat,
    /// Byte 16: grasp feedback (GRASP_FEEDBACK).
    pub grasp_feedback: GraspFeedback,
    /// Bytes 18–45: robot pose (ROBOT_POSE), layout given by `pose_format`.
    pub robot_pose: [i32; 7],
    /// Bytes 46–49: project index (SET_PROJECT).
    pub project_index: u32,
}

impl RequestFrame {
    /// A request of `message_type` with every body field zero.
    pub fn new(message_type: MessageType) -> RequestFrame {
        RequestFrame {
            version: PROTOCOL_VERSION,
            header: Header {
                communication_type: CommunicationType::Request,
                // The manual's request tables write 0 into the response code and counter.
                response_code: ResponseCode::Unknown(0),
                response_counter: 0,
                message_type,
            },
            client: RobotSystem::Unknown(0),
            grasp_mode: GraspMode::Unknown(0),
            object_class: 0,
            tool: Tool::Unknown(0),
            pose_format: PoseFormat::Unknown(0),
            grasp_feedback: GraspFeedback::Unknown(0),
            robot_pose: [0; 7],
            project_index: 0,
        }
    }

    /// The 80 bytes of the frame; prefix length 74, padding zero.
    pub fn encode(&self) -> [u8; FRAME_LEN] {
        use offset::*;
        let mut b = [0u8; FRAME_LEN];
        write_prefix_and_header(&mut b, self.version, &self.header);
        b[REQ_CLIENT] = self.client.into();
        b[REQ_GRASP_MODE] = self.grasp_mode.into();
        put_u16(&mut b, REQ_OBJECT_CLASS, self.object_class);
        b[REQ_TOOL] = self.tool.into();
        b[REQ_POSE_FORMAT] = self.pose_format.into();
        b[REQ_GRASP_FEEDBACK] = self.grasp_feedback.into();
        put_i32s(&mut b, REQ_ROBOT_POSE, &self.robot_pose);
        put_u32(&mut b, REQ_PROJECT_INDEX, self.project_index);
        b
    }

    /// Reads every field of a request frame. The prefix's length field is not checked here (the
    /// codec checked it before cutting 80 bytes); padding is ignored.
    pub fn decode(b: &[u8; FRAME_LEN]) -> RequestFrame {
        use offset::*;
        RequestFrame {
            version: get_u16(b, VERSION),
            header: read_header(b),
            client: b[REQ_CLIENT].into(),
            grasp_mode: b[REQ_GRASP_MODE].into(),
            object_class: get_u16(b, REQ_OBJECT_CLASS),
            tool: b[REQ_TOOL].into(),
            pose_format: b[REQ_POSE_FORMAT].into(),
            grasp_feedback: b[REQ_GRASP_FEEDBACK].into(),
            robot_pose: get_i32s(b, REQ_ROBOT_POSE),
            project_index: get_u32(b, REQ_PROJECT_INDEX),
        }
    }
}

/// An 80-byte V3 response frame with every field of the response layout (manual 3.2). Only the
/// fields the message type uses carry meaning, and none when the response code is not SUCCESS;
/// [`Response`](super::Response) is the typed view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ResponseFrame {
    /// Prefix version: the server answers with the version the request used (manual 1.3).
    pub version: u16,
    /// Header.
    pub header: Header,
    /// Bytes 10–11: the server's highest protocol version (GET_PROTOCOL_VERSION).
    pub server_version: u16,
    /// Byte 12: server state (GET_STATE).
    pub server_state: ServerState,
    /// Byte 13: grasp mode of the returned grasp (GET_GRASP).
    pub grasp_mode: GraspMode,
    /// Bytes 14–15: object class (GET_GRASP, GET_OBJECT_COUNT).
    pub object_class: u16,
    /// Bytes 16–17: object instance (GET_GRASP).
    pub object_instance: u16,
    /// Bytes 18–21: stroke in µm to set before approaching (GET_GRASP).
    pub stroke_um: i32,
    /// Bytes 22–25: angle offset in µdeg between object model and flange (GET_GRASP).
    pub angle_offset_udeg: i32,
    /// Bytes 26–37: center offset x, y, z in µm, robot base frame (GET_GRASP).
    pub center_offset_um: [i32; 3],
    /// Byte 38: tool (GET_GRASP).
    pub tool: Tool,
    /// Byte 39: pose format of `grasp_pose` (GET_GRASP).
    pub pose_format: PoseFormat,
    /// Bytes 40–67: grasp pose in the robot base frame (GET_GRASP).
    pub grasp_pose: [i32; 7],
    /// Bytes 68–69: number of detected objects (GET_GRASP, GET_OBJECT_COUNT).
    pub object_count: u16,
    /// Bytes 70–71: number of detected objects of the requested class (GET_GRASP, GET_OBJECT_COUNT).
    pub candidate_count: u16,
}

impl ResponseFrame {
    /// A response to `message_type` with `code` and `counter`, every body field zero.
    pub fn new(message_type: MessageType, code: ResponseCode, counter: u8) -> ResponseFrame {
        ResponseFrame {
            version: PROTOCOL_VERSION,
            header: Header {
                communication_type: CommunicationType::Response,
                response_code: code,
                response_counter: counter,
                message_type,
            },
            server_version: 0,
            server_state: ServerState::Unknown(0),
            grasp_mode: GraspMode::Unknown(0),
            object_class: 0,
            object_instance: 0,
            stroke_um: 0,
            angle_offset_udeg: 0,
            center_offset_um: [0; 3],
            tool: Tool::Unknown(0),
            pose_format: PoseFormat::Unknown(0),
            grasp_pose: [0; 7],
            object_count: 0,
            candidate_count: 0,
        }
    }

    /// The 80 bytes of the frame; prefix length 74, padding zero.
    pub fn encode(&self) -> [u8; FRAME_LEN] {
        use offset::*;
        let mut b = [0u8; FRAME_LEN];
        write_prefix_and_header(&mut b, self.version, &self.header);
        put_u16(&mut b, RESP_VERSION, self.server_version);
        b[RESP_STATE] = self.server_state.into();
        b[RESP_GRASP_MODE] = self.grasp_mode.into();
        put_u16(&mut b, RESP_OBJECT_CLASS, self.object_class);
        put_u16(&mut b, RESP_OBJECT_INSTANCE, self.object_instance);
        put_i32s(&mut b, RESP_STROKE, &[self.stroke_um]);
        put_i32s(&mut b, RESP_ANGLE_OFFSET, &[self.angle_offset_udeg]);
        put_i32s(&mut b, RESP_CENTER_OFFSET, &self.center_offset_um);
        b[RESP_TOOL] = self.tool.into();
        b[RESP_POSE_FORMAT] = self.pose_format.into();
        put_i32s(&mut b, RESP_GRASP_POSE, &self.grasp_pose);
        put_u16(&mut b, RESP_OBJECT_COUNT, self.object_count);
        put_u16(&mut b, RESP_CANDIDATE_COUNT, self.candidate_count);
        b
    }

    /// Reads every field of a response frame. The prefix's length field is not checked here (the
    /// codec checked it before cutting 80 bytes); padding is ignored.
    pub fn decode(b: &[u8; FRAME_LEN]) -> ResponseFrame {
        use offset::*;
        let [stroke_um] = get_i32s::<1>(b, RESP_STROKE);
        let [angle_offset_udeg] = get_i32s::<1>(b, RESP_ANGLE_OFFSET);
        ResponseFrame {
            version: get_u16(b, VERSION),
            header: read_header(b),
            server_version: get_u16(b, RESP_VERSION),
            server_state: b[RESP_STATE].into(),
            grasp_mode: b[RESP_GRASP_MODE].into(),
            object_class: get_u16(b, RESP_OBJECT_CLASS),
            object_instance: get_u16(b, RESP_OBJECT_INSTANCE),
            stroke_um,
            angle_offset_udeg,
            center_offset_um: get_i32s(b, RESP_CENTER_OFFSET),
            tool: b[RESP_TOOL].into(),
            pose_format: b[RESP_POSE_FORMAT].into(),
            grasp_pose: get_i32s(b, RESP_GRASP_POSE),
            object_count: get_u16(b, RESP_OBJECT_COUNT),
            candidate_count: get_u16(b, RESP_CANDIDATE_COUNT),
        }
    }
}

/// A request frame of either version, as the prefix's version says: 4 is the V4 layout, every
/// other version V3's (a V3 server reads any 74-byte frame as V3 and judges the version itself).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AnyRequestFrame {
    /// The V3 layout (manual 3.2).
    V3(RequestFrame),
    /// The V4 layout (PROTOCOLS.md 2b).
    V4(v4::RequestFrame),
}

impl AnyRequestFrame {
    /// Reads a frame in the layout of its prefix's version.
    pub fn decode(b: &[u8; FRAME_LEN]) -> AnyRequestFrame {
        if get_u16(b, offset::VERSION) == v4::PROTOCOL_VERSION {
            AnyRequestFrame::V4(v4::RequestFrame::decode(b))
        } else {
            AnyRequestFrame::V3(RequestFrame::decode(b))
        }
    }

    /// The 80 bytes of the frame.
    pub fn encode(&self) -> [u8; FRAME_LEN] {
        match self {
            AnyRequestFrame::V3(f) => f.encode(),
            AnyRequestFrame::V4(f) => f.encode(),
        }
    }

    /// The prefix's version.
    pub fn version(&self) -> u16 {
        match self {
            AnyRequestFrame::V3(f) => f.version,
            AnyRequestFrame::V4(f) => f.version,
        }
    }

    /// The header.
    pub fn header(&self) -> Header {
        match self {
            AnyRequestFrame::V3(f) => f.header,
            AnyRequestFrame::V4(f) => f.header,
        }
    }
}

/// A response frame of either version, as the prefix's version says (see [`AnyRequestFrame`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AnyResponseFrame {
    /// The V3 layout (manual 3.2).
    V3(ResponseFrame),
    /// The V4 layout (PROTOCOLS.md 2b).
    V4(v4::ResponseFrame),
}

impl AnyResponseFrame {
    /// Reads a frame in the layout of its prefix's version.
    pub fn decode(b: &[u8; FRAME_LEN]) -> AnyResponseFrame {
        if get_u16(b, offset::VERSION) == v4::PROTOCOL_VERSION {
            AnyResponseFrame::V4(v4::ResponseFrame::decode(b))
        } else {
            AnyResponseFrame::V3(ResponseFrame::decode(b))
        }
    }

    /// The 80 bytes of the frame.
    pub fn encode(&self) -> [u8; FRAME_LEN] {
        match self {
            AnyResponseFrame::V3(f) => f.encode(),
            AnyResponseFrame::V4(f) => f.encode(),
        }
    }

    /// The prefix's version.
    pub fn version(&self) -> u16 {
        match self {
            AnyResponseFrame::V3(f) => f.version,
            AnyResponseFrame::V4(f) => f.version,
        }
    }

    /// The header.
    pub fn header(&self) -> Header {
        match self {
            AnyResponseFrame::V3(f) => f.header,
            AnyResponseFrame::V4(f) => f.header,
        }
    }

    /// The header, to change.
    pub fn header_mut(&mut self) -> &mut Header {
        match self {
            AnyResponseFrame::V3(f) => &mut f.header,
            AnyResponseFrame::V4(f) => &mut f.header,
        }
    }
}

impl From<RequestFrame> for AnyRequestFrame {
    fn from(f: RequestFrame) -> Self {
        AnyRequestFrame::V3(f)
    }
}

impl From<v4::RequestFrame> for AnyRequestFrame {
    fn from(f: v4::RequestFrame) -> Self {
        AnyRequestFrame::V4(f)
    }
}

impl From<ResponseFrame> for AnyResponseFrame {
    fn from(f: ResponseFrame) -> Self {
        AnyResponseFrame::V3(f)
    }
}

impl From<v4::ResponseFrame> for AnyResponseFrame {
    fn from(f: v4::ResponseFrame) -> Self {
        AnyResponseFrame::V4(f)
    }
}

// The offsets below are the constants of the layout table, all inside the fixed 80-byte array,
// so the indexing cannot fail whatever bytes came from the wire.

fn write_prefix_and_header(b: &mut [u8; FRAME_LEN], version: u16, header: &Header) {
    b[..PREFIX_LEN].copy_from_slice(
        &Prefix {
            version,
            length: V3_LENGTH,
        }
        .encode(),
    );
    b[offset::COMMUNICATION_TYPE] = header.communication_type.into();
    b[offset::RESPONSE_CODE] = header.response_code.into();
    b[offset::RESPONSE_COUNTER] = header.response_counter;
    b[offset::MESSAGE_TYPE] = header.message_type.into();
}

fn read_header(b: &[u8; FRAME_LEN]) -> Header {
    Header {
        communication_type: b[offset::COMMUNICATION_TYPE].into(),
        response_code: b[offset::RESPONSE_CODE].into(),
        response_counter: b[offset::RESPONSE_COUNTER],
        message_type: b[offset::MESSAGE_TYPE].into(),
    }
}

fn put_u16(b: &mut [u8; FRAME_LEN], at: usize, value: u16) {
    b[at..at + 2].copy_from_slice(&value.to_be_bytes());
}

fn put_u32(b: &mut [u8; FRAME_LEN], at: usize, value: u32) {
    b[at..at + 4].copy_from_slice(&value.to_be_bytes());
}

fn put_i32s(b: &mut [u8; FRAME_LEN], at: usize, values: &[i32]) {
    for (i, value) in values.iter().enumerate() {
        let start = at + 4 * i;
        b[start..start + 4].copy_from_slice(&value.to_be_bytes());
    }
}

fn get_u16(b: &[u8; FRAME_LEN], at: usize) -> u16 {
    u16::from_be_bytes([b[at], b[at + 1]])
}

fn get_u32(b: &[u8; FRAME_LEN], at: usize) -> u32 {
    u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

// `inline` and a plain loop: several calls per response decoded, and the compiler inlined
// neither this function nor `std::array::from_fn`'s closure on its own (issue 14, measured).
#[inline]
fn get_i32s<const N: usize>(b: &[u8; FRAME_LEN], at: usize) -> [i32; N] {
    let mut values = [0; N];
    for (i, value) in values.iter_mut().enumerate() {
        let s = at + 4 * i;
        *value = i32::from_be_bytes([b[s], b[s + 1], b[s + 2], b[s + 3]]);
    }
    values
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Manual 6.1: the GET_PROTOCOL_VERSION request, `000 003 000 000 000 074 001 000 000 001`
    /// then zeros.
    #[test]
    fn get_protocol_version_request_matches_manual_6_1() {
        let bytes = RequestFrame::new(MessageType::GetProtocolVersion).encode();
        assert_eq!(bytes[..10], [0, 3, 0, 0, 0, 74, 1, 0, 0, 1]);
        assert!(bytes[10..].iter().all(|&b| b == 0));
    }

    /// Manual 6.1 response: `000 003 000 000 000 074 002 001 000 001 000 003` then zeros.
    #[test]
    fn get_protocol_version_response_matches_manual_6_1() {
        let mut bytes = [0u8; FRAME_LEN];
        bytes[..12].copy_from_slice(&[0, 3, 0, 0, 0, 74, 2, 1, 0, 1, 0, 3]);
        let frame = ResponseFrame::decode(&bytes);
        assert_eq!(frame.header.communication_type, CommunicationType::Response);
        assert_eq!(frame.header.response_code, ResponseCode::Success);
        assert_eq!(frame.header.response_counter, 0);
        assert_eq!(frame.header.message_type, MessageType::GetProtocolVersion);
        assert_eq!(frame.server_version, 3);
        assert_eq!(frame.encode(), bytes);
    }

    /// Manual 6.3: REGISTER_CLIENT as a Siemens PLC puts 128 at byte 10.
    #[test]
    fn register_client_request_matches_manual_6_3() {
        let mut frame = RequestFrame::new(MessageType::RegisterClient);
        frame.client = RobotSystem::SiemensPlc;
        let bytes = frame.encode();
        assert_eq!(bytes[..11], [0, 3, 0, 0, 0, 74, 1, 0, 0, 3, 128]);
        assert!(bytes[11..].iter().all(|&b| b == 0));
    }

    /// Manual 6.4: SET_PROJECT 5 puts the u32 5 at byte 46.
    #[test]
    fn set_project_index_is_at_byte_46() {
        let mut frame = RequestFrame::new(MessageType::SetProject);
        frame.project_index = 5;
        let bytes = frame.encode();
        assert_eq!(bytes[46..50], [0, 0, 0, 5]);
        assert!(bytes[10..46].iter().all(|&b| b == 0));
        assert!(bytes[50..].iter().all(|&b| b == 0));
    }

    /// Manual 6.5: the GET_GRASP response fields land at the layout table's offsets.
    #[test]
    fn get_grasp_response_fields_at_their_offsets() {
        let mut frame = ResponseFrame::new(MessageType::GetGrasp, ResponseCode::Success, 3);
        frame.grasp_mode = GraspMode::AnyGrasp;
        frame.object_class = 3;
        frame.object_instance = 0x0102;
        frame.stroke_um = 86_000;
        frame.angle_offset_udeg = -25_210_142;
        frame.center_offset_um = [-911, -310, 68];
        frame.tool = Tool::Exterior;
        frame.pose_format = PoseFormat::Quaternion;
        frame.grasp_pose = [853_798, 111_998, 502_790, 775_990, 630_744, 0, 0];
        frame.object_count = 2;
        frame.candidate_count = 2;
        let b = frame.encode();
        assert_eq!(b[13], 2);
        assert_eq!(b[14..16], [0, 3]);
        assert_eq!(b[16..18], [1, 2]);
        assert_eq!(b[18..22], 86_000i32.to_be_bytes());
        assert_eq!(b[22..26], (-25_210_142i32).to_be_bytes());
        assert_eq!(b[26..30], (-911i32).to_be_bytes());
        assert_eq!(b[34..38], 68i32.to_be_bytes());
        assert_eq!(b[38], 1);
        assert_eq!(b[39], 1);
        assert_eq!(b[40..44], 853_798i32.to_be_bytes());
        assert_eq!(b[52..56], 775_990i32.to_be_bytes());
        assert_eq!(b[68..70], [0, 2]);
        assert_eq!(b[70..72], [0, 2]);
        assert!(b[72..].iter().all(|&x| x == 0));
        assert_eq!(ResponseFrame::decode(&b), frame);
    }

    #[test]
    fn padding_is_ignored_on_read() {
        let mut frame = RequestFrame::new(MessageType::RobotPose);
        frame.pose_format = PoseFormat::Abc;
        frame.robot_pose = [1, -2, 3, -4, 5, -6, 7];
        let mut b = frame.encode();
        b[17] = 0xAA;
        for x in &mut b[50..] {
            *x = 0xFF;
        }
        assert_eq!(RequestFrame::decode(&b), frame);
        let mut r = ResponseFrame::new(MessageType::GetState, ResponseCode::Success, 9).encode();
        for x in &mut r[72..] {
            *x = 0xFF;
        }
        assert_eq!(
            ResponseFrame::decode(&r),
            ResponseFrame::new(MessageType::GetState, ResponseCode::Success, 9)
        );
    }

    proptest::proptest! {
        /// Every byte a field covers survives decode → encode; every other byte (padding, the
        /// request's offset byte 17) comes back zero. A field missing from either side, or at a
        /// wrong offset, breaks this.
        #[test]
        fn request_fields_cover_exactly_the_layout(b in any_frame()) {
            let mut expected = b;
            expected[17] = 0;
            expected[50..].fill(0);
            proptest::prop_assert_eq!(RequestFrame::decode(&b).encode(), expected);
        }

        #[test]
        fn response_fields_cover_exactly_the_layout(b in any_frame()) {
            let mut expected = b;
            expected[72..].fill(0);
            proptest::prop_assert_eq!(ResponseFrame::decode(&b).encode(), expected);
        }
    }

    /// A V3 prefix (any version byte: a frame keeps the version it carried) and 74 arbitrary
    /// bytes.
    fn any_frame() -> impl proptest::strategy::Strategy<Value = [u8; FRAME_LEN]> {
        use proptest::strategy::Strategy;
        proptest::collection::vec(proptest::prelude::any::<u8>(), 75).prop_map(|v| {
            let mut out = [0u8; FRAME_LEN];
            out[..PREFIX_LEN].copy_from_slice(&Prefix::V3.encode());
            out[1] = v[0];
            out[PREFIX_LEN..].copy_from_slice(&v[1..]);
            out
        })
    }
}
