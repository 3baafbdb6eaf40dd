//! An in-process WSG gripper that speaks the binary protocol over TCP, UDP, a serial
//! pseudo-terminal or any byte stream (feature `sim`, on by default).
//!
//! [`device`] is the pure state machine (homing, moves with trapezoidal profiles within the
//! model's limits, the grip states of Anhang C, stop and FAST STOP, soft limits, force,
//! overdrive, auto-updates, tag, statistics, finger interface); [`SimServer`] serves it.
//!
//! # Time scale
//!
//! [`SimConfig::time_scale`] is wall seconds per simulated second of motion. In-process,
//! [`SimConfig::new`] uses 0: a move's final reply follows its E_CMD_PENDING at once, so tests
//! cost no wall time (use [`SimServer::set_time_scale`] with e.g. 1000 to have a move still
//! running when a stop arrives). The standalone simulators (`wsg_simulator`, `gripctl sim wsg`)
//! serve [`SimConfig::standalone`], **real time** (1): a move lasts as long as on the device, so
//! any client can exercise stop, FAST STOP, E_CMD_ABORTED and E_ALREADY_RUNNING (manual 1.3,
//! 3.2); `--time-scale 0` makes them instant. Auto-update periods are always wall-clock.
//!
//! # Transports as on the device
//!
//! - **TCP**: an unannounced close (no 0x07 first, manual 3.1.2) triggers FAST STOP (1.4.2); the
//!   move it aborts answers its owner with E_CMD_ABORTED, whichever session that is. The end of
//!   a client's byte stream (half-close) ends its session, but every reply due up to then is
//!   written first; frames received before a failed write (e.g. a reset) are still handled, so a
//!   0x07 sent before closing always counts. A client that does not read its replies is not
//!   read either once 256 replies wait (backpressure): no reply is dropped for want of room,
//!   and its auto-updates pause meanwhile.
//! - **UDP**: one frame per datagram. Replies go to the sender's address, or with
//!   [`SimConfig::udp_remote_port`] to the sender's IP address at that port whatever port the
//!   request came from: the device's "UDP remote port" setting, which public UDP drivers rely
//!   on (`PROTOCOLS.md`, WSG field notes). A UDP session silent for
//!   [`SimConfig::udp_idle_timeout`] (60 s) is forgotten, unless a move's final reply or
//!   auto-updates it switched on are still due to it; at most [`MAX_UDP_SESSIONS`] are kept.
//! - **Bytes that make no frame**: a partial frame that gets no new byte for
//!   [`DEFAULT_PARTIAL_FRAME_TIMEOUT`](crate::wsg::client::DEFAULT_PARTIAL_FRAME_TIMEOUT) is
//!   dropped as noise (the client is stricter: it times a frame from its first byte, and knows
//!   each reply's longest length). A frame with a bad checksum is discarded unanswered:
//!   the manual does not say what the device does with one (it lists E_CHECKSUM_ERROR in
//!   Anhang A under no command; 1.2.1 only discards frames *missing* their checksum), and an
//!   answer under a possibly corrupted id could fail an unrelated caller.
//!   [`SimConfig::answer_bad_checksum`] answers E_CHECKSUM_ERROR instead, to test a client's
//!   handling of that code.
//!
//! # Text interface (GCL)
//!
//! With [`SimConfig::text`] (`wsg_simulator --text`, `gripctl sim wsg --text`) TCP connections
//! speak the text interface ([`wsg::text`](crate::wsg::text)) instead of frames, served from
//! the same device (one motion model, one state; the module `text` says how each GCL command
//! maps onto the binary ones and which readings it takes where no source says). Replies end in
//! LF only, each line is one write, and [`SimConfig::text_ack_gap`] separates a motion's `ACK`
//! from its `FIN`, as the public GCL drivers need. A close without `BYE()` raises FAST STOP
//! like an unannounced binary close, unless [`SimConfig::fast_stop_on_close`] is off.
//!
//! Where the manual is silent the simulator's choice is documented on the item concerned: an
//! auto-update period under the 10 ms minimum runs at 10 ms (0x40–0x45 list no refusal for
//! it); finger queries with parameters get E_CMD_FORMAT_ERROR (3.6.1–3.6.4).

mod commands;
pub mod device;
mod model;
mod motion;
mod server;
mod sessions;
mod text;

// Inlined, so that this page lists them with their summaries.
#[doc(inline)]
pub use device::{Device, Out, SessionId, SessionKind};
pub use model::{Model, Part, SimConfig, SimFinger, DEFAULT_UDP_IDLE_TIMEOUT, MAX_UDP_SESSIONS};
pub use server::{SimEvent, SimRecord, SimRecording, SimServer, SimSnapshot};
pub use sessions::MIN_UPDATE_PERIOD_MS;
