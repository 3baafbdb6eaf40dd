//! The async client: a cheap, cloneable handle to a background task that owns the connection.
//!
//! # Pairing rules
//! The WSG protocol has no sequence numbers: a reply carries only its command id (manual
//! 1.2.2). These rules decide which request a reply answers, and when the client answers on
//! its own. TCP and serial deliver replies in the order sent and lose none (a reply with a bad
//! checksum aside, which is dropped like a lost one); UDP loses, duplicates and reorders.
//!
//! | Rule | Manual | Sound on | Residual risk |
//! |------|--------|----------|---------------|
//! | One request per id on the wire; the next call of the id queues behind it; other ids run concurrently. | 1.2.2 | all | none by itself |
//! | A timed-out or dropped call keeps its id until its reply, or its deadline plus [`ClientBuilder::late_reply_grace`]; the late reply is discarded. | 1.2.2 | all | UDP: a reply later than the grace is taken for the next call of the id (datagrams keep no order: no barrier can prove that none is still on its way) |
//! | TCP, serial, attached streams: a request released with no reply at all *fences* its id: the next request of the id waits for the echo of a loop-back (0x06, unique payload) sent at the release, and a reply of the id before that echo is the late one (dropped). A released motion goes back under recovery (below) at its E_CMD_PENDING, if that still comes before the echo, or at the echo (its E_CMD_PENDING may have been corrupted while the move runs: its final reply must not complete the next request). | 1.2.2, 1.3, 3.1.1 | TCP, serial | the manual does not state in so many words that a connection's immediate replies keep the order of its commands (its request-reply scheme implies it); an acknowledged non-motion command (finger power on, 3.6.3) is fenced too, never before [`FINGER_POWER_ON_DURATION`] + grace after it was sent or acknowledged (whichever is later: a request held on the way reaches the device late), so that its final reply, sent when it ended, comes before the echo: a device that takes longer to end it than its release gets that reply taken for the next call of the id; while no echo comes, calls of the fenced id time out (on TCP and serial an unanswered loop-back keeps its id [`ClientBuilder::partial_frame_timeout`] (at least [`DEFAULT_PARTIAL_FRAME_TIMEOUT`]) longer than other requests, so the line rests that long between barriers: a device whose decoder waits for silence to drop a frame with a corrupted length, as the simulator's does, gets it; the manual does not say how the device recovers: one that needs longer silence than a barrier's query timeout + partial frame timeout + grace may keep the id fenced); a device that answers three barriers in a row with something other than their echo gets the id released as on UDP |
//! | E_CMD_PENDING acknowledges; the final reply follows and ends the call. | 1.3 | all | — |
//! | No request keeps its id for ever: a caller with a timeout of its own (also one longer than the connection's, [`Client::with_timeouts`]) keeps it until its deadline + grace (a motion command, whose E_CMD_PENDING comes at once, only until [`ClientBuilder::query_timeout`] + grace after it was sent while unacknowledged); a caller without timeout (`Duration::MAX`), or one that dropped the call (noticed when the next call of the id comes), keeps it, unacknowledged, until [`ClientBuilder::query_timeout`] ([`DEFAULT_QUERY_TIMEOUT`] when that is `Duration::MAX`: the client's own loop-back barriers, which have no deadline, are bounded so too) + grace after it was sent, then it is released (fenced on streams) and a caller still waiting gets [`Error::Timeout`] naming that timeout; acknowledged, a motion goes under recovery (below) [`ClientBuilder::motion_timeout`] after it was sent (the query timeout after it was sent when the motion timeout is `Duration::MAX`: recovery releases only on evidence, so it may start early). | 1.2.2, 1.3 (the reply or E_CMD_PENDING comes at once) | all | a raw request whose *immediate* reply the device sends later than the query timeout + grace (none in the manual) is released before it; an acknowledged non-motion command keeps its id until its caller's deadline + grace, and at least [`FINGER_POWER_ON_DURATION`] + grace after it was sent or acknowledged |
//! | An E_CMD_PENDING after a final reply that had none may be that request's, reordered: it acknowledges the next request only doubtfully, and E_ALREADY_RUNNING still ends it. | 1.3 | all (needed on UDP) | UDP: a duplicated request's refusal, in that situation, ends the call as refused |
//! | E_ALREADY_RUNNING for an acknowledged request refuses a duplicate of it: dropped. A loop reply that does not echo the payload on the wire is not its reply. | 1.3, 3.1.1 | all | — |
//! | A second motion call of an id on the wire waits; the device's state is asked at once: SF_MOVING from a query sent after the call refuses it (E_ALREADY_RUNNING, unsent); the first's final reply, or two "not moving" a grace apart, sends it. Never refused on belief. | 3.2.2, Anhang B | all | SF_MOVING is not synchronised with the end of a move (Anhang B): a refusal right at a move's end; a final reply later than a grace after the second "not moving" goes to the next call |
//! | An acknowledged motion past its caller's deadline keeps its id until its final reply or two "not moving" a grace apart ([`Error::ReplyLost`] for a caller still waiting). | 1.3, Anhang B | all | as above |
//! | Stop and FAST STOP are never queued; a stop call is `Ok` only on a reply to a stop sent at or after it (each reply is taken for the oldest unanswered stop); a call still waiting [`RESEND_STOP_AFTER`] later gets the stop sent again. TCP, serial: no stop is given up on time (its reply may be stalled for any time); a stop unanswered [`RESEND_STOP_AFTER`] after it was sent gets a barrier (a loop-back) instead, and is sent again only when its echo proves the earlier stops lost (request or reply damaged). A stop is a safety command: one proven lost is sent again **even after its caller stopped waiting** (timed out, dropped), up to [`MAX_STOP_RESENDS`] times in a row, until the device answers one, unless the device accepted (E_CMD_PENDING) a motion command (home, pre-position, grasp, release) sent after it: then it is dropped (logged), as a late stop would abort that newer motion; a motion refused at once ran nothing and drops nothing, and one unanswered at the echo decides by its answer. | 1.2.2, 3.1.1, 3.2.3, 3.2.4 | TCP, serial | TCP, serial: after a corrupted stop reply, a call waits [`RESEND_STOP_AFTER`] and a round trip longer; a stop whose caller stopped waiting may reach the device up to a few round trips after the call returned (stopping whatever moves then, short of a motion the program started after it); a barrier waits behind any loop-back already on the wire (one per id), so a re-send can take the query timeout + grace longer when that one's echo was lost; a stop proven lost while a motion sent after it has no answer yet is held until that answer, and when that motion's request or answer was lost too, until the device's word under recovery (its caller's deadline, then two "not moving" a grace apart): seconds, 13 s in the explorer's `wsg-serial:0xde1245ed22975681`, where two motions in a row were lost; a stop dropped for a motion whose acknowledgement never came (lost) is not sent again; a device that answers three barriers in a row with something other than their echo gets the stops given up unproven. UDP: a stop reply later than the grace, or duplicated, is taken for a later stop; a stop sent again may arrive after `stop()` returned and abort a move started right after |
//! | A frame must complete within [`ClientBuilder::partial_frame_timeout`] from its first byte; a header longer than any reply of its id is noise at once; while a frame is held, no id is released. | 1.2.1, chapter 3 | TCP, serial (UDP: one frame per datagram) | a plausible corrupted length holds replies for up to the timeout |
//! | Once a value's updates were switched on over a connection, every later request of that id on it (TCP, serial) is followed by a loop-back (0x06, unique payload) and answered by the last E_SUCCESS frame of the id received before its echo: the reply, or an update sent after it; a frame that is not E_SUCCESS is no update and answers at once. An echo with no frame of the id before it: the request got no reply, and no later frame answers it. A frame dropped as damaged (bad checksum, bytes skipped as noise, a partial frame dropped after a silence) between the request and the echo may have been the reply, and the last frame then an update sent before the device read the request: the request is sent again, with a loop-back of its own (a query or a stream's switch, both idempotent), at most 3 times; after that it takes no answer and ends at its deadline (`Timeout`; without one, at the query timeout + grace after its last send). Ids never streamed on the connection get no loop-back. | 1.4, 3.4.1–3.4.6 (an update and the reply share id and form), 3.1.1 | TCP, serial | a request the device drops as corrupt (no reply, manual 1.2.1) is answered by an update received before the echo: a value the device sent during the call, not its answer (nothing on the wire tells them apart); for the same reason no answer proves that updates were switched off, so the loop-back stays until the connection ends. UDP: the request takes the next frame of its id, which may be an update sent before the device received it (at most one period older); the subscribe call's own reply cannot be told from an update either (same status, same data) |
//! | Frames already received are paired before the next request goes out: a request freed by a reply waits until no frame is ready to be read (a copy of that reply, already received, is then dropped as unsolicited). | 1.2.2 | all (needed on UDP) | UDP: a duplicated reply that arrives after the next request of its id went out is taken for it |

