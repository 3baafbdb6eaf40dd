//! LF-terminated lines as a tokio-util codec: the framing of both line protocols, GRIPLINK
//! (GRIPLINK manual 2.1) and the WSG text interface (GCL, WSG-TEXT-INTERFACE.md §2).
//!
//! Decoding never fails on bad input: an over-long line or one with a non-ASCII byte is
//! discarded (with a `tracing` event) and reported as [`Line::Discarded`], and decoding goes on
//! with the next line. It is reported rather than dropped silently because the client pairs
//! replies with commands by order: a reply that vanished would hand every later reply to the
//! wrong caller. An over-long line that arrives in many chunks is skipped up to its LF without
//! buffering it, so memory stays bounded by the maximum line length. A trailing CR is removed.

use bytes::{Buf, BufMut, BytesMut};
use tokio_util::codec::{Decoder, Encoder};

/// Default longest line, in bytes without the LF (GRIPLINK's default; the WSG text client has its
/// own, `wsg::text::line::DEFAULT_MAX_LINE_LEN`). GRIPLINK replies are short (a GRIPCFGF recipe
/// is the longest, around 200 bytes); this leaves room without letting a peer make us buffer
/// much.
pub const DEFAULT_MAX_LINE_LEN: usize = 1024;

/// One decoded line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Line {
    /// A line of ASCII text, without LF or trailing CR.
    Text(String),
    /// A line that was discarded; it still counts as one line.
    Discarded(Discarded),
}

/// Why a line was discarded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Discarded {
    /// Longer than the codec's maximum.
    TooLong,
    /// Contained a byte above 0x7F.
    NotAscii,
}

impl std::fmt::Display for Discarded {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Discarded::TooLong => "line too long (discarded)",
            Discarded::NotAscii => "line with non-ASCII bytes (discarded)",
        })
    }
}

/// A decoded line whose text stays in the receive buffer's memory: what the client reads. It
/// parses a reply at once and keeps nothing of the line, so copying it into a `String` (a
/// [`Line`]) would cost an allocation per reply for nothing.
#[derive(Debug)]
pub(crate) enum RawLine {
    /// A line of ASCII text, without LF or trailing CR.
    Text(BytesMut),
    /// A line that was discarded; it still counts as one line.
    Discarded(Discarded),
}

impl RawLine {
    /// The line's text, or why it was discarded.
    pub(crate) fn text(&self) -> Result<&str, Discarded> {
        match self {
            // Only ASCII lines are kept, and ASCII is valid UTF-8.
            RawLine::Text(bytes) => std::str::from_utf8(bytes).map_err(|_| Discarded::NotAscii),
            RawLine::Discarded(why) => Err(*why),
        }
    }

    fn into_line(self) -> Line {
        match self {
            RawLine::Text(bytes) => Line::Text(String::from_utf8_lossy(&bytes).into_owned()),
            RawLine::Discarded(why) => Line::Discarded(why),
        }
    }
}

/// [`LineCodec`] decoding [`RawLine`]s, for the client's reader.
#[derive(Debug)]
pub(crate) struct RawLineCodec(pub(crate) LineCodec);

impl Decoder for RawLineCodec {
    type Item = RawLine;
    type Error = std::io::Error;

    fn decode(&mut self, buf: &mut BytesMut) -> Result<Option<RawLine>, std::io::Error> {
        self.0.decode_raw(buf)
    }

    fn decode_eof(&mut self, buf: &mut BytesMut) -> Result<Option<RawLine>, std::io::Error> {
        self.0.decode_eof_raw(buf)
    }
}

/// The LF line codec: decodes [`Line`]s, encodes `&str` lines (appending the LF).
#[derive(Debug, Clone)]
pub struct LineCodec {
    max_len: usize,
    /// Where to resume the search for LF (bytes before it are known to hold none).
    searched: usize,
    /// Inside an over-long line: drop bytes until the next LF.
    discarding: bool,
    /// At the end of the stream, an unterminated last line is an error instead of a line.
    reject_unterminated: bool,
}

impl Default for LineCodec {
    fn default() -> Self {
        LineCodec::new(DEFAULT_MAX_LINE_LEN)
    }
}

impl LineCodec {
    /// A codec for lines of at most `max_len` bytes (not counting LF and a trailing CR).
    pub fn new(max_len: usize) -> Self {
        LineCodec {
            max_len,
            searched: 0,
            discarding: false,
            reject_unterminated: false,
        }
    }

    /// The same codec, but an unterminated line at the end of the stream is an
    /// [`UnexpectedEof`](std::io::ErrorKind::UnexpectedEof) error instead of a line. The client
    /// uses it: a reply cut off by a lost connection (`VALUE[0][0]=12` of `…=12345`) must not
    /// be taken for a whole one.
    pub fn reject_unterminated(mut self) -> Self {
        self.reject_unterminated = true;
        self
    }

