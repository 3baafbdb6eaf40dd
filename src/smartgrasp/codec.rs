//! tokio-util codecs: [`ClientCodec`] (requests out, responses in) and [`ServerCodec`] (requests
//! in, responses out), over the pure [`peek_frame`].
//!
//! The prefix is read first (manual 1.3: a client must not assume 80 bytes). Length 74 is a frame
//! (V3, or V4 when the prefix says 4: both are 80 bytes, PROTOCOLS.md 2b); length 0 is the
//! "server too old" empty message; any other length is refused before a
//! byte of it is buffered: the field is a u32, and a hostile 4 GB length must not allocate 4 GB.
//! Frames carry no start marker, so after a bad length the stream cannot be resynchronised: the
//! decoder returns `Err`, which ends the stream, and the connection is reported broken.

use bytes::{Buf, BytesMut};
use tokio_util::codec::{Decoder, Encoder};

use super::error::{Error, Malformed};
use super::frame::{
    AnyRequestFrame, AnyResponseFrame, Prefix, FRAME_LEN, PREFIX_LEN, PROTOCOL_VERSION, V3_LENGTH,
};

/// What the bytes at the front of a buffer hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Peeked {
    /// Not enough bytes yet; `needed` more would complete the prefix or the frame.
    Incomplete {
        /// Bytes still missing.
        needed: usize,
    },
    /// A complete frame, V3 or V4 (the first 80 bytes).
    Frame([u8; FRAME_LEN]),
    /// An empty message: a prefix with length 0 (the first 6 bytes). From a server, it means
    /// "too old" and `version` is its highest version (manual 1.3).
    Empty {
        /// The prefix's version.
        version: u16,
    },
}

/// Looks at the front of `bytes` without consuming anything. `Err` carries a prefix whose length
/// is neither 74 nor 0.
pub fn peek_frame(bytes: &[u8]) -> Result<Peeked, Prefix> {
    let Some(head) = bytes.first_chunk::<PREFIX_LEN>() else {
        return Ok(Peeked::Incomplete {
            needed: PREFIX_LEN - bytes.len(),
        });
    };
    let prefix = Prefix::decode(head);
    match prefix.length {
        0 => Ok(Peeked::Empty {
            version: prefix.version,
        }),
        V3_LENGTH => match bytes.first_chunk::<FRAME_LEN>() {
            Some(frame) => Ok(Peeked::Frame(*frame)),
            None => Ok(Peeked::Incomplete {
                needed: FRAME_LEN - bytes.len(),
            }),
        },
        _ => Err(prefix),
    }
}

/// How long the frame at the front of `bytes` is, in any protocol version: the 6-byte prefix plus
/// its `length` field (manual 1.3). `None` until the prefix is complete. Unlike [`peek_frame`] it
/// does not judge the length: it cuts a stream into frames (`proxy_frame_len`, feature `sim`,
/// does it for the fault proxy).
pub fn frame_len(bytes: &[u8]) -> Option<usize> {
    let prefix = Prefix::decode(bytes.first_chunk::<PREFIX_LEN>()?);
    // Saturating: on a 32-bit target a hostile u32 length must not wrap to a small frame.
    Some(PREFIX_LEN.saturating_add(usize::try_from(prefix.length).unwrap_or(usize::MAX)))
}

/// [`frame_len`] in the fault proxy's terms, so that its faults hit whole SmartGrasp frames:
/// `ProxyConfig::new().framing(Framing::Custom(codec::proxy_frame_len))` (see
/// [`crate::fault`]). A length over the proxy's `max_frame_len` is forwarded unframed.
#[cfg(feature = "sim")]
pub fn proxy_frame_len(bytes: &[u8]) -> crate::fault::FrameLen {
    use crate::fault::FrameLen;
    frame_len(bytes).map_or(FrameLen::NeedMore, FrameLen::Complete)
}

/// What [`take`] cut off the front of a buffer.
enum Taken {
    Frame([u8; FRAME_LEN]),
    Empty { version: u16 },
}

