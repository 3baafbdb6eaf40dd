//! Pure encoding and decoding of WSG frames (manual 1.2.1 and 1.2.2), no I/O.
//!
//! ```text
//! AA AA AA | id:u8 | len:u16 LE | payload[len] | checksum:u16 LE
//! ```
//!
//! # Resynchronisation
//! [`decode`] never fails: it skips garbage byte by byte to the next preamble, and reports a
//! frame whose checksum does not match as [`Decoded::Corrupt`] before resuming the search one
//! byte after that frame's start (so a corrupted length field cannot swallow the frames behind
//! it).
//!
//! The flip side of byte-wise resynchronisation: when a frame whose payload carries a whole,
//! valid frame (a loop reply echoing one, say) is itself corrupted, the inner frame is found and
//! delivered. Skipping the whole rejected frame instead would let one corrupted length field
//! swallow the good frames behind it, which happens far more often.
//!
//! Runs of more than three `AA` bytes are resolved by taking the **last three** as the preamble:
//! the byte after the preamble is the command id, and no WSG command has id `0xAA`. This keeps
//! `AA` noise before a frame from being read as the header of a long bogus frame (which would
//! stall the decoder until that many bytes arrived). The client therefore refuses to send id
//! `0xAA` (its reply could not be told from noise).
//!
//! A header whose length exceeds the decoder's maximum is treated as noise (one byte skipped).
//! A corrupted length field below the maximum still makes the decoder wait for that many bytes
//! before the checksum can reject it; on a stream, later traffic completes it, and
//! [`decode_eof`] flushes it at end of stream.

use bytes::{Buf, BufMut, Bytes, BytesMut};

use super::checksum;

/// The fixed preamble that starts every frame (manual 1.2.1, bytes 0..2).
pub const PREAMBLE: [u8; 3] = [0xAA; 3];
/// Bytes before the payload: preamble, id, length.
pub const HEADER_LEN: usize = 6;
/// Bytes after the payload: the checksum.
pub const CHECKSUM_LEN: usize = 2;
/// The largest payload the decoder accepts by default.
///
/// The length field allows 65535, but no command of the manual comes close: the longest are the
/// loop reply (2 + 256 bytes) and finger data, whose size the finger reports (0x60/0x70). 4096
/// leaves room for sensor fingers while bounding how long a corrupted length can stall
/// resynchronisation and how much one frame can make the decoder buffer.
pub const DEFAULT_MAX_PAYLOAD_LEN: usize = 4096;

/// One frame: a command (client → device) or a reply (device → client).
///
/// For a reply, the payload starts with the status code (see [`super::Reply`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Frame {
    /// The command id (manual 1.2.1, byte 3).
    pub id: u8,
    /// The payload, without preamble, header and checksum.
    pub payload: Bytes,
}

impl Frame {
    /// A frame with the given id and payload.
    pub fn new(id: u8, payload: impl Into<Bytes>) -> Self {
        Self {
            id,
            payload: payload.into(),
        }
    }

    /// The number of bytes this frame takes on the wire.
    pub fn encoded_len(&self) -> usize {
        HEADER_LEN + self.payload.len() + CHECKSUM_LEN
    }
}

/// The payload does not fit the 16-bit length field.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("payload of {0} bytes does not fit a WSG frame (at most 65535)")]
pub struct PayloadTooLong(pub usize);

/// Appends `frame` to `dst` with its checksum.
pub fn encode(frame: &Frame, dst: &mut BytesMut) -> Result<(), PayloadTooLong> {
    encode_parts(frame.id, &[&frame.payload], dst)
}

/// Appends a frame whose payload is the concatenation of `parts` (saves a copy when a reply is
/// a status code followed by data).
pub fn encode_parts(id: u8, parts: &[&[u8]], dst: &mut BytesMut) -> Result<(), PayloadTooLong> {
    let len: usize = parts.iter().map(|p| p.len()).sum();
    let len16 = u16::try_from(len).map_err(|_| PayloadTooLong(len))?;
    dst.reserve(HEADER_LEN + len + CHECKSUM_LEN);
    let start = dst.len();
    dst.put_slice(&PREAMBLE);
    dst.put_u8(id);
    dst.put_u16_le(len16);
    for p in parts {
        dst.put_slice(p);
    }
    let crc = checksum::checksum(&dst[start..]);
    dst.put_u16_le(crc);
    Ok(())
}