mod builder;
mod commands;
mod connector;
mod pairing;
mod stops;
mod task;

pub use self::builder::ClientBuilder;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::Duration;

use bytes::Bytes;
use tokio::net::ToSocketAddrs;
use tokio::sync::mpsc::error::TrySendError;
use tokio::sync::{mpsc, oneshot};
use tokio::time::{timeout_at, Instant};

use self::connector::Reconnect;
use self::task::Msg;
use super::command::{id, Command};
use super::subscription::{Subscriber, Subscription, UpdateOptions};
use super::transport::TransportKind;
use super::types::decode_f32;
use super::{Error, Frame, GripState, Reply, Result, Status, SystemState};
use crate::connection::Connection;
use crate::deadline::after;
use crate::reconnect::{ConnectionEvents, EventSubscriber};
use crate::supervisor::CloseRequest;

/// Default timeout of queries and settings.
pub const DEFAULT_QUERY_TIMEOUT: Duration = Duration::from_secs(1);
/// Default timeout of motion commands (homing, pre-position, grasp, release), from sending to
/// the final reply. (Finger power on has its own: [`FINGER_POWER_ON_DURATION`] plus the query
/// timeout.)
pub const DEFAULT_MOTION_TIMEOUT: Duration = Duration::from_secs(30);
/// Default time an unanswered request keeps its command id after its caller's deadline.
pub const DEFAULT_LATE_REPLY_GRACE: Duration = Duration::from_secs(2);
/// How long switching a finger's power on takes: its final reply comes "nach etwa 500 ms"
/// (manual 3.6.3). [`Client::set_finger_power`] waits this long plus the query timeout.
pub const FINGER_POWER_ON_DURATION: Duration = Duration::from_millis(500);
/// How long a stop (or FAST STOP) call waits for a reply to a stop sent at or after it before
/// the stop is sent again (on TCP and serial: before a loop-back checks whether the stop's reply
/// was lost, see [`Client`]): far above a stop's round trip, far below a call's timeout.
pub const RESEND_STOP_AFTER: Duration = stops::RESEND_AFTER;