/// Consumes one frame or empty message from `src`, or reserves room for the rest of it (never
/// more than one frame, whatever the prefix says). `Err`: a length that is neither 74 nor 0.
fn take(src: &mut BytesMut) -> Result<Option<Taken>, Malformed> {
    match peek_frame(src) {
        Ok(Peeked::Incomplete { needed }) => {
            src.reserve(needed);
            Ok(None)
        }
        Ok(Peeked::Frame(bytes)) => {
            src.advance(FRAME_LEN);
            Ok(Some(Taken::Frame(bytes)))
        }
        Ok(Peeked::Empty { version }) => {
            src.advance(PREFIX_LEN);
            Ok(Some(Taken::Empty { version }))
        }
        Err(prefix) => Err(Malformed::FrameLength {
            length: prefix.length,
        }),
    }
}

/// The client side: encodes request frames, decodes [`AnyResponseFrame`]s (the layout the
/// prefix's version says).
///
/// Decoder errors: [`Error::ServerTooOld`] for an empty message from a server older than
/// [`version`](Self::version) before the server said its
/// [`server_version`](Self::server_version), [`Malformed::FrameLength`] for any other empty
/// message and any length but 74 and 0. Each ends the stream.
#[derive(Debug, Clone, Copy)]
pub struct ClientCodec {
    /// The protocol version the client sends: an empty message with a lower version says the
    /// server is older (manual 1.3).
    pub version: u16,
    /// The highest version the server said it speaks on this connection (its answer to
    /// GET_PROTOCOL_VERSION), once known. A client never sends a version above it, so from
    /// then on the server has no cause to send an empty message: one that arrives is a damaged
    /// frame ([`Malformed::FrameLength`]), never [`Error::ServerTooOld`], whatever version it
    /// claims.
    pub server_version: Option<u16>,
}

impl ClientCodec {
    /// A codec for a client sending protocol `version`, the server's version not yet known.
    pub fn new(version: u16) -> ClientCodec {
        ClientCodec {
            version,
            server_version: None,
        }
    }
}

impl Default for ClientCodec {
    /// A V3 client's codec (every server since V3 answers V3 in full).
    fn default() -> Self {
        ClientCodec::new(PROTOCOL_VERSION)
    }
}

impl Decoder for ClientCodec {
    type Item = AnyResponseFrame;
    type Error = Error;

    fn decode(&mut self, src: &mut BytesMut) -> Result<Option<AnyResponseFrame>, Error> {
        match take(src)? {
            None => Ok(None),
            Some(Taken::Frame(bytes)) => Ok(Some(AnyResponseFrame::decode(&bytes))),
            // Only a server older than this client answers with an empty message (manual 1.3);
            // one that claims this client's version or newer is a damaged frame, not a version
            // answer. So is one that claims less than the server said it speaks on this
            // connection: a damaged request draws an empty message, and a damaged byte of it
            // then forged "too old" (smartgrasp-v3:0xd2a532f64f1247cd).
            Some(Taken::Empty { version })
                if version < self.version && self.server_version.is_none() =>
            {
                Err(Error::ServerTooOld {
                    server_version: version,
                    client_version: self.version,
                })
            }
            Some(Taken::Empty { .. }) => Err(Malformed::FrameLength { length: 0 }.into()),
        }
    }

    fn decode_eof(&mut self, src: &mut BytesMut) -> Result<Option<AnyResponseFrame>, Error> {
        match self.decode(src)? {
            Some(frame) => Ok(Some(frame)),
            None if src.is_empty() => Ok(None),
            // Say what happened rather than the default "bytes remaining on stream".
            None => Err(Error::ConnectionLost {
                reason: format!(
                    "the server closed the connection in the middle of a frame ({} bytes of it)",
                    src.len()
                )
                .into(),
            }),
        }
    }
}

impl<F: Into<AnyRequestFrame>> Encoder<F> for ClientCodec {
    type Error = Error;

