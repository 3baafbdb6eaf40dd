//! The WSG's text interface, GCL ("Gripper Control Language"): the ASCII command set a WSG
//! speaks on its TCP port instead of the binary protocol when "Use text based interface" is set
//! in its web interface (Settings → Command Interface).
//!
//! ```text
//! → FSACK()            ← ACK FSACK
//! → HOME()             ← ACK HOME   … ← FIN HOME
//! → POS?               ← POS=110.0
//! → GRIP(40,20,50)     ← ACK GRIP   … ← FIN GRIP      (or ← ERR GRIP 18)
//! → AUTOSEND("POS",50) ← ACK AUTOSEND, then ← @POS=20.0 every 50 ms
//! → BYE()              ← ACK BYE
//! ```
//!
//! Layers: [`line`](mod@line) encodes commands and parses replies (pure, fuzzed); [`Client`] is the async
//! client (a task owns the connection, the handle is `Clone`, every call has a timeout);
//! [`Pushes`] streams `AUTOSEND` values. The simulator serves GCL from the same device model as
//! the binary one: [`SimConfig::text`](crate::wsg::sim::SimConfig::text).
//!
//! # Where each rule comes from
//!
//! Weiss's GCL manual is not among our specs; we have its chapter 2 ("Basic Command Set") and
//! the code of public drivers (the repository's research note `WSG-TEXT-INTERFACE.md`, whose
//! section numbers are cited as §). Every rule this module relies on is one of three kinds:
//!
//! **Pinned by the manual's chapter 2:**
//! - the commands `VERBOSE=n`, `BYE()`, `HOME()`/`HOME(0|1)`, `MOVE(p[,v])`, `GRIP([f[,w[,v]]])`,
//!   `RELEASE([d[,v]])`, `PWT`/`CLT` (`?` and `=`), `POS?`, `SPEED?`, `FORCE?`, `GRIPSTATE?`, and
//!   their replies `ACK <NAME>` / `FIN <NAME>` / `NAME=value`;
//! - `HOME(1)` is positive, `HOME(0)` negative (the binary protocol numbers 1/2);
//! - `RELEASE` opens **by a pull-back distance**, relative to where the fingers are (the binary
//!   protocol's release takes an absolute width); it is allowed only after a grip;
//! - a grip with a part width that finds no part fails with E_CMD_FAILED, a collision before
//!   the tolerance zone with E_AXIS_BLOCKED; `GRIP()`/`GRIP(f)` always end HOLDING;
//! - PWT and CLT last for the connection only;
//! - a close without `BYE()` raises FAST STOP, which blocks motion;
//! - `GRIPSTATE=4` is HOLDING.
//!
//! **Pinned by clients that ran on real grippers:**
//! - replies end in LF only, one reply per line; the name in `ACK`/`FIN`/`ERR` is the bare
//!   upper-case command name (§2, §3);
//! - `ERR` lines carry the command name as second token (§4.3, inferred from a client's use);
//! - `STOP()`, `FASTSTOP()` and `FSACK()` exist; `STOP()` and `FSACK()` answer with an `ACK`
//!   only, `FSACK()` also with no FAST STOP pending; STOP returns the grip state to IDLE (§3.7);
//! - the gripper reads and answers queries, STOP and FASTSTOP while a motion runs (§3.7): this
//!   client pairs replies by name, so a query resolves while a `MOVE` waits for its `FIN`;
//! - `MOVE` works while a part is held (§3.4);
//! - pushes read `@NAME=value`, and `AUTOSEND("POS",50)` is the command's form (§3.10).
//!
//! **Our reading (a guess where no source says; documented as such):**
//! - the numeral code in `ERR` lines uses the WSG binary table ([`Status`](crate::wsg::Status));
//!   [`Error::Device`] keeps the raw line beside it (§4.3, §6.1);
//! - the `AUTOSEND` interval is in ms, its third argument means "only on change", it answers
//!   `ACK AUTOSEND`, and an interval of 0 stops it (§3.10);
//! - `TEMP?` answers `TEMP=<°C>` (§3.9);
//! - what a second motion does while one runs (the simulator refuses it, `ERR MOVE 4`, §6.2);
//! - the line length limit (this client: [`ClientConfig::max_line_len`], 256 bytes).
//!
//! # Pairing, timeouts, cancellation
//!
//! Replies carry no id, only the command's name: one command of each name is on the wire at a
//! time, and a second call with that name waits in the client until the first is answered.
//! Queries use [`ClientConfig::query_timeout`], motions [`ClientConfig::motion_timeout`] up to
//! their `FIN` or `ERR`. A call that times out or whose future is dropped after its line was
//! sent keeps its name busy until the reply comes, which is then consumed and handed to nobody;
//! a command still queued when its caller leaves is never sent. A reply that stays away
//! [`ClientConfig::give_up_after`] past its call's timeout ends the connection
//! ([`Error::ConnectionLost`]): a later line with that name could no longer be paired with
//! confidence. An `ERR` line without a command name, or a line that is not GCL, is logged and
//! dropped (its caller times out) rather than failing a caller it may not belong to. A motion's
//! `FIN` comes after its `ACK` (§3): a `FIN` read before the `ACK` of the motion on the wire,
//! with no unreadable line since that motion was written, belongs to an earlier motion of the
//! name and ends nothing. (Where the field might differ: a gripper that sent a `FIN` without
//! its `ACK` would see such a motion end by its timeout, not by that `FIN`. The manual and the
//! public drivers have the `ACK` at once, §3.) An `ERR` line holding another reply run into
//! its text (an LF damaged into `*` or `J`) counts as unreadable, whole: the `ERR` part too,
//! so that motion ends as one whose `ERR` could not be read, never with a code the damage may
//! have touched.
//!
//! A line damaged on its way to the gripper may read as another command's name (`GRIPSTATE?` as
//! `GRIP…`), answered `ERR GRIP 15` (format error; 14, unknown command). Such an `ERR` read while
//! a command written before that `GRIP` still waits for its reply is held, not handed to GRIP:
//! the gripper answers in order, so the next reply tells whose it was. GRIP's own `ACK`, or a
//! reply to a line written before GRIP, shows it answered an earlier line (which then fails as
//! one whose reply could not be read); a reply to a line written after GRIP shows it was GRIP's.
//! When no such reply is due, the client writes a query of its own to draw one. If a line that
//! could not be read came after a motion's held `ERR` (it may have been the motion's `ACK`),
//! the client asks the gripper whether the motion runs: its own moving state says the `ERR` was
//! another line's; twice no motion, with nothing unreadable since, says it was the motion's
//! own; anything else leaves the call to time out rather than take a refusal that may be
//! another line's. Residual risk, inherent in GCL: a call whose deadline comes first gets the
//! held `ERR` just before it, as it would have without the doubt; the `FIN` rule above then keeps the replies that follow
//! from shifting onto later calls of the name. (Where the field might differ: the codes are our
//! reading of the binary table, §4.3; on a gripper that numbered otherwise the rule holds a
//! refusal a moment, never hands it to another call.)
//!
//! The client writes a query on its own now and then (`GRIPSTATE?`, `POS?`, `SPEED?` or
//! `FORCE?`, whichever name is free): after a reply line it could not read, to learn which
//! calls lost their reply, and for an acknowledged motion past its give-up time (or one whose
//! refusal is in doubt), to learn whether it still runs. A call of the
//! same query made before such a line was written takes its answer (the gripper read that
//! very line after the call was made) instead of writing the query again.
//!
//! # Memory bounds
//! Reply lines longer than [`ClientConfig::max_line_len`] are skipped to their LF without being
//! buffered; calls wait in a channel of [`ClientConfig::queue_len`] and at most as many again
//! behind a busy name; each [`Pushes`] stream buffers [`ClientConfig::push_buffer`] values and
//! counts the ones it drops ([`Pushes::missed`]).
//!
//! # Example
//! ```
//! # #[cfg(feature = "sim")]
//! # #[tokio::main(flavor = "current_thread")]
//! # async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use gripper::wsg::{sim, text, GripState, HomingDirection};
//!
//! let config = sim::SimConfig::new(sim::Model::Wsg50).with_part(40.0, 2.0).text();
//! let simulator = sim::SimServer::bind("127.0.0.1:0", config).await?;
//! let gripper = text::Client::connect(simulator.local_addr().expect("TCP")).await?;
//! gripper.ack_fast_stop().await?;
//! gripper.home(HomingDirection::Default).await?;
//! gripper.grip_part(40.0, 40.0, Some(50.0)).await?;
//! assert_eq!(gripper.grip_state().await?, GripState::Holding);
//! gripper.release(Some(10.0), None).await?; // opens BY 10 mm
//! assert_eq!(gripper.position_mm().await?, 50.0);
//! gripper.close().await?; // BYE(): no FAST STOP
//! # Ok(())
//! # }
//! # #[cfg(not(feature = "sim"))]
//! # fn main() {}
//! ```

mod book;
mod client;
mod error;
pub mod line;
mod push;
mod task;

pub use client::{Client, ClientConfig};
pub use error::{Error, Result};
pub use push::{Push, Pushes, Quantity};