/// On TCP and serial, how many times in a row a stop (or FAST STOP) whose caller stopped
/// waiting is sent again, each time after a loop-back's echo proved the one before lost,
/// before the client gives it up (see [`Client`]: a stop is delivered even after its call
/// returned).
pub const MAX_STOP_RESENDS: u32 = stops::MAX_OWED_RESENDS;
/// Default timeout of a TCP connect (see [`ClientBuilder::connect_timeout`]).
pub const DEFAULT_CONNECT_TIMEOUT: Duration = Duration::from_secs(5);
/// Default silence after which a partial frame is dropped as noise (see
/// [`ClientBuilder::partial_frame_timeout`]).
pub const DEFAULT_PARTIAL_FRAME_TIMEOUT: Duration = Duration::from_millis(500);
/// Connection events each [`Client::connection_events`] stream buffers, at most (a slower
/// reader gets [`ConnectionEvent::Missed`](crate::reconnect::ConnectionEvent::Missed)).
pub const EVENT_BUFFER: usize = 32;
/// Default buffer of each subscription, in updates.
pub const DEFAULT_SUBSCRIPTION_BUFFER: usize = 64;

#[derive(Debug)]
struct Shared {
    /// The background task; calls poll it inline to send their requests (see `crate::connection`).
    connection: Connection,
    tx: mpsc::Sender<Msg>,
    unsubscribe: mpsc::UnboundedSender<(u8, u64)>,
    subscription_buffer: usize,
    next_key: AtomicU64,
    kind: TransportKind,
    /// Why the connection broke for good, once it did.
    lost: Arc<OnceLock<String>>,
    events: EventSubscriber,
    /// Set when a handle asks to close: the task stops reconnecting at once.
    close: CloseRequest,
}

impl Shared {
    /// The error for a call that finds the task gone: lost connection or closed client.
    fn gone(&self) -> Error {
        match self.lost.get() {
            Some(reason) => Error::lost(reason.as_str()),
            None => Error::Closed,
        }
    }
}