    fn encode(&mut self, item: F, dst: &mut BytesMut) -> Result<(), Error> {
        dst.extend_from_slice(&item.into().encode());
        Ok(())
    }
}

/// The server side: decodes [`AnyRequestFrame`]s of any version whose length is 74, encodes
/// response frames and bare [`Prefix`]es (the "too old" empty message).
///
/// Any other length is an `Err` ([`Malformed::FrameLength`]) that ends the stream; the prefix is
/// still in the read buffer, so a server can answer a newer client "too old" first (manual 1.3).
#[derive(Debug, Clone, Copy, Default)]
pub struct ServerCodec;

impl Decoder for ServerCodec {
    type Item = AnyRequestFrame;
    type Error = Error;

    fn decode(&mut self, src: &mut BytesMut) -> Result<Option<AnyRequestFrame>, Error> {
        match take(src)? {
            None => Ok(None),
            Some(Taken::Frame(bytes)) => Ok(Some(AnyRequestFrame::decode(&bytes))),
            // A request with no body has no meaning in any version.
            Some(Taken::Empty { .. }) => Err(Malformed::FrameLength { length: 0 }.into()),
        }
    }
}

impl<F: Into<AnyResponseFrame>> Encoder<F> for ServerCodec {
    type Error = Error;

    fn encode(&mut self, item: F, dst: &mut BytesMut) -> Result<(), Error> {
        dst.extend_from_slice(&item.into().encode());
        Ok(())
    }
}

/// The "too old" empty message.
impl Encoder<Prefix> for ServerCodec {
    type Error = Error;