    /// The longest line accepted.
    pub fn max_len(&self) -> usize {
        self.max_len
    }

    /// `line` is the line without its LF.
    fn finish_line(&self, mut line: BytesMut) -> RawLine {
        if line.last() == Some(&b'\r') {
            line.truncate(line.len() - 1);
        }
        if line.len() > self.max_len {
            tracing::warn!(len = line.len(), "line codec: discarding over-long line");
            return RawLine::Discarded(Discarded::TooLong);
        }
        if !line.is_ascii() {
            tracing::warn!("line codec: discarding line with non-ASCII bytes");
            return RawLine::Discarded(Discarded::NotAscii);
        }
        RawLine::Text(line)
    }

    /// [`Decoder::decode`], the line left in `buf`'s memory.
    fn decode_raw(&mut self, buf: &mut BytesMut) -> Result<Option<RawLine>, std::io::Error> {
        let from = self.searched.min(buf.len());
        let newline = buf
            .get(from..)
            .and_then(|tail| tail.iter().position(|b| *b == b'\n'))
            .map(|i| from + i);
        match newline {
            Some(at) => {
                let mut line = buf.split_to(at + 1);
                self.searched = 0;
                if std::mem::take(&mut self.discarding) {
                    // The end of an over-long line whose start is already gone.
                    return Ok(Some(RawLine::Discarded(Discarded::TooLong)));
                }
                line.truncate(at);
                Ok(Some(self.finish_line(line)))
            }
            None => {
                // +1: the line may still end in a CR that does not count. Subtracted from the
                // buffer rather than added to the maximum: `usize::MAX` ("no limit") must not
                // overflow (issue 29 O).
                if buf.len().saturating_sub(1) > self.max_len {
                    if !self.discarding {
                        tracing::warn!(
                            max = self.max_len,
                            "line codec: line exceeds the maximum length, skipping to its end"
                        );
                    }
                    self.discarding = true;
                    buf.advance(buf.len());
                    self.searched = 0;
                } else {
                    self.searched = buf.len();
                }
                Ok(None)
            }
        }
    }

    /// [`Decoder::decode_eof`], the line left in `buf`'s memory.
    fn decode_eof_raw(&mut self, buf: &mut BytesMut) -> Result<Option<RawLine>, std::io::Error> {
        if let Some(line) = self.decode_raw(buf)? {
            return Ok(Some(line));
        }
        // An unterminated last line: hand it on as a line (the peer closed after it).
        self.searched = 0;
        if self.reject_unterminated && (self.discarding || !buf.is_empty()) {
            self.discarding = false;
            buf.clear();
            return Err(std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                "the connection ended in the middle of a line",
            ));
        }
        if buf.is_empty() {
            return Ok(if std::mem::take(&mut self.discarding) {
                Some(RawLine::Discarded(Discarded::TooLong))
            } else {
                None
            });
        }
        let rest = buf.split();
        if std::mem::take(&mut self.discarding) {
            return Ok(Some(RawLine::Discarded(Discarded::TooLong)));
        }
        Ok(Some(self.finish_line(rest)))
    }
}

impl Decoder for LineCodec {
    type Item = Line;
    type Error = std::io::Error;

    fn decode(&mut self, buf: &mut BytesMut) -> Result<Option<Line>, std::io::Error> {
        Ok(self.decode_raw(buf)?.map(RawLine::into_line))
    }

    fn decode_eof(&mut self, buf: &mut BytesMut) -> Result<Option<Line>, std::io::Error> {
        Ok(self.decode_eof_raw(buf)?.map(RawLine::into_line))
    }
}

impl Encoder<&str> for LineCodec {
    type Error = std::io::Error;