/// A handle to a WSG gripper: `Clone + Send + Sync`, any number of tasks may call it at once.
///
/// One background task owns the connection (calls poll it inline to send their requests: see
/// [Where a client's work runs](crate#where-a-clients-work-runs)). Replies are paired with requests by command id:
/// calls with different ids run concurrently, calls with the same id are queued, with two
/// exceptions:
/// - **Stop and FAST STOP are never queued** (manual 3.2.3: "stoppt unmittelbar jede laufende
///   Fingerbewegung"): each [`Client::stop`] / [`Client::fast_stop`] is sent at once, whatever is
///   on the wire, even while an earlier stop's reply is outstanding or lost. A stop call
///   succeeds only on a reply to a stop sent at or after the call (a reply acknowledges "the
///   received command", 1.2.2; an earlier stop may have been processed before a move that
///   started afterwards). Their replies carry no data, so each reply is taken for the oldest
///   stop still unanswered, and a call still waiting [`RESEND_STOP_AFTER`] later gets the stop
///   sent again (a lost UDP datagram) until its reply comes or its timeout ends. Sound on TCP
///   and serial (ordered): there no stop counts as lost on time, however long its reply is
///   stalled; a loop-back (0x06) is sent instead, and only its echo, which comes after the
///   reply to every earlier command, proves an unanswered stop lost (its request or its reply
///   damaged) and gets the stop sent again. A stop is a safety command: on TCP and serial one
///   proven lost is sent again **even after its caller stopped waiting** (the call returned
///   [`Error::Timeout`] or was dropped), until the device answers one (at most
///   [`MAX_STOP_RESENDS`] times in a row), unless the program sent a motion command (home, pre-position, grasp, release) after
///   it that the device accepted: then the program has moved on, and the stop is dropped
///   (logged) rather than abort that newer motion. On UDP a stop reply later than the late-reply grace past its
///   caller's deadline (for a caller without timeout, past the query timeout from its send), or
///   a duplicated one, could be taken for a later stop, and a stop sent again may arrive after
///   `stop()` returned and stop a move started right after (it then fails with
///   E_CMD_ABORTED). A pending move fails with E_CMD_ABORTED.
/// - **A second motion command (homing, pre-position, grasp, release) of an id on the wire is
///   answered by the device's state, never by a belief**: the protocol cannot pair two
///   requests of one id, so the call waits, and the client asks the device's system state
///   (0x40) at once. If a query sent after the call says the fingers move (SF_MOVING), the call
///   is refused with [`Error::Device`] / [`Status::AlreadyRunning`] without being sent, as the
///   device refuses a motion command while another runs (3.2.2); a `grasp` during a
///   `pre_position` (another id) is sent and refused by the device itself. If the first move's
///   final reply comes, the call is sent and the device answers it; if the device says twice,
///   a [`ClientBuilder::late_reply_grace`] apart, that it does not move while no final reply
///   came, that reply is lost: the first call fails with [`Error::ReplyLost`] and the second is
///   sent. So after `stop()` the next move works whatever order the move's E_CMD_ABORTED and
///   the stop's reply arrive in (the manual fixes none; UDP reorders), and one lost final reply
///   costs the next move about one grace period, not the first call's whole timeout.
///
/// Motion commands resolve on their final reply (after E_CMD_PENDING).
///
/// Every call has a timeout ([`ClientBuilder::query_timeout`], [`ClientBuilder::motion_timeout`],
/// or per handle with [`Client::with_timeouts`]) covering queueing, sending and the final reply.
/// A call that times out or whose future is dropped does not desync the connection: its request
/// keeps its command id until its late reply arrives, and that reply is discarded. Because the
/// protocol has no sequence numbers, an unanswered (and unacknowledged) request gives up its id
/// after its deadline plus [`ClientBuilder::late_reply_grace`]. On UDP only a reply later than
/// that could be taken for the next request of the same id. On TCP and serial not even that:
/// the next request of the id waits until the echo of a loop-back (0x06) sent at the release
/// comes back; the stream keeps the device's replies in order, so a reply of the id before the
/// echo is the late one (dropped), and none can come after it.
///
/// # Lost final replies
/// A request the device acknowledged (E_CMD_PENDING, manual 1.3) holds its command id until its
/// final reply, but never for good, so one lost frame cannot block an id for the life of the
/// connection:
/// - **finger power on** (0x62/0x72): the final reply comes "nach etwa 500 ms" (3.6.3), so the
///   call waits [`FINGER_POWER_ON_DURATION`] plus the query timeout, then fails with
///   [`Error::Timeout`]; its id is released a grace period later (on TCP and serial fenced by
///   a loop-back barrier, whose echo comes after the final reply the device sent when the
///   power-on ended), never before [`FINGER_POWER_ON_DURATION`] + grace after it was sent or
///   acknowledged, whichever is later;
/// - **raw requests** ([`Client::request`], [`Client::request_with_timeout`]): the call's timeout
///   is the bound; the id is released a grace period after it, except for a motion command's
///   id (0x20, 0x21, 0x25, 0x26), which is recovered like a motion command (below);
/// - **motion commands**: a move may outlast its caller's timeout, so the id is not released on
///   time alone. From the caller's deadline on (or, before it, as soon as another call of
///   the id waits), the client asks the device's system state (0x40) every grace period, and
///   releases the id only when two answers in a row, from queries sent after that point and a
///   grace period apart, say the fingers do not move (SF_MOVING clear) and no final reply came
///   in between; a caller still waiting then gets [`Error::ReplyLost`]. One answer is not
///   enough: Anhang B says the flags are not synchronised with the end of a move, UDP may
///   reorder the final reply behind the answer, and while 0x40 is streamed the answer may be a
///   stream frame sent just before the query arrived. A call of that id made meanwhile waits
///   for the verdict: it is sent once the id is released, or refused with E_ALREADY_RUNNING
///   when a query sent after it finds the device moving.
///
/// In each case the residual risk is a final reply later than the grace period (for a move:
/// later than a grace period after the device said twice that it stopped): it would be taken
/// for the next call of the same id. The loop-back barrier (above) cannot close it: a final
/// reply comes when the command ends, not in the order of the commands.
///
/// # A misbehaving wire
/// What the client does about each fault (each one is tested through the fault proxy in
/// `tests/wsg_faults.rs`):
/// - a reply with a bad checksum is dropped (checking it is the client's job, manual 1.2.2:
///   "Die Auswertung obliegt dem Client"); its call ends in a timeout (or, should the device
///   answer a corrupted request with E_CHECKSUM_ERROR, which the manual does not specify,
///   [`Error::Device`] with that code);
/// - a reply whose checksum passes but whose status is not E_SUCCESS while it carries data is
///   dropped as damaged too (data comes only with E_SUCCESS, PROTOCOLS.md §1): a CRC16 lets
///   about one damaged frame in 65,536 through, and noise inserted after a header was once read
///   as status 7111. (Where the field may differ: a device that sent data with a refusal would
///   see those calls time out.) Damage elsewhere in a frame that the checksum misses stays a
///   residual risk of the wire;
/// - a header longer than any reply of its command id (a corrupted length) is skipped at once;
///   one that is plausible but never completes is dropped
///   [`ClientBuilder::partial_frame_timeout`] after its first byte, however many bytes follow,
///   and the frames behind it are decoded; meanwhile no id is released, so a reply held behind
///   it still reaches its own request (or is discarded as late), never a newer one;
/// - a lost reply ends its call in a timeout; a lost E_CMD_PENDING changes nothing (the final
///   reply ends the call); a lost final reply times its call out, and its id comes back as
///   [Lost final replies](Client#lost-final-replies) says; a lost stop reply holds up no later
///   stop; a lost (corrupted) E_CMD_PENDING of a motion command whose call timed out before
///   any reply came keeps the id under recovery (its final reply may still come);
/// - a duplicated reply is dropped when no request of its id is on the wire. Frames already
///   received are paired before the next request goes out, and a loop reply must echo its own
///   payload; otherwise, without sequence numbers, a copy arriving after the next request of
///   its id went out would be taken as its answer (it carries the same value unless the device
///   changed in between);
/// - a duplicated motion request while the first still moves is refused by the device with
///   E_ALREADY_RUNNING, which cannot be the final reply of an acknowledged move and is
///   dropped; a move that already ended runs a second time (to the same target), and its second
///   pair of replies is dropped as unsolicited;
/// - a cut connection fails the calls in flight with [`Error::ConnectionLost`] (see
///   [`ClientBuilder::reconnect`]).
///
/// While a value is streamed ([`Client::subscribe_width_mm`] and friends), a one-off query of
/// it is sent with the stream's flags, so it does not switch the device's updates off (FLAGS bit0
/// clear would). An update and the reply share id and form (manual 1.4), so on TCP and serial
/// a query of a value that was streamed on the connection is followed by a loop-back and
/// answered by the last frame of that value received before its echo: the reply, or an update
/// sent after the device received the query (one round trip more). When a damaged frame came
/// before the echo (it may have been the reply) the query is asked again. On UDP it is answered
/// by the next frame of that value, which may be an update sent before the device received the
/// query (at most one period older).
///
/// # Cancellation
/// Every method is cancel-safe for the connection: dropping its future at any await point (a
/// `select!`, a timeout, an aborted task) never desyncs the client. A request not sent yet
/// (waiting in the request queue or behind a request of the same id) is never sent. A request
/// already sent keeps its command id until its reply arrives; that reply is consumed and
/// discarded, never handed to another call. Cancelling does **not** undo the command on the
/// device: a setting that was sent takes effect, and a motion command that was sent keeps the
/// fingers moving to its end — send [`Client::stop`] (or [`Client::fast_stop`]) to stop them.
/// Whether a dropped call had been sent cannot be told from outside: query the state (e.g.
/// [`Client::system_state`]) when it matters.
///
/// The connection closes when [`Client::close`] is called or the last handle is dropped (with the
/// disconnect announcement on TCP either way). Call [`Client::close`] before the runtime shuts
/// down: a task cancelled with its runtime cannot announce anything.
#[derive(Clone, Debug)]
pub struct Client {
    shared: Arc<Shared>,
    query_timeout: Duration,
    motion_timeout: Duration,
}

