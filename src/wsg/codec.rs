//! The tokio-util codec: [`super::frame`] encoding and decoding over a byte stream.

use bytes::BytesMut;
use tokio_util::codec::{Decoder, Encoder};

use super::frame::{self, Decoded, Frame, DEFAULT_MAX_PAYLOAD_LEN};

/// A [`Decoder`]/[`Encoder`] of WSG [`Frame`]s for TCP and serial streams.
///
/// Decoding never returns `Err` for anything that came from the wire (an `Err` would end a
/// `FramedRead`): garbage is skipped to the next preamble and frames with a bad checksum are
/// dropped with a `tracing` warning and counted in [`WsgCodec::corrupt_frames`].
#[derive(Clone, Debug)]
pub struct WsgCodec {
    max_payload_len: usize,
    corrupt_frames: u64,
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
            corrupt_frames: 0,
        }
    }

    /// How many frames with a bad checksum were dropped so far.
    pub fn corrupt_frames(&self) -> u64 {
        self.corrupt_frames
    }

    fn next(&mut self, src: &mut BytesMut, eof: bool) -> Option<Frame> {
        loop {
            let d = if eof {
                frame::decode_eof(src, self.max_payload_len)
            } else {
                frame::decode(src, self.max_payload_len)
            };
            match d? {
                Decoded::Frame(f) => return Some(f),
                Decoded::Corrupt { .. } => self.corrupt_frames += 1,
            }
        }
    }
}

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
