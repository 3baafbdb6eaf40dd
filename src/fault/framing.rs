//! Where frames begin and end in a byte stream, so that "frame" faults (drop, duplicate, corrupt,
//! merge…) hit whole protocol frames rather than whatever a socket read happened to return.
//!
//! Pure code: no I/O, no clock. The proxy feeds what it reads into a [`Framer`] and gets back
//! units, each either a frame (faults apply) or pass-through bytes (garbage between frames, frames
//! longer than the bound, the tail of a stream), which are forwarded untouched so that the proxy
//! never buffers without limit and never hides bytes it could not frame.

use std::fmt;

use bytes::{Bytes, BytesMut};

/// What a custom framing function says about the bytes at the front of the buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameLen {
    /// A frame of this many bytes in total starts at the front of the buffer.
    ///
    /// The function may answer from the header alone: the framer waits until all `n` bytes have
    /// arrived. `Complete(0)` is treated as `Garbage(1)`, so a framing function cannot make the
    /// proxy loop forever.
    Complete(usize),
    /// The bytes so far are the beginning of a frame, but too few to know its length.
    NeedMore,
    /// The first `n` bytes are not (the start of) a frame: forward them as they are and look again
    /// after them. `Garbage(0)` is treated as `Garbage(1)`.
    Garbage(usize),
}

/// How the proxy cuts a byte stream into frames, per protocol.
///
/// Frame faults apply to each frame as a whole; with [`Framing::Bytes`] every socket read is one
/// unit instead. A frame longer than the proxy's `max_frame_len` is forwarded as plain bytes
/// (no fault applies to it) instead of being buffered.
#[derive(Clone, Copy)]
pub enum Framing {
    /// No framing: each read from the socket is one unit.
    Bytes,
    /// Frames end with this byte, which belongs to the frame (GRIPLINK lines end with LF,
    /// `b'\n'`: PROTOCOLS.md §3).
    Delimited(u8),
    /// Every frame has this many bytes (SmartGrasp V3 frames are 80 bytes: PROTOCOLS.md §2).
    /// A length of 0 is treated as 1.
    FixedLength(usize),
    /// A function that reads the front of the buffer and says how long the frame there is, or that
    /// it needs more bytes, or that some bytes are garbage (e.g. for WSG frames,
    /// `AA AA AA id len:u16 LE payload crc:u16`, which are `8 + len` bytes long).
    ///
    /// The function is called with at least one byte; a panic in it ends that connection.
    Custom(fn(&[u8]) -> FrameLen),
}

impl fmt::Debug for Framing {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Framing::Bytes => f.write_str("Bytes"),
            Framing::Delimited(byte) => write!(f, "Delimited({byte:#04x})"),
            Framing::FixedLength(len) => write!(f, "FixedLength({len})"),
            Framing::Custom(_) => f.write_str("Custom(..)"),
        }
    }
}

impl Framing {
    /// The length of the frame at the front of `buf` (which is never empty).
    fn frame_len(&self, buf: &[u8]) -> FrameLen {
        match *self {
            Framing::Bytes => FrameLen::Complete(buf.len()),
            Framing::Delimited(delimiter) => match buf.iter().position(|&b| b == delimiter) {
                Some(end) => FrameLen::Complete(end + 1),
                None => FrameLen::NeedMore,
            },
            Framing::FixedLength(len) => FrameLen::Complete(len.max(1)),
            Framing::Custom(frame_len) => frame_len(buf),
        }
    }
}

/// What a unit coming out of the [`Framer`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum UnitKind {
    /// A whole frame (or one read, for [`Framing::Bytes`]): fault rules apply.
    Frame,
    /// Bytes that are not a frame the proxy can hold: forwarded as they are.
    Passthrough,
}

/// One piece of the stream, in order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Unit {
    pub(crate) kind: UnitKind,
    pub(crate) bytes: Bytes,
}