impl Client {
    /// A builder with the default configuration.
    pub fn builder() -> ClientBuilder {
        ClientBuilder::default()
    }

    /// Connects over TCP with the default configuration.
    ///
    /// Cancel-safe: a dropped call leaves nothing behind.
    pub async fn connect_tcp(addr: impl ToSocketAddrs) -> Result<Client> {
        ClientBuilder::default().connect_tcp(addr).await
    }

    /// A handle on the same connection whose calls use these timeouts: `query` for queries,
    /// settings and raw requests ([`Client::request`]), `motion` for motion commands.
    ///
    /// Each call gets exactly its timeout, shorter or longer than the connection's
    /// ([`ClientBuilder::query_timeout`], [`ClientBuilder::motion_timeout`]): a device that
    /// answers before it is heard, and a call that times out fails with [`Error::Timeout`]
    /// naming this timeout. Its request keeps its command id until its deadline plus
    /// [`ClientBuilder::late_reply_grace`] (see [`Client`]); a motion under recovery is
    /// probed from its deadline on. A motion command's acknowledgement (E_CMD_PENDING, sent
    /// at once, manual 1.3) is awaited the connection's query timeout + grace after it was
    /// sent: without it the call fails with [`Error::Timeout`] naming that timeout. The connection's timeouts still bound a request as a
    /// *hold* when no deadline does: with `Duration::MAX` ("no timeout"), an unanswered
    /// request is released the connection's query timeout (or, when that is `Duration::MAX`
    /// too, [`DEFAULT_QUERY_TIMEOUT`]) + grace after it was sent (the call
    /// fails with [`Error::Timeout`] naming that timeout), and an
    /// acknowledged motion is probed from the connection's motion timeout after it was sent
    /// (from its query timeout when the motion timeout is `Duration::MAX` too) (released only on evidence that its final reply is lost: [`Error::ReplyLost`]; its
    /// "not moving" probes go on a grace period apart until then), and an acknowledged finger
    /// power on is released the query timeout + [`FINGER_POWER_ON_DURATION`] + grace after it
    /// was sent ([`Error::Timeout`]). A call dropped before its reply keeps its id no longer than that hold either, once another
    /// call of the id wants it: nobody waits for the reply.
    #[must_use]
    pub fn with_timeouts(&self, query: Duration, motion: Duration) -> Client {
        Client {
            shared: self.shared.clone(),
            query_timeout: query,
            motion_timeout: motion,
        }
    }