    /// Writes `line` and a LF. Refuses a line that holds a LF or CR (it would be two commands)
    /// or is longer than the maximum.
    fn encode(&mut self, line: &str, dst: &mut BytesMut) -> Result<(), std::io::Error> {
        if line.bytes().any(|b| b == b'\n' || b == b'\r') {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "a line must not contain LF or CR",
            ));
        }
        if line.len() > self.max_len {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!("line of {} bytes exceeds {}", line.len(), self.max_len),
            ));
        }
        dst.reserve(line.len() + 1);
        dst.put_slice(line.as_bytes());
        dst.put_u8(b'\n');
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode_all(codec: &mut LineCodec, chunks: &[&[u8]]) -> Vec<Line> {
        let mut buf = BytesMut::new();
        let mut out = Vec::new();
        for chunk in chunks {
            buf.extend_from_slice(chunk);
            while let Some(line) = codec.decode(&mut buf).unwrap() {
                out.push(line);
            }
        }
        out
    }

    fn text(s: &str) -> Line {
        Line::Text(s.into())
    }

    #[test]
    fn lines_with_and_without_cr() {
        let mut c = LineCodec::new(16);
        assert_eq!(
            decode_all(&mut c, &[b"ACK\nDEVSTATE[0]=3\r\n\n"]),
            vec![text("ACK"), text("DEVSTATE[0]=3"), text("")]
        );
    }

    #[test]
    fn split_anywhere() {
        let mut c = LineCodec::new(16);
        let chunks: Vec<&[u8]> = b"ACK\nERR 04\n".iter().map(std::slice::from_ref).collect();
        assert_eq!(
            decode_all(&mut c, &chunks),
            vec![text("ACK"), text("ERR 04")]
        );
    }

    #[test]
    fn over_long_line_in_many_chunks_is_skipped_with_bounded_memory() {
        let mut c = LineCodec::new(8);
        let mut buf = BytesMut::new();
        for _ in 0..1000 {
            buf.extend_from_slice(b"0123456789");
            assert_eq!(c.decode(&mut buf).unwrap(), None);
            assert!(buf.len() <= 20, "buffer grew to {}", buf.len());
        }
        buf.extend_from_slice(b"tail\nACK\n");
        assert_eq!(
            c.decode(&mut buf).unwrap(),
            Some(Line::Discarded(Discarded::TooLong))
        );
        assert_eq!(c.decode(&mut buf).unwrap(), Some(text("ACK")));
    }

    #[test]
    fn non_ascii_is_discarded_and_decoding_continues() {
        let mut c = LineCodec::new(16);
        assert_eq!(
            decode_all(
                &mut c,
                &[b"ID=\"\xc3\xa9\"\nACK\n", b"0123456789abcdefg\nACK\n"]
            ),
            vec![
                Line::Discarded(Discarded::NotAscii),
                text("ACK"),
                Line::Discarded(Discarded::TooLong),
                text("ACK")
            ]
        );
    }

    #[test]
    fn exact_max_with_cr_is_accepted() {
        let mut c = LineCodec::new(4);
        assert_eq!(decode_all(&mut c, &[b"ABCD\r", b"\n"]), vec![text("ABCD")]);
    }

    #[test]
    fn eof_flushes_an_unterminated_line() {
        let mut c = LineCodec::new(16);
        let mut buf = BytesMut::from(&b"BYE()"[..]);
        assert_eq!(c.decode_eof(&mut buf).unwrap(), Some(text("BYE()")));
        assert_eq!(c.decode_eof(&mut buf).unwrap(), None);
    }

    #[test]
    fn strict_eof_refuses_an_unterminated_line() {
        let mut c = LineCodec::new(16).reject_unterminated();
        let mut buf = BytesMut::from(&b"ACK\nVALUE[0][0]=12"[..]);
        assert_eq!(c.decode_eof(&mut buf).unwrap(), Some(text("ACK")));
        let err = c.decode_eof(&mut buf).unwrap_err();
        assert_eq!(err.kind(), std::io::ErrorKind::UnexpectedEof);
        assert_eq!(c.decode_eof(&mut BytesMut::new()).unwrap(), None);
    }

    /// `usize::MAX` means "no limit": the length check must not overflow (issue 29 O; it
    /// panicked in a debug build as soon as a partial line was buffered).
    #[test]
    fn no_limit_does_not_overflow() {
        let mut c = LineCodec::new(usize::MAX);
        let mut buf = BytesMut::from(&b"ACK\nVALUE[0][0]=1"[..]);
        assert_eq!(c.decode(&mut buf).unwrap(), Some(text("ACK")));
        assert_eq!(c.decode(&mut buf).unwrap(), None);
        buf.extend_from_slice(b"2\n");
        assert_eq!(c.decode(&mut buf).unwrap(), Some(text("VALUE[0][0]=12")));
        let mut dst = BytesMut::new();
        c.encode("ID?", &mut dst).unwrap();
        assert_eq!(&dst[..], b"ID?\n");
    }

    #[test]
    fn encoder_refuses_line_breaks() {
        let mut c = LineCodec::new(16);
        let mut dst = BytesMut::new();
        c.encode("ID?", &mut dst).unwrap();
        assert_eq!(&dst[..], b"ID?\n");
        assert!(c.encode("ID?\nBYE()", &mut dst).is_err());
        assert!(c.encode("LABEL=\"x\"\r", &mut dst).is_err());
        assert!(c.encode(&"X".repeat(17), &mut dst).is_err());
        assert_eq!(&dst[..], b"ID?\n");
    }
}