/// Cuts a byte stream into [`Unit`]s.
///
/// Memory bound: the buffer holds at most `max_frame_len` bytes plus the last chunk pushed,
/// because anything that cannot become a frame within `max_frame_len` bytes leaves as
/// pass-through.
#[derive(Debug)]
pub(crate) struct Framer {
    framing: Framing,
    max_frame_len: usize,
    buf: BytesMut,
    /// Bytes still to forward as pass-through without looking at them: the rest of an oversized
    /// frame whose length is known, or garbage longer than what was buffered.
    skip: usize,
    /// Inside a delimited frame longer than the bound: pass bytes through up to the delimiter,
    /// so that the next frame starts aligned.
    in_long_line: bool,
}

impl Framer {
    pub(crate) fn new(framing: Framing, max_frame_len: usize) -> Self {
        Framer {
            framing,
            max_frame_len: max_frame_len.max(1),
            buf: BytesMut::new(),
            skip: 0,
            in_long_line: false,
        }
    }

    /// Appends bytes read from the socket.
    pub(crate) fn push(&mut self, data: &[u8]) {
        self.buf.extend_from_slice(data);
    }

    /// The next unit, if one is complete. Consecutive pass-through pieces come out as one unit, so
    /// garbage skipped a byte at a time is still forwarded in one write.
    pub(crate) fn next_unit(&mut self) -> Option<Unit> {
        let first = self.next_piece()?;
        if first.kind == UnitKind::Frame {
            return Some(first);
        }
        let mut bytes = BytesMut::from(first.bytes);
        // Stop at a frame: it is kept at the front of the buffer for the next call. Peeking is
        // cheap because the framer only splits the buffer, it does not copy.
        while !self.buf.is_empty() && self.front_is_passthrough() {
            match self.next_piece() {
                Some(piece) => bytes.extend_from_slice(&piece.bytes),
                None => break,
            }
        }
        Some(Unit {
            kind: UnitKind::Passthrough,
            bytes: bytes.freeze(),
        })
    }

    /// Everything still buffered, at the end of the stream: a partial frame is forwarded as it is.
    pub(crate) fn finish(&mut self) -> Option<Unit> {
        if self.buf.is_empty() {
            return None;
        }
        self.skip = 0;
        self.in_long_line = false;
        Some(Unit {
            kind: UnitKind::Passthrough,
            bytes: self.buf.split().freeze(),
        })
    }

    /// Bytes held, waiting for the rest of a frame.
    #[cfg(test)]
    pub(crate) fn buffered(&self) -> usize {
        self.buf.len()
    }

    /// Whether the next piece would be pass-through (without consuming it).
    fn front_is_passthrough(&self) -> bool {
        if self.skip > 0 || self.in_long_line {
            return true;
        }
        if matches!(self.framing, Framing::Bytes) {
            return false;
        }
        match self.framing.frame_len(&self.buf) {
            FrameLen::Complete(0) | FrameLen::Garbage(_) => true,
            FrameLen::Complete(n) => n > self.max_frame_len,
            FrameLen::NeedMore => self.buf.len() >= self.max_frame_len,
        }
    }

    fn passthrough(&mut self, n: usize) -> Unit {
        let n = n.min(self.buf.len());
        Unit {
            kind: UnitKind::Passthrough,
            bytes: self.buf.split_to(n).freeze(),
        }
    }