    /// The connection's events from now on: each loss, and with
    /// [`ClientBuilder::reconnect`] each attempt and recovery (each is also logged with
    /// `tracing`). The stream ends when the client has closed or given up. It buffers
    /// [`EVENT_BUFFER`] events; a slower reader gets
    /// [`ConnectionEvent::Missed`](crate::reconnect::ConnectionEvent::Missed) instead of the
    /// oldest ones.
    pub fn connection_events(&self) -> ConnectionEvents {
        self.shared.events.subscribe()
    }

    /// Whether the connection is closed for good: [`Client::close`] was called, the last
    /// handle's task ended, or the connection was lost and no reconnect policy brings it back
    /// (every call fails with [`Error::Closed`] or [`Error::ConnectionLost`]). While the client
    /// reconnects it is not closed. The same as the other protocols' `is_closed`.
    pub fn is_closed(&self) -> bool {
        // The task closes its queue when it ends (see `task::run`).
        self.shared.tx.is_closed()
    }

    /// The transport this client uses.
    pub fn transport(&self) -> TransportKind {
        self.shared.kind
    }

    /// Sends `frame` and returns its final reply, whatever its status.
    async fn exchange(&self, frame: Frame, timeout: Duration) -> Result<Reply> {
        let command = frame.id;
        let deadline = after(Instant::now(), timeout);
        let (reply, rx) = oneshot::channel();
        let msg = Msg::Call {
            frame,
            deadline,
            reply,
        };
        self.send_and_wait(msg, rx, deadline, command, timeout)
            .await
    }

    /// Hands `msg` to the task and waits for its reply, all within the deadline (a full request
    /// channel counts against it too).
    async fn send_and_wait(
        &self,
        msg: Msg,
        rx: oneshot::Receiver<Result<Reply>>,
        deadline: Instant,
        command: u8,
        timeout: Duration,
    ) -> Result<Reply> {
        let work = async {
            // The queue nearly always has room: `try_send` skips building and polling a permit
            // future (issue 14). Fair all the same: a released permit goes to a waiting sender
            // before `try_send` can take it.
            match self.shared.tx.try_send(msg) {
                Ok(()) => {}
                Err(TrySendError::Full(msg)) => self
                    .shared
                    .tx
                    .send(msg)
                    .await
                    .map_err(|_| self.shared.gone())?,
                Err(TrySendError::Closed(_)) => return Err(self.shared.gone()),
            }
            rx.await.map_err(|_| self.shared.gone())?
        };
        // Pinned in place, as GRIPLINK's is: handed on by value, the future (the request, a
        // timer) was copied twice more, by `memcpy`, into the connection's call (BENCHMARKS.md,
        // "Issue 30: the last of SmartGrasp's cost").
        let work = std::pin::pin!(timeout_at(deadline, work));
        self.shared
            .connection
            .call(work)
            .await
            .map_err(|_| Error::Timeout { command, timeout })?
    }

