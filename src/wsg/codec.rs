//! The tokio-util codec: [`super::frame`] encoding and decoding over a byte stream.

use bytes::BytesMut;
use tokio_util::codec::{Decoder, Encoder};

use super::command::id;
use super::frame::{self, Decoded, Frame, DEFAULT_MAX_PAYLOAD_LEN};

/// A [`Decoder`]/[`Encoder`] of WSG [`Frame`]s for TCP and serial streams.
///
/// Decoding never returns `Err` for anything that came from the wire (an `Err` would end a
/// `FramedRead`): garbage is skipped to the next preamble and frames with a bad checksum are
/// dropped with a `tracing` warning and counted in [`WsgCodec::corrupt_frames`].
#[derive(Clone, Debug)]
pub struct WsgCodec {
    max_payload_len: usize,
    /// Decodes a client's input: a header longer than any reply of its id is noise
    /// ([`max_reply_payload_len`]).
    replies: bool,
    corrupt_frames: u64,
    /// Frames dropped and runs of bytes skipped as noise: whatever may have been a frame the
    /// peer sent ([`WsgCodec::damage`]).
    damage: u64,
}

impl Default for WsgCodec {
    fn default() -> Self {
        Self::new()
    }
}

impl WsgCodec {
    /// A codec accepting payloads up to [`DEFAULT_MAX_PAYLOAD_LEN`].
    pub fn new() -> Self {
        Self::with_max_payload_len(DEFAULT_MAX_PAYLOAD_LEN)
    }

    /// A codec accepting payloads up to `max_payload_len` bytes (longer headers are noise).
    pub fn with_max_payload_len(max_payload_len: usize) -> Self {
        Self {
            max_payload_len,
            replies: false,
            corrupt_frames: 0,
            damage: 0,
        }
    }

    /// A codec for a client's side of the stream: besides `max_payload_len`, a header longer
    /// than any reply of its command id can be ([`max_reply_payload_len`]) is noise at once,
    /// instead of holding every later reply until that many bytes have arrived (a bit flip in
    /// a length field).
    pub(crate) fn for_replies(max_payload_len: usize) -> Self {
        Self {
            replies: true,
            ..Self::with_max_payload_len(max_payload_len)
        }
    }

    /// How many frames with a bad checksum were dropped so far.
    pub fn corrupt_frames(&self) -> u64 {
        self.corrupt_frames
    }

    /// How many times the decoder dropped something the peer may have sent as a frame: a frame
    /// with a bad checksum, or bytes skipped to the next preamble. A client that cannot tell a
    /// reply from an update by its bytes asks again after one (issue 29 A).
    pub(crate) fn damage(&self) -> u64 {
        self.damage
    }

    fn next(&mut self, src: &mut BytesMut, eof: bool) -> Option<Frame> {
        let before = src.len();
        let frame = self.next_frame(src, eof);
        let consumed = before - src.len();
        if consumed > frame.as_ref().map_or(0, Frame::encoded_len) {
            self.damage += 1;
        }
        frame
    }

    fn next_frame(&mut self, src: &mut BytesMut, eof: bool) -> Option<Frame> {
        let (max, replies) = (self.max_payload_len, self.replies);
        let limit = |id: u8| match REPLY_LIMITS[usize::from(id)] {
            0 => max,
            n if replies => usize::from(n).min(max),
            _ => max,
        };
        loop {
            let d = if eof {
                frame::decode_eof_limited(src, limit)
            } else {
                frame::decode_limited(src, limit)
            };
            match d? {
                Decoded::Frame(f) => return Some(f),
                Decoded::Corrupt { .. } => self.corrupt_frames += 1,
            }
        }
    }
}