    fn next_piece(&mut self) -> Option<Unit> {
        if self.buf.is_empty() {
            return None;
        }
        if self.skip > 0 {
            let n = self.skip.min(self.buf.len());
            self.skip -= n;
            return Some(self.passthrough(n));
        }
        if self.in_long_line {
            let Framing::Delimited(delimiter) = self.framing else {
                unreachable!("only delimited framing has long lines")
            };
            return Some(match self.buf.iter().position(|&b| b == delimiter) {
                Some(end) => {
                    self.in_long_line = false;
                    self.passthrough(end + 1)
                }
                None => self.passthrough(self.buf.len()),
            });
        }
        if matches!(self.framing, Framing::Bytes) {
            // One read, one unit. The proxy reads at most one chunk at a time, so this is bounded.
            return Some(Unit {
                kind: UnitKind::Frame,
                bytes: self.buf.split().freeze(),
            });
        }
        match self.framing.frame_len(&self.buf) {
            FrameLen::Complete(0) | FrameLen::Garbage(0) => Some(self.passthrough(1)),
            FrameLen::Garbage(n) => {
                self.skip = n;
                self.next_piece()
            }
            FrameLen::Complete(n) if n > self.max_frame_len => {
                // Too long to hold: forward it as bytes, but keep counting so the frame after it
                // is still recognised.
                tracing::debug!(
                    len = n,
                    "fault proxy: frame longer than the bound, passed through"
                );
                self.skip = n;
                self.next_piece()
            }
            FrameLen::Complete(n) if n <= self.buf.len() => Some(Unit {
                kind: UnitKind::Frame,
                bytes: self.buf.split_to(n).freeze(),
            }),
            FrameLen::Complete(_) => None,
            FrameLen::NeedMore if self.buf.len() >= self.max_frame_len => {
                tracing::debug!("fault proxy: no frame within the bound, bytes passed through");
                if matches!(self.framing, Framing::Delimited(_)) {
                    self.in_long_line = true;
                }
                Some(self.passthrough(self.buf.len()))
            }
            FrameLen::NeedMore => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn units(framer: &mut Framer) -> Vec<(UnitKind, Vec<u8>)> {
        std::iter::from_fn(|| framer.next_unit())
            .map(|u| (u.kind, u.bytes.to_vec()))
            .collect()
    }

    fn frame(bytes: &[u8]) -> (UnitKind, Vec<u8>) {
        (UnitKind::Frame, bytes.to_vec())
    }

    fn pass(bytes: &[u8]) -> (UnitKind, Vec<u8>) {
        (UnitKind::Passthrough, bytes.to_vec())
    }

    /// WSG frame length from the header (PROTOCOLS.md §1: `AA AA AA id len:u16 LE payload crc`).
    fn wsg(buf: &[u8]) -> FrameLen {
        let preamble = buf.iter().take(3).all(|&b| b == 0xAA);
        match buf {
            _ if !preamble => FrameLen::Garbage(1),
            [_, _, _, _, lo, hi, ..] => {
                FrameLen::Complete(8 + usize::from(u16::from_le_bytes([*lo, *hi])))
            }
            _ => FrameLen::NeedMore,
        }
    }

    #[test]
    fn delimited_lines_wait_for_their_end() {
        let mut framer = Framer::new(Framing::Delimited(b'\n'), 64);
        framer.push(b"ACK\nERR 0");
        assert_eq!(units(&mut framer), vec![frame(b"ACK\n")]);
        assert_eq!(framer.buffered(), 5);
        framer.push(b"5\n");
        assert_eq!(units(&mut framer), vec![frame(b"ERR 05\n")]);
        assert_eq!(framer.finish(), None);
    }

    #[test]
    fn overlong_line_passes_through_and_the_next_line_is_a_frame() {
        let mut framer = Framer::new(Framing::Delimited(b'\n'), 4);
        framer.push(b"abcdef");
        assert_eq!(units(&mut framer), vec![pass(b"abcdef")]);
        framer.push(b"gh\nok\n");
        assert_eq!(units(&mut framer), vec![pass(b"gh\n"), frame(b"ok\n")]);
    }

    #[test]
    fn fixed_length_frames_and_partial_tail_at_end() {
        let mut framer = Framer::new(Framing::FixedLength(3), 64);
        framer.push(b"abcdefg");
        assert_eq!(units(&mut framer), vec![frame(b"abc"), frame(b"def")]);
        assert_eq!(
            framer.finish().map(|u| u.bytes.to_vec()),
            Some(b"g".to_vec())
        );
    }

    #[test]
    fn fixed_length_longer_than_bound_passes_through_but_stays_aligned() {
        let mut framer = Framer::new(Framing::FixedLength(5), 3);
        framer.push(b"abcd");
        assert_eq!(units(&mut framer), vec![pass(b"abcd")]);
        framer.push(b"e12345");
        assert_eq!(units(&mut framer), vec![pass(b"e12345")]);
    }

    #[test]
    fn custom_framing_skips_garbage_as_one_passthrough() {
        let mut framer = Framer::new(Framing::Custom(wsg), 64);
        framer.push(&[
            0x01, 0x02, 0xAA, 0x03, 0xAA, 0xAA, 0xAA, 0x06, 0x01, 0x00, 0x42, 0x11,
        ]);
        assert_eq!(units(&mut framer), vec![pass(&[0x01, 0x02, 0xAA, 0x03])]);
        framer.push(&[0x22]);
        assert_eq!(
            units(&mut framer),
            vec![frame(&[
                0xAA, 0xAA, 0xAA, 0x06, 0x01, 0x00, 0x42, 0x11, 0x22
            ])]
        );
    }

    #[test]
    fn custom_framing_that_never_decides_is_bounded() {
        fn never(_: &[u8]) -> FrameLen {
            FrameLen::NeedMore
        }
        let mut framer = Framer::new(Framing::Custom(never), 8);
        framer.push(&[0u8; 7]);
        assert!(units(&mut framer).is_empty());
        framer.push(&[0u8; 3]);
        assert_eq!(units(&mut framer), vec![pass(&[0u8; 10])]);
        assert_eq!(framer.buffered(), 0);
    }

    #[test]
    fn degenerate_answers_cannot_loop() {
        fn zero(_: &[u8]) -> FrameLen {
            FrameLen::Complete(0)
        }
        let mut framer = Framer::new(Framing::Custom(zero), 8);
        framer.push(b"xyz");
        assert_eq!(units(&mut framer), vec![pass(b"xyz")]);
    }

    #[test]
    fn bytes_framing_makes_each_push_one_frame() {
        let mut framer = Framer::new(Framing::Bytes, 8);
        framer.push(b"hello");
        assert_eq!(units(&mut framer), vec![frame(b"hello")]);
    }

    proptest! {
        /// Any split of a stream (frames with garbage between them) yields the same frames, and
        /// every byte comes out exactly once, in order.
        #[test]
        fn any_split_gives_the_same_frames(
            payloads in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..20), 0..6),
            garbage in proptest::collection::vec(proptest::collection::vec(0u8..0xA0, 0..5), 6),
            cuts in proptest::collection::vec(1usize..16, 0..40),
        ) {
            let mut stream = Vec::new();
            let mut frames = Vec::new();
            for (payload, junk) in payloads.iter().zip(&garbage) {
                stream.extend_from_slice(junk);
                let mut f = vec![0xAA, 0xAA, 0xAA, 0x01];
                f.extend_from_slice(&(payload.len() as u16).to_le_bytes());
                f.extend_from_slice(payload);
                f.extend_from_slice(&[0x12, 0x34]);
                stream.extend_from_slice(&f);
                frames.push(f);
            }
            let mut framer = Framer::new(Framing::Custom(wsg), 64);
            let mut out = Vec::new();
            let mut rest = &stream[..];
            let mut cuts = cuts.into_iter();
            while !rest.is_empty() {
                let n = cuts.next().unwrap_or(rest.len()).min(rest.len());
                framer.push(&rest[..n]);
                rest = &rest[n..];
                out.extend(units(&mut framer));
            }
            out.extend(framer.finish().map(|u| (u.kind, u.bytes.to_vec())));
            let got: Vec<Vec<u8>> = out.iter().filter(|(k, _)| *k == UnitKind::Frame).map(|(_, b)| b.clone()).collect();
            prop_assert_eq!(got, frames);
            let all: Vec<u8> = out.into_iter().flat_map(|(_, b)| b).collect();
            prop_assert_eq!(all, stream);
        }
    }
}