    /// Sends a typed command and returns the data of its E_SUCCESS reply; any other final status
    /// is [`Error::Device`].
    ///
    /// Cancel-safe for the connection; a command that was sent takes effect (a motion keeps moving)
    /// even if the call is dropped (see [Cancellation](Client#cancellation)).
    pub async fn command(&self, command: Command) -> Result<Bytes> {
        command
            .validate()
            .map_err(|reason| Error::invalid("command argument", reason))?;
        let timeout = match command {
            // Not a move: its final reply comes after a known time (3.6.3).
            Command::FingerPower(_, true) => {
                self.query_timeout.saturating_add(FINGER_POWER_ON_DURATION)
            }
            _ if command.is_async() => self.motion_timeout,
            _ => self.query_timeout,
        };
        let reply = self.exchange(command.to_frame(), timeout).await?;
        success(reply)
    }

    /// Sends a command the crate has no type for (e.g. scripting commands) and returns its final
    /// reply (after E_CMD_PENDING, if the device sends one) with whatever status it has, within
    /// the query timeout. If the final reply does not come by then, the call fails with
    /// [`Error::Timeout`] and the id is released [`ClientBuilder::late_reply_grace`] later (see
    /// [Lost final replies](Client#lost-final-replies)); use
    /// [`Client::request_with_timeout`] for a command that takes longer. A raw request with a
    /// motion command's id (0x20, 0x21, 0x25, 0x26) is paired like that motion command: once
    /// acknowledged, its id is not released on time but by probing whether the device still
    /// moves, and a second call of the id waits for the device's state (see [`Client`]).
    ///
    /// Cancel-safe for the connection; a command that was sent takes effect (a motion keeps moving)
    /// even if the call is dropped (see [Cancellation](Client#cancellation)).
    pub async fn request(&self, id: u8, payload: impl Into<Bytes>) -> Result<Reply> {
        self.request_with_timeout(id, payload, self.query_timeout)
            .await
    }

    /// [`Client::request`] with an explicit timeout, which also bounds how long an acknowledged
    /// request may wait for its final reply (see [Lost final replies](Client#lost-final-replies)).
    ///
    /// Cancel-safe for the connection; a command that was sent takes effect (a motion keeps moving)
    /// even if the call is dropped (see [Cancellation](Client#cancellation)).
    pub async fn request_with_timeout(
        &self,
        id: u8,
        payload: impl Into<Bytes>,
        timeout: Duration,
    ) -> Result<Reply> {
        let payload = payload.into();
        if id == 0xAA {
            // The decoder reads AA runs as preamble (see frame.rs): a reply with id 0xAA could
            // not be received reliably.
            return Err(Error::invalid(
                "command id",
                "0xAA cannot be framed unambiguously",
            ));
        }
        if payload.len() > usize::from(u16::MAX) {
            return Err(Error::invalid(
                "payload",
                format!("{} bytes exceed 65535", payload.len()),
            ));
        }
        self.exchange(Frame::new(id, payload), timeout).await
    }

    async fn query<T>(
        &self,
        command: Command,
        decode: fn(&[u8]) -> std::result::Result<T, String>,
    ) -> Result<T> {
        let id = command.id();
        let data = self.command(command).await?;
        decode(&data).map_err(|reason| Error::MalformedReply {
            command: id,
            reason,
        })
    }

    async fn no_data(&self, command: Command) -> Result<()> {
        self.command(command).await.map(drop)
    }

    async fn subscribe<T>(
        &self,
        id: u8,
        options: UpdateOptions,
        decode: fn(&[u8]) -> std::result::Result<T, String>,
    ) -> Result<Subscription<T>> {
        let mode = options
            .to_mode()
            .map_err(|reason| Error::invalid("update options", reason))?;
        let (tx, rx) = mpsc::channel(self.shared.subscription_buffer);
        let key = self.shared.next_key.fetch_add(1, Ordering::Relaxed);
        let missed = Arc::new(AtomicU64::new(0));
        // Created first so that an early return unsubscribes (Drop) again.
        let subscription = Subscription {
            rx,
            id,
            key,
            unsubscribe: self.shared.unsubscribe.clone(),
            missed: missed.clone(),
            decode,
        };
        let timeout = self.query_timeout;
        let deadline = after(Instant::now(), timeout);
        let (reply, rx) = oneshot::channel();
        let subscriber = Subscriber { key, tx, missed };
        let msg = Msg::Subscribe {
            id,
            mode,
            subscriber,
            deadline,
            reply,
        };
        let reply = self.send_and_wait(msg, rx, deadline, id, timeout).await?;
        success(reply)?;
        Ok(subscription)
    }