/// What [`decode`] found at the front of the buffer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Decoded {
    /// A frame with a correct checksum.
    Frame(Frame),
    /// A complete frame whose checksum did not match; the search resumes one byte after its
    /// start. The manual leaves what to do with it to the receiver: a client evaluates the
    /// checksum of replies itself (1.2.2, "Die Auswertung obliegt dem Client") and drops such a
    /// frame; what the device does with a request that has one is not documented (it names
    /// E_CHECKSUM_ERROR in Anhang A under no command; 1.2.1 only says a frame *missing* its
    /// checksum is discarded). The simulator discards it by default
    /// (`sim::SimConfig::answer_bad_checksum`).
    Corrupt {
        /// The id byte of the rejected frame.
        id: u8,
        /// Its length field.
        len: u16,
    },
}

/// Decodes the next frame from the front of `src`, consuming what it decodes or skips.
///
/// Returns `None` when more bytes are needed; bytes before a possible preamble are dropped, so
/// `src` never grows beyond one frame of at most `max_payload_len` plus a few bytes of garbage.
pub fn decode(src: &mut BytesMut, max_payload_len: usize) -> Option<Decoded> {
    decode_limited(src, |_| max_payload_len)
}

/// [`decode`] with a limit per command id: a header whose length exceeds `limit(id)` is noise.
pub(crate) fn decode_limited(src: &mut BytesMut, limit: impl Fn(u8) -> usize) -> Option<Decoded> {
    loop {
        let start = find_preamble(src)?;
        src.advance(start);
        // src starts with AA AA AA and the byte after it (if present) is not AA.
        if src.len() < HEADER_LEN {
            return None;
        }
        let id = src[3];
        let len = u16::from_le_bytes([src[4], src[5]]);
        let max_payload_len = limit(id);
        if usize::from(len) > max_payload_len {
            tracing::warn!(
                id,
                len,
                max_payload_len,
                "WSG frame length above the limit: skipping"
            );
            src.advance(1);
            continue;
        }
        let total = HEADER_LEN + usize::from(len) + CHECKSUM_LEN;
        if src.len() < total {
            return None;
        }
        // Compare with the checksum field itself. Running the checksum over the frame *with* its
        // checksum gives 0 for the right value, but this hybrid (see `checksum`) is not a true
        // CRC: about three other values give 0 too, so that test let frames with a wrong checksum
        // through (found by fuzz/wsg_codec). `src` holds `total` bytes, so the indices are in range.
        let received = u16::from_le_bytes([src[total - 2], src[total - 1]]);
        if checksum::checksum(&src[..total - CHECKSUM_LEN]) != received {
            tracing::warn!(id, len, "WSG frame with a bad checksum: skipping");
            src.advance(1);
            return Some(Decoded::Corrupt { id, len });
        }
        let mut frame = src.split_to(total);
        frame.advance(HEADER_LEN);
        frame.truncate(usize::from(len));
        return Some(Decoded::Frame(Frame {
            id,
            payload: frame.freeze(),
        }));
    }
}

/// Like [`decode`], at end of stream: a header that cannot complete any more is dropped as noise
/// and the search continues after its first byte.
pub fn decode_eof(src: &mut BytesMut, max_payload_len: usize) -> Option<Decoded> {
    decode_eof_limited(src, |_| max_payload_len)
}

/// [`decode_eof`] with a limit per command id (see [`decode_limited`]).
pub(crate) fn decode_eof_limited(
    src: &mut BytesMut,
    limit: impl Fn(u8) -> usize,
) -> Option<Decoded> {
    loop {
        if let Some(d) = decode_limited(src, &limit) {
            return Some(d);
        }
        if src.is_empty() {
            return None;
        }
        // An incomplete frame (or lone preamble) at the very end: skip one byte and retry.
        src.advance(1);
    }
}