    fn encode(&mut self, item: Prefix, dst: &mut BytesMut) -> Result<(), Error> {
        dst.extend_from_slice(&item.encode());
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::smartgrasp::frame::ResponseFrame;
    use crate::smartgrasp::types::{MessageType, ResponseCode};
    use proptest::prelude::*;

    fn response(counter: u8) -> AnyResponseFrame {
        let mut f = ResponseFrame::new(MessageType::GetState, ResponseCode::Success, counter);
        f.server_state = crate::smartgrasp::ServerState::Operational;
        f.into()
    }

    #[test]
    fn partial_frames_wait_and_reserve_at_most_one_frame() {
        let bytes = response(1).encode();
        let mut buf = BytesMut::from(&bytes[..3]);
        assert!(ClientCodec::default().decode(&mut buf).unwrap().is_none());
        buf.extend_from_slice(&bytes[3..50]);
        assert!(ClientCodec::default().decode(&mut buf).unwrap().is_none());
        assert!(buf.capacity() < 4096);
        buf.extend_from_slice(&bytes[50..]);
        assert_eq!(
            ClientCodec::default().decode(&mut buf).unwrap(),
            Some(response(1))
        );
        assert!(buf.is_empty());
    }

    #[test]
    fn empty_message_is_server_too_old() {
        let mut buf = BytesMut::from(
            &Prefix {
                version: 2,
                length: 0,
            }
            .encode()[..],
        );
        let err = ClientCodec::default().decode(&mut buf).unwrap_err();
        assert!(matches!(
            err,
            Error::ServerTooOld {
                server_version: 2,
                client_version: 3
            }
        ));
    }

    #[test]
    fn empty_message_after_the_server_said_its_version_is_malformed_not_server_too_old() {
        let empty = |version| BytesMut::from(&Prefix { version, length: 0 }.encode()[..]);
        let said_v3 = ClientCodec {
            server_version: Some(3),
            ..ClientCodec::default()
        };
        for version in [2, 3] {
            let err = { said_v3 }.decode(&mut empty(version)).unwrap_err();
            assert!(
                matches!(
                    err,
                    Error::MalformedReply(Malformed::FrameLength { length: 0 })
                ),
                "{version}: {err:?}"
            );
        }
        // Before the server said its version, the same message is its "too old" answer.
        let err = ClientCodec::default().decode(&mut empty(2)).unwrap_err();
        assert!(matches!(err, Error::ServerTooOld { .. }), "{err:?}");
    }

    #[test]
    fn frame_len_is_prefix_plus_length_field() {
        let frame = response(7).encode();
        assert_eq!(frame_len(&frame[..5]), None);
        assert_eq!(frame_len(&frame[..6]), Some(FRAME_LEN));
        assert_eq!(frame_len(&frame), Some(FRAME_LEN));
        let empty = Prefix {
            version: 2,
            length: 0,
        }
        .encode();
        assert_eq!(frame_len(&empty), Some(PREFIX_LEN));
        let hostile = Prefix {
            version: 3,
            length: u32::MAX,
        }
        .encode();
        assert_eq!(frame_len(&hostile), Some(PREFIX_LEN + u32::MAX as usize));
    }

    #[test]
    fn an_empty_message_from_a_server_as_new_as_this_client_is_malformed() {
        let mut buf = BytesMut::from(
            &Prefix {
                version: 3,
                length: 0,
            }
            .encode()[..],
        );
        assert!(matches!(
            ClientCodec::default().decode(&mut buf),
            Err(Error::MalformedReply(Malformed::FrameLength { length: 0 }))
        ));
    }

    #[test]
    fn end_of_stream_inside_a_frame_is_a_closed_connection() {
        let bytes = response(1).encode();
        let mut buf = BytesMut::from(&bytes[..30]);
        assert!(matches!(
            ClientCodec::default().decode_eof(&mut buf),
            Err(Error::ConnectionLost { reason }) if reason.contains("30 bytes")
        ));
        let mut buf = BytesMut::from(&bytes[..]);
        assert_eq!(
            ClientCodec::default().decode_eof(&mut buf).unwrap(),
            Some(response(1))
        );
        assert_eq!(ClientCodec::default().decode_eof(&mut buf).unwrap(), None);
    }

    #[test]
    fn hostile_length_is_refused_without_allocating() {
        let mut buf = BytesMut::from(
            &Prefix {
                version: 3,
                length: u32::MAX,
            }
            .encode()[..],
        );
        let err = ClientCodec::default().decode(&mut buf).unwrap_err();
        assert!(matches!(
            err,
            Error::MalformedReply(Malformed::FrameLength { length: u32::MAX })
        ));
        assert!(buf.capacity() < 4096);
        let mut buf = BytesMut::from(
            &Prefix {
                version: 3,
                length: 75,
            }
            .encode()[..],
        );
        assert!(ServerCodec.decode(&mut buf).is_err());
    }

    proptest! {
        /// Any split of a valid stream decodes to the same frames.
        #[test]
        fn any_split_decodes_to_the_same_frames(
            counters in proptest::collection::vec(any::<u8>(), 1..6),
            cuts in proptest::collection::vec(0usize..480, 0..8),
        ) {
            let frames: Vec<AnyResponseFrame> = counters.iter().map(|&c| response(c)).collect();
            let stream: Vec<u8> = frames.iter().flat_map(|f| f.encode()).collect();
            let mut cuts: Vec<usize> = cuts.into_iter().map(|c| c % (stream.len() + 1)).collect();
            cuts.push(stream.len());
            cuts.sort_unstable();
            let mut buf = BytesMut::new();
            let mut out = Vec::new();
            let mut start = 0;
            for cut in cuts {
                buf.extend_from_slice(&stream[start..cut]);
                start = cut;
                while let Some(f) = ClientCodec::default().decode(&mut buf).unwrap() {
                    out.push(f);
                }
            }
            prop_assert_eq!(out, frames);
            prop_assert!(buf.is_empty());
        }

        /// Whatever the bytes, decoding never panics and never holds more than one frame.
        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
            let mut buf = BytesMut::from(&bytes[..]);
            while let Ok(Some(_)) = ClientCodec::default().decode(&mut buf) {}
            let mut buf = BytesMut::from(&bytes[..]);
            while let Ok(Some(_)) = ServerCodec.decode(&mut buf) {}
        }
    }
}