    /// A stream of the system state flags (0x40 with auto-update).
    ///
    /// Cancel-safe: a dropped call leaves no subscriber behind (the device's updates are turned off
    /// again if nobody else streams the value).
    pub async fn subscribe_system_state(
        &self,
        options: UpdateOptions,
    ) -> Result<Subscription<SystemState>> {
        self.subscribe(id::SYSTEM_STATE, options, SystemState::decode)
            .await
    }

    /// A stream of the grip state (0x41 with auto-update).
    ///
    /// Cancel-safe: a dropped call leaves no subscriber behind (the device's updates are turned off
    /// again if nobody else streams the value).
    pub async fn subscribe_grip_state(
        &self,
        options: UpdateOptions,
    ) -> Result<Subscription<GripState>> {
        self.subscribe(id::GRIP_STATE, options, GripState::decode)
            .await
    }

    /// A stream of the opening width in mm (0x43 with auto-update).
    ///
    /// Cancel-safe: a dropped call leaves no subscriber behind (the device's updates are turned off
    /// again if nobody else streams the value).
    pub async fn subscribe_width_mm(&self, options: UpdateOptions) -> Result<Subscription<f32>> {
        self.subscribe(id::WIDTH, options, decode_f32).await
    }

    /// A stream of the finger speed in mm/s (0x44 with auto-update).
    ///
    /// Cancel-safe: a dropped call leaves no subscriber behind (the device's updates are turned off
    /// again if nobody else streams the value).
    pub async fn subscribe_speed_mm_per_s(
        &self,
        options: UpdateOptions,
    ) -> Result<Subscription<f32>> {
        self.subscribe(id::SPEED, options, decode_f32).await
    }

    /// A stream of the finger force in N (0x45 with auto-update).
    ///
    /// Cancel-safe: a dropped call leaves no subscriber behind (the device's updates are turned off
    /// again if nobody else streams the value).
    pub async fn subscribe_force_n(&self, options: UpdateOptions) -> Result<Subscription<f32>> {
        self.subscribe(id::FORCE, options, decode_f32).await
    }

    /// Closes the connection: on TCP, announces the disconnect (0x07) and waits for its reply
    /// first, so the gripper does not go into FAST STOP. The announcement also **stops every
    /// finger motion at once** (manual 3.1.2: "werden alle laufenden Fingerbewegungen des
    /// Greifmoduls unmittelbar gestoppt"), whichever client started it: a move in flight, of
    /// this or any other handle, ends with E_CMD_ABORTED. Calls still waiting fail with
    /// [`Error::Closed`], streams end, and every other handle's calls fail with
    /// [`Error::Closed`] (or [`Error::ConnectionLost`] if the connection had broken).
    ///
    /// While the client reconnects ([`ClientBuilder::reconnect`]), in a backoff wait or an
    /// attempt, it stops at once and this returns `Ok(())`: the client is closed, calls still
    /// queued fail with [`Error::Closed`], and so does every later call. Nothing is announced:
    /// there is no connection (on TCP the loss put the gripper into FAST STOP already, as its
    /// [`ConnectionEvent::Lost`](crate::reconnect::ConnectionEvent::Lost) said). A second
    /// `close()` returns what a close after the end returns ([`Error::Closed`]).
    ///
    /// Cancel-safe: once the request reached the task, the close completes even if this call is
    /// dropped.
    pub async fn close(&self) -> Result<()> {
        // Seen by a reconnecting task at once, in a backoff wait or an attempt: it stops and
        // the client ends closed (the request below waits in the queue it no longer reads).
        let first = self.shared.close.request();
        let (done, rx) = oneshot::channel();
        let close = async {
            self.shared
                .tx
                .send(Msg::Close { done })
                .await
                .map_err(|_| self.shared.gone())?;
            rx.await.map_err(|_| self.shared.gone())?
        };
        let asked = self.shared.connection.call(close).await;
        self.shared.close.outcome(first, asked)
    }
}

fn success(reply: Reply) -> Result<Bytes> {
    if reply.status == Status::Success {
        Ok(reply.data)
    } else {
        Err(Error::Device {
            command: reply.id,
            status: reply.status,
        })
    }
}

fn not_available_as_none<T>(r: Result<T>) -> Result<Option<T>> {
    match r {
        Ok(v) => Ok(Some(v)),
        Err(Error::Device {
            status: Status::NotAvailable,
            ..
        }) => Ok(None),
        Err(e) => Err(e),
    }
}