/// The longest payload a reply of command `id` has (its 2-byte status code included), from the
/// manual's reply layouts (chapter 3; the client's decoders accept exactly these lengths and
/// nothing longer); `None` for ids whose reply length is not fixed (finger data, commands the
/// crate has no type for).
pub(crate) const fn max_reply_payload_len(command: u8) -> Option<usize> {
    const STATUS: usize = 2;
    let data = match command {
        // 3.1.1: the echo of up to 256 bytes.
        id::LOOP => super::command::MAX_LOOP_LEN,
        id::ANNOUNCE_DISCONNECT
        | id::HOMING..=id::RELEASE
        | id::SET_ACCELERATION
        | id::SET_FORCE
        | id::SET_SOFT_LIMITS
        | id::CLEAR_SOFT_LIMITS
        | id::OVERDRIVE
        | id::TARE
        | id::SET_TAG
        | id::FINGER1_POWER
        | id::FINGER2_POWER => 0,
        // One f32 or u32 (3.3.2, 3.3.4, 3.4.1, 3.4.4-3.4.6).
        id::GET_ACCELERATION
        | id::GET_FORCE
        | id::SYSTEM_STATE
        | id::WIDTH
        | id::SPEED
        | id::FORCE => 4,
        id::GRIP_STATE => 1,
        id::TEMPERATURE | id::FINGER1_FLAGS | id::FINGER2_FLAGS => 2,
        id::FINGER1_INFO | id::FINGER2_INFO => 3,
        id::GET_SOFT_LIMITS | id::GRASPING_STATISTICS | id::SYSTEM_INFO => 8,
        id::SYSTEM_LIMITS => 32,
        id::GET_TAG => super::command::MAX_TAG_LEN,
        _ => return None,
    };
    Some(STATUS + data)
}

/// [`max_reply_payload_len`] for every id, 0 for none: one load per header on the hot path.
const REPLY_LIMITS: [u16; 256] = {
    let mut t = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        if let Some(n) = max_reply_payload_len(i as u8) {
            t[i] = n as u16;
        }
        i += 1;
    }
    t
};

impl Decoder for WsgCodec {
    type Item = Frame;
    type Error = std::io::Error;

    fn decode(&mut self, src: &mut BytesMut) -> Result<Option<Frame>, Self::Error> {
        Ok(self.next(src, false))
    }

    fn decode_eof(&mut self, src: &mut BytesMut) -> Result<Option<Frame>, Self::Error> {
        Ok(self.next(src, true))
    }
}

impl Encoder<Frame> for WsgCodec {
    type Error = std::io::Error;

    fn encode(&mut self, item: Frame, dst: &mut BytesMut) -> Result<(), Self::Error> {
        self.encode(&item, dst)
    }
}

impl Encoder<&Frame> for WsgCodec {
    type Error = std::io::Error;

    fn encode(&mut self, item: &Frame, dst: &mut BytesMut) -> Result<(), Self::Error> {
        frame::encode(item, dst)
            .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn encoded(f: &Frame) -> BytesMut {
        let mut b = BytesMut::new();
        frame::encode(f, &mut b).unwrap();
        b
    }

    /// Issue 20.2 #2: a bit flip in a reply's length field (6 → 0x0806 for a width) must not
    /// hold the replies behind it until 2 KiB have arrived: no width reply is that long.
    #[test]
    fn a_reply_header_longer_than_its_id_allows_is_noise_at_once() {
        let good = Frame::new(id::WIDTH, vec![0, 0, 0, 0, 0x20, 0x42]);
        let mut bytes = BytesMut::from(&[0xAA, 0xAA, 0xAA, id::WIDTH, 0x06, 0x08][..]);
        bytes.extend_from_slice(&encoded(&good));
        let mut codec = WsgCodec::for_replies(DEFAULT_MAX_PAYLOAD_LEN);
        assert_eq!(
            codec.decode(&mut bytes.clone()).unwrap(),
            Some(good.clone())
        );
        // A codec for requests (the simulator's) knows no reply lengths: it waits.
        assert_eq!(WsgCodec::new().decode(&mut bytes).unwrap(), None);
        // Each fixed-length reply the crate decodes fits its limit.
        let mut big = Frame::new(id::GET_TAG, vec![0; 2 + super::super::command::MAX_TAG_LEN]);
        assert_eq!(codec.decode(&mut encoded(&big)).unwrap(), Some(big.clone()));
        big.payload = vec![0; 3 + super::super::command::MAX_TAG_LEN].into();
        assert_eq!(codec.decode(&mut encoded(&big)).unwrap(), None);
    }
}