/// Finds the start of the next preamble, dropping nothing. Within a run of `AA` bytes it
/// returns the position of the last three (the id byte cannot be `AA`). Returns `None` (after
/// dropping the bytes that cannot start a preamble) when no complete preamble + id is known yet.
fn find_preamble(src: &mut BytesMut) -> Option<usize> {
    let mut i = 0;
    while i < src.len() {
        if src[i] != 0xAA {
            i += 1;
            continue;
        }
        // A run of AA starts at i: find its end.
        let run_start = i;
        while i < src.len() && src[i] == 0xAA {
            i += 1;
        }
        let run_len = i - run_start;
        if i == src.len() {
            // The run reaches the end of the buffer: keep its last three bytes for later.
            let keep_from = src.len() - run_len.min(3);
            src.advance(keep_from);
            return None;
        }
        if run_len >= 3 {
            return Some(i - 3);
        }
    }
    src.clear();
    None
}

/// The length of the frame at the front of `buf`, for the fault proxy's
/// [`Framing::Custom`](crate::fault::Framing::Custom) (feature `sim`): lets a test drop,
/// duplicate or corrupt whole WSG frames. Bytes before a preamble are garbage; within a run of
/// `AA` bytes the last three are the preamble, as in [`decode`]. The checksum is not checked (a
/// proxy forwards corrupt frames too).
///
/// ```
/// use gripper::fault::{FrameLen, Framing, ProxyConfig};
/// use gripper::wsg::frame::frame_len;
///
/// assert_eq!(frame_len(&[0xAA, 0xAA, 0xAA, 0x06, 0x02, 0x00]), FrameLen::Complete(10));
/// assert_eq!(frame_len(&[0x00, 0xAA]), FrameLen::Garbage(1));
/// let config = ProxyConfig::new().framing(Framing::Custom(frame_len));
/// # let _ = config;
/// ```
#[cfg(feature = "sim")]
pub fn frame_len(buf: &[u8]) -> crate::fault::FrameLen {
    use crate::fault::FrameLen;
    let run = buf.iter().take_while(|&&b| b == 0xAA).count();
    match buf {
        _ if run == 0 => FrameLen::Garbage(1),
        // More than three AA: the first ones are noise before the preamble.
        _ if run > 3 => FrameLen::Garbage(run - 3),
        [_, _, _, _, lo, hi, ..] if run == 3 => FrameLen::Complete(
            HEADER_LEN + usize::from(u16::from_le_bytes([*lo, *hi])) + CHECKSUM_LEN,
        ),
        // A run shorter than three that is followed by another byte cannot be a preamble.
        _ if run < 3 && buf.len() > run => FrameLen::Garbage(run),
        _ => FrameLen::NeedMore,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn enc(id: u8, payload: &[u8]) -> Vec<u8> {
        let mut b = BytesMut::new();
        encode(&Frame::new(id, payload.to_vec()), &mut b).unwrap();
        b.to_vec()
    }

    /// Regression (fuzz/wsg_codec): the manual's example frame `AA AA AA 01 02 00 12 34` has
    /// checksum `6D 66`, but the running checksum over the frame also ends at 0 with `EE 04`,
    /// `67 A5` or `E4 C7` in its place. Only the real checksum may pass.
    #[test]
    fn only_the_exact_checksum_is_accepted() {
        let good = enc(0x01, &[0x12, 0x34]);
        let (body, crc) = good.split_at(good.len() - CHECKSUM_LEN);
        let mut residue_zero = 0;
        for wrong in (0..=u16::MAX).filter(|&v| v.to_le_bytes() != crc) {
            let mut frame = body.to_vec();
            frame.extend_from_slice(&wrong.to_le_bytes());
            residue_zero += usize::from(checksum::checksum(&frame) == 0);
            let mut src = BytesMut::from(&frame[..]);
            assert_eq!(
                decode(&mut src, DEFAULT_MAX_PAYLOAD_LEN),
                Some(Decoded::Corrupt { id: 0x01, len: 2 }),
                "checksum {wrong:#06x}"
            );
        }
        // The old test (residue 0) would have passed these three.
        assert_eq!(residue_zero, 3);
        let mut src = BytesMut::from(&good[..]);
        assert_eq!(
            decode(&mut src, DEFAULT_MAX_PAYLOAD_LEN),
            Some(Decoded::Frame(Frame::new(0x01, vec![0x12, 0x34])))
        );
    }

    #[test]
    fn encodes_the_manuals_examples() {
        assert_eq!(
            enc(0x01, &[]),
            [0xAA, 0xAA, 0xAA, 0x01, 0x00, 0x00, 0xE8, 0x10]
        );
        assert_eq!(
            enc(0x01, &[0x12, 0x34]),
            [0xAA, 0xAA, 0xAA, 0x01, 0x02, 0x00, 0x12, 0x34, 0x6D, 0x66]
        );
        assert_eq!(
            enc(0x07, &[]),
            [0xAA, 0xAA, 0xAA, 0x07, 0x00, 0x00, 0x35, 0x4C]
        );
    }

    #[test]
    fn decodes_every_protocol_vector() {
        for v in crate::wsg::checksum::tests::VECTORS {
            let mut b = BytesMut::from(*v);
            match decode(&mut b, DEFAULT_MAX_PAYLOAD_LEN) {
                Some(Decoded::Frame(f)) => {
                    assert_eq!(f.id, v[3]);
                    assert_eq!(&f.payload[..], &v[6..v.len() - 2]);
                }
                other => panic!("{v:02X?} decoded as {other:?}"),
            }
            assert!(b.is_empty());
        }
    }

    #[test]
    fn aa_run_before_a_frame() {
        let mut b = BytesMut::from(&[0xAA; 7][..]);
        b.extend_from_slice(&enc(0x20, &[0, 0]));
        let got = decode(&mut b, DEFAULT_MAX_PAYLOAD_LEN);
        assert_eq!(got, Some(Decoded::Frame(Frame::new(0x20, vec![0, 0]))));
    }

    #[test]
    fn corrupt_frame_is_reported_and_the_next_decodes() {
        let mut bad = enc(0x43, &[1, 2, 3]);
        let n = bad.len();
        bad[n - 1] ^= 0x55;
        let mut b = BytesMut::from(&bad[..]);
        b.extend_from_slice(&enc(0x44, &[9]));
        assert_eq!(
            decode(&mut b, 4096),
            Some(Decoded::Corrupt { id: 0x43, len: 3 })
        );
        assert_eq!(
            decode(&mut b, 4096),
            Some(Decoded::Frame(Frame::new(0x44, vec![9])))
        );
        assert_eq!(decode(&mut b, 4096), None);
    }

    #[test]
    fn oversized_length_is_noise() {
        let mut b = BytesMut::from(&[0xAA, 0xAA, 0xAA, 0x06, 0xFF, 0xFF][..]);
        b.extend_from_slice(&enc(0x06, &[1]));
        assert_eq!(
            decode(&mut b, 256),
            Some(Decoded::Frame(Frame::new(0x06, vec![1])))
        );
    }

    #[test]
    fn eof_flushes_a_stalled_header() {
        // A bogus header claiming 100 bytes, then a real frame; at end of stream the real
        // frame comes out.
        let mut b = BytesMut::from(&[0xAA, 0xAA, 0xAA, 0x06, 100, 0][..]);
        b.extend_from_slice(&enc(0x06, &[1]));
        assert_eq!(decode(&mut b, 4096), None);
        assert_eq!(
            decode_eof(&mut b, 4096),
            Some(Decoded::Frame(Frame::new(0x06, vec![1])))
        );
        assert_eq!(decode_eof(&mut b, 4096), None);
    }

    #[test]
    fn too_long_payload_is_refused() {
        let mut b = BytesMut::new();
        let f = Frame::new(6, vec![0u8; 65536]);
        assert_eq!(encode(&f, &mut b), Err(PayloadTooLong(65536)));
    }
}
