//! Weiss WSG grippers' binary command protocol (WSG 50, 32, 25, 70) over TCP, UDP and RS-232.
//!
//! Layers, each usable alone:
//! - [`checksum`]: the manual's CRC table and update rule (Anhang D);
//! - [`frame`]: pure encode/decode of `AA AA AA | id | len | payload | crc` frames, resyncing
//!   byte-wise on noise; [`WsgCodec`]: the tokio-util codec over it;
//! - [`command`], [`types`], [`Status`]: typed commands, reply data and status codes;
//! - [`Client`]: the async client (cancel-safe calls, optional reconnect, and what it does under
//!   each wire fault: see its docs); [`Subscription`]: auto-update streams;
//! - `sim` (feature `sim`): a simulated gripper serving TCP, UDP and a serial pseudo-terminal.
//!
//! # Memory bounds
//! Nothing the wire sends can make the client's memory grow without limit:
//! - **Frames**: a reply payload longer than
//!   [`ClientBuilder::max_payload_len`] (default [`frame::DEFAULT_MAX_PAYLOAD_LEN`] = 4096 bytes,
//!   a frame of 4104) is noise: its header is skipped. A request payload is at most 65535 bytes
//!   (the length field); the client refuses longer ones before sending.
//! - **Stream decoder** (TCP, serial): garbage before a preamble is dropped as it is scanned, so
//!   the buffer holds at most one partial frame plus one socket read: 8 KiB with the default
//!   maximum (tokio-util's read buffer), under any flood of garbage (tested). A partial frame
//!   that gets no new byte for [`ClientBuilder::partial_frame_timeout`] is dropped as noise.
//! - **UDP**: one receive buffer of one maximum frame per client; longer datagrams are cut to it
//!   and fail their checksum.
//! - **Request queue**: [`ClientBuilder::request_queue`] requests (default 64) between the
//!   handles and the task; a caller waits for a slot within its timeout.
//! - **Per command id**: one request on the wire, the others queued behind it (except stop and
//!   FAST STOP, never queued, and a motion command, refused while one of its id runs: see
//!   [`Client`]); a queued request whose caller is gone is dropped when the next one is queued,
//!   so the queue holds at most one request per live caller. A request on the wire whose caller
//!   left holds its id until its reply, or its deadline plus [`ClientBuilder::late_reply_grace`]
//!   (an acknowledged move: its final reply, or the device saying twice, a grace period apart,
//!   that it no longer moves; see [Lost final replies](Client#lost-final-replies)). Stop
//!   requests waiting for a reply are at most one per live caller too.
//! - **Subscriptions**: each subscriber buffers [`ClientBuilder::subscription_buffer`] updates
//!   (default 64); a slow consumer misses the newest updates while its buffer is full, counted by
//!   [`Subscription::missed`], and reads the older buffered ones first (tested).
//! - The unsubscribe channel holds at most one message per live subscription.
//! - **Connection events**: each [`Client::connection_events`] stream buffers
//!   [`client::EVENT_BUFFER`] events; a slower reader loses the oldest and is told how many.
//!
//! What a checksum cannot catch: random bytes pass the 16-bit checksum about once in 65536
//! candidate frames. A loop reply is checked against its payload, and a reply with no request of
//! its id on the wire is dropped, but noise that forms a valid reply to a pending query would be
//! taken for its answer, and such a frame of a subscribed id is delivered as an auto-update; the
//! protocol has no stronger check. The manual's checksum (Anhang D, not a catalogue CRC: see
//! [`checksum`]) catches every single flipped bit and every burst of up to 11 bits in a 14-byte
//! frame, but not every 2-bit error (50 of that frame's 6,216 bit pairs pass) nor every burst of
//! 12–16 bits; inserted serial line noise or a corrupted length field passes by chance.
//!
//! # Example
//! ```
//! # #[cfg(feature = "sim")]
//! # #[tokio::main(flavor = "current_thread")]
//! # async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use gripper::wsg::{sim, Client, GripState, HomingDirection};
//!
//! // A simulated WSG 50 with a 40 mm part between the fingers; motion takes no wall time.
//! let config = sim::SimConfig::new(sim::Model::Wsg50).with_part(40.0, 2.0);
//! let simulator = sim::SimServer::bind("127.0.0.1:0", config).await?;
//! let addr = simulator.local_addr().expect("TCP server has an address");
//!
//! let gripper = Client::connect_tcp(addr).await?;
//! println!("{:?}", gripper.system_info().await?);
//! gripper.home(HomingDirection::Default).await?;
//! gripper.pre_position(60.0, 100.0).await?;
//! gripper.grasp(40.0, 50.0).await?;
//! assert_eq!(gripper.grip_state().await?, GripState::Holding);
//! gripper.release(60.0, 100.0).await?;
//! gripper.close().await?; // announces the disconnect (0x07): no FAST STOP
//! # Ok(())
//! # }
//! # #[cfg(not(feature = "sim"))]
//! # fn main() {}
//! ```

pub mod checksum;
pub mod codec;
pub mod command;
mod error;
pub mod frame;
mod status;
pub mod types;

#[doc(inline)]
pub use codec::WsgCodec;
#[doc(inline)]
pub use command::{Command, HomingDirection, Reply, UpdateMode};
#[doc(inline)]
pub use error::{Error, Result};
#[doc(inline)]
pub use frame::Frame;
#[doc(inline)]
pub use status::Status;
#[doc(inline)]
pub use types::{
    DeviceType, Finger, FingerFlags, FingerInfo, FingerType, FirmwareVersion, GraspingStatistics,
    GripState, SoftLimits, SystemInfo, SystemLimits, SystemState,
};
pub mod client;
pub mod subscription;
pub mod text;
pub mod transport;

#[doc(inline)]
pub use client::{Client, ClientBuilder};
#[doc(inline)]
pub use subscription::{Subscription, UpdateOptions};
#[doc(inline)]
pub use transport::TransportKind;
// `DEFAULT_PORT`, as in the other protocols' modules.
#[doc(inline)]
pub use transport::DEFAULT_TCP_PORT as DEFAULT_PORT;
#[cfg(feature = "sim")]
pub mod sim;
