//! The background task that owns the transport (the model of rodbus's channel task): it sends
//! requests, pairs replies (see [`super::pairing`]), fans auto-updates out to
//! subscribers, and is the one place where requests fail when the connection goes.

use std::io;
use std::pin::pin;
use std::sync::{Arc, OnceLock};
use std::time::Duration;

use bytes::Bytes;
use tokio::sync::{mpsc, oneshot};
use tokio::time::{sleep_until, timeout, Instant};

use super::pairing::{Output, Pairing, Request, Submit, Token};
use super::Reconnect;
use crate::deadline::{after, move_timer};
use crate::int_map::IntMap;
use crate::reconnect::{EventSender, ReconnectPolicy};
use crate::supervisor::{supervise, CloseRequest, Restore, Served, Session};
use crate::wsg::command::{id, Command, UpdateMode};
use crate::wsg::subscription::{Subscriber, UpdateOptions};
use crate::wsg::transport::Link;
use crate::wsg::{Error, Frame, Reply, Result, Status};

/// A request from a handle to the task.
pub(crate) enum Msg {
    /// Send `frame` and answer with its final reply (whatever its status).
    Call {
        frame: Frame,
        deadline: Instant,
        reply: oneshot::Sender<Result<Reply>>,
    },
    /// Register a subscriber, then send the command with auto-update `mode`.
    Subscribe {
        id: u8,
        mode: UpdateMode,
        subscriber: Subscriber,
        deadline: Instant,
        reply: oneshot::Sender<Result<Reply>>,
    },
    /// Announce the disconnect (if configured), close the transport and end.
    Close { done: oneshot::Sender<Result<()>> },
}

/// Who asked to close (nobody when the last handle went away), and how closing went.
type Closing = Option<(oneshot::Sender<Result<()>>, Result<()>)>;

struct StreamState {
    mode: UpdateMode,
    subscribers: Vec<Subscriber>,
}

pub(crate) struct Task {
    pub(crate) link: Link,
    pub(crate) rx: mpsc::Receiver<Msg>,
    pub(crate) unsubscribe: mpsc::UnboundedReceiver<(u8, u64)>,
    pub(crate) pairing: Pairing,
    pub(crate) query_timeout: Duration,
    /// Bounds each write and the transport's shutdown: the query timeout plus the late-reply
    /// grace, generous for a slow serial line, short enough that a gripper which stopped
    /// reading cannot hold the task.
    write_timeout: Duration,
    pub(crate) announce_on_close: bool,
    /// How long a frame may take from its first byte before it is dropped as noise.
    pub(crate) partial_frame_timeout: Duration,
    /// When the partial frame held by the decoder was first seen (`None`: none held). Measured
    /// from the frame's first byte, not its last: bytes that keep coming (a stream of updates
    /// behind a corrupted length field) must not keep a bogus frame, and every reply behind
    /// it, waiting (issue 20.2 #2).
    partial_since: Option<Instant>,
    /// The decoder's damage count when last looked at ([`Task::note_damage`]).
    damage_seen: u64,
    /// Set to the reason when the connection breaks for good, so later calls can say why.
    lost: Arc<OnceLock<String>>,
    /// Where connection losses (and reconnects) are reported.
    pub(crate) events: EventSender,
    /// How to reconnect after a loss; `None`: the client ends with the connection.
    pub(crate) reconnect: Option<Reconnect>,
    /// Set by [`Client::close`](super::Client::close) before it asks: stops reconnecting, a
    /// backoff wait or an attempt at once.
    pub(crate) close: CloseRequest,
    /// The transport is TCP: a loss puts the gripper into FAST STOP.
    pub(crate) tcp: bool,
    /// The callers waiting for a request's final reply, by token (the pairing keeps its own
    /// requests, [`super::pairing::Internal`]).
    callers: IntMap<Token, oneshot::Sender<Result<Reply>>>,
    streams: IntMap<u8, StreamState>,
    /// Ids whose id is free and whose next queued request waits until every frame already
    /// received has been paired (see [`Task::send_next`]): a frame received before a request
    /// went out cannot answer it, but would be taken for its answer (a duplicated UDP reply).
    ready: Vec<u8>,
    /// The transport keeps the device's replies in order (a byte stream).
    ordered: bool,
    /// Ids whose auto-updates the device may be sending on this connection: from the request
    /// that switched them on until the connection ends (see [`Task::transmit`]). Not before:
    /// the device drops a corrupted request unanswered (its updates then look like the reply),
    /// so no answer proves that a request switching them off was received.
    device_streams: Vec<u8>,
    /// From a loss until the reconnect: the frames that ask the new connection for the
    /// auto-update streams again.
    restore: Vec<Frame>,
}

/// Where the connection's timers wait while nothing is due (they are not polled then).
const IDLE_TIMER: Duration = Duration::from_secs(3600);

fn stream_command(id: u8, mode: UpdateMode) -> Frame {
    match id {
        id::SYSTEM_STATE => Command::SystemState(mode),
        id::GRIP_STATE => Command::GripState(mode),
        id::WIDTH => Command::Width(mode),
        id::SPEED => Command::Speed(mode),
        _ => Command::Force(mode),
    }
    .to_frame()
}

impl Task {
    pub(crate) fn new(
        link: Link,
        rx: mpsc::Receiver<Msg>,
        unsubscribe: mpsc::UnboundedReceiver<(u8, u64)>,
        grace: Duration,
        (query_timeout, motion_timeout): (Duration, Duration),
        announce_on_close: bool,
        lost: Arc<OnceLock<String>>,
    ) -> Self {
        let mut pairing = Pairing::new(grace);
        // No request keeps its id for ever: a caller without timeout (Duration::MAX), or one
        // that dropped the call, does not hold it past the default timeouts (pairing.rs).
        pairing.set_holds(query_timeout, motion_timeout);
        // A byte stream (TCP, serial, attached) keeps the device's replies in order.
        let ordered = matches!(link, Link::Stream(_));
        pairing.set_ordered(ordered);
        Self {
            partial_frame_timeout: super::DEFAULT_PARTIAL_FRAME_TIMEOUT,
            partial_since: None,
            damage_seen: 0,
            events: EventSender::new("wsg", super::EVENT_BUFFER),
            reconnect: None,
            close: CloseRequest::default(),
            tcp: false,
            lost,
            link,
            rx,
            unsubscribe,
            pairing,
            query_timeout,
            write_timeout: query_timeout.saturating_add(grace),
            announce_on_close,
            callers: IntMap::default(),
            streams: IntMap::default(),
            ready: Vec::new(),
            ordered,
            device_streams: Vec::new(),
            restore: Vec::new(),
        }
    }

    /// Runs until closed, every handle is dropped, or the connection is lost for good (the
    /// loop is the shared supervisor's, `crate::supervisor`).
    pub(crate) async fn run(self) {
        supervise(self).await;
    }

    /// Fails every call in flight or queued behind one (internal requests are forgotten).
    fn fail_waiters(&mut self, e: &Error) {
        for (_, tx) in self.callers.drain() {
            let again = match e {
                Error::ConnectionLost { .. } => e.clone(),
                _ => Error::Closed,
            };
            let _ = tx.send(Err(again));
        }
        self.pairing.drain();
        self.ready.clear();
    }

    /// The auto-update streams that still have subscribers, and the frames that ask a new
    /// connection for them again.
    fn streams_to_restore(&mut self) -> Vec<Frame> {
        for st in self.streams.values_mut() {
            st.subscribers.retain(|s| !s.tx.is_closed());
        }
        self.streams.retain(|_, st| !st.subscribers.is_empty());
        self.streams
            .iter()
            .map(|(id, st)| stream_command(*id, st.mode))
            .collect()
    }

    /// Runs until closed (returns who to tell and how it went) or the connection breaks
    /// (returns the reason).
    async fn serve_link(&mut self) -> std::result::Result<Closing, String> {
        // One timer each for the pairing's next due time and a stalled partial frame, kept
        // across iterations: a new `Sleep` per iteration costs a timer-wheel insert and removal
        // for every request and reply (issue 14). Unpolled, a timer costs nothing.
        let mut due_timer = pin!(sleep_until(Instant::now() + IDLE_TIMER));
        let mut stale_timer = pin!(sleep_until(Instant::now() + IDLE_TIMER));
        loop {
            let stale = self.partial_frame_deadline();
            // While the decoder holds a partial frame, nothing is released or probed: the
            // frames behind it may be the very replies awaited, and a released id's next
            // request would take them (issue 20.2 #2). The hold ends by `stale` at the latest.
            let due = self
                .pairing
                .next_due()
                .map(|at| stale.map_or(at, |s| at.max(s)));
            if let Some(at) = due {
                // Early is harmless (the pairing says what is due when the timer fires, and the
                // timer is then set again): one set for an earlier request's deadline serves
                // the later ones, so a stream of calls does not move it every time.
                if due_timer.is_elapsed() || at < due_timer.deadline() {
                    due_timer.as_mut().reset(at);
                }
            }
            if let Some(at) = stale {
                // Exact: the handler below takes the deadline as reached.
                move_timer(stale_timer.as_mut(), at);
            }
            tokio::select! {
                // Input first: a frame already received cannot answer a request sent after it,
                // so it is paired before the next request of its id goes out (a duplicated
                // reply sitting in the buffer is then dropped as unsolicited).
                biased;
                received = self.link.recv_or_partial(stale.is_some()) => match received {
                    // A frame has started: the next pass times it.
                    None => {}
                    Some(Some(Ok(frame))) => {
                        // Whatever the decoder holds now is the start of the next frame.
                        self.partial_since = None;
                        self.note_damage();
                        self.on_frame(frame).await.map_err(io_reason)?;
                    }
                    Some(Some(Err(e))) => return Err(e.to_string()),
                    Some(None) => return Err("the gripper closed the connection".into()),
                },
                () = &mut stale_timer, if stale.is_some() => {
                    self.partial_since = None;
                    // The partial frame dropped as noise may have been a reply.
                    self.pairing.on_damage();
                    let frames = self.link.resync();
                    // Told already: the frames found after it were not damaged since.
                    self.damage_seen = self.link.damage();
                    for frame in frames {
                        self.on_frame(frame).await.map_err(io_reason)?;
                    }
                }
                // Reached only when no frame is ready to be read: every frame already received
                // is paired, so the next requests of the freed ids can go out. Unless the
                // task's cooperative budget ran out, which makes a read return "not ready"
                // whatever is received: then yield (that renews it) and read first.
                () = std::future::ready(()), if !self.ready.is_empty() => {
                    if !tokio::task::coop::has_budget_remaining() {
                        tokio::task::yield_now().await;
                        continue;
                    }
                    self.send_ready().await.map_err(io_reason)?;
                }
                msg = self.rx.recv() => match msg {
                    // A caller that gave up while its request waited in the channel: never sent.
                    Some(Msg::Call { reply, .. }) if reply.is_closed() => {}
                    Some(Msg::Call { frame, deadline, reply }) => {
                        let token = self.caller(reply);
                        self.submit(Request { token, frame, deadline }).await.map_err(io_reason)?;
                    }
                    Some(Msg::Subscribe { id, mode, subscriber, deadline, reply }) => {
                        let st = self.streams.entry(id).or_insert(StreamState { mode, subscribers: Vec::new() });
                        // Subscriptions already dropped do not count (their unsubscribe
                        // message may still be on its way).
                        st.subscribers.retain(|s| !s.tx.is_closed());
                        if !st.subscribers.is_empty() && st.mode != mode {
                            // Re-configuring the device's stream would change it under the
                            // subscribers it already has (3.4.1: one stream per value).
                            let _ = reply.send(Err(Error::SubscriptionConflict {
                                command: id,
                                active: UpdateOptions::from_mode(st.mode),
                            }));
                            continue;
                        }
                        st.mode = mode;
                        st.subscribers.push(subscriber);
                        let token = self.caller(reply);
                        let frame = stream_command(id, mode);
                        self.submit(Request { token, frame, deadline }).await.map_err(io_reason)?;
                    }
                    Some(Msg::Close { done }) => {
                        let result = self.close().await;
                        return Ok(Some((done, result)));
                    }
                    None => {
                        // Every handle is gone: close as gracefully as `close()` would.
                        let _ = self.close().await;
                        return Ok(None);
                    }
                },
                Some((id, key)) = self.unsubscribe.recv() => {
                    self.unsubscribe(id, key).await.map_err(io_reason)?;
                }
                () = &mut due_timer, if due.is_some() => {
                    // The timer may have been set before a partial frame came: hold on until
                    // that frame ends (the timer is then set to `stale`).
                    let now = Instant::now();
                    if stale.is_none_or(|s| s <= now) {
                        self.pairing.expire(now);
                        self.act().await.map_err(io_reason)?;
                    }
                }
            }
        }
    }

    /// Tells the pairing when the decoder dropped something since the last frame: before the
    /// frame read after it is paired, so that the echo of a barrier settling a streamed query
    /// knows the query's reply may have been lost (issue 29 A, [`Pairing::on_damage`]).
    fn note_damage(&mut self) {
        let damage = self.link.damage();
        if damage != self.damage_seen {
            self.damage_seen = damage;
            self.pairing.on_damage();
        }
    }

    /// When the partial frame held by the decoder (if any) is dropped as noise:
    /// `partial_frame_timeout` after it was first seen, however many bytes came since.
    fn partial_frame_deadline(&mut self) -> Option<Instant> {
        if self.link.partial_len() == 0 {
            self.partial_since = None;
            return None;
        }
        let since = *self.partial_since.get_or_insert_with(Instant::now);
        Some(after(since, self.partial_frame_timeout))
    }

    /// Sends stop or FAST STOP `id` again, at once (the pairing recorded it as sent).
    async fn send_stop(&mut self, id: u8) -> io::Result<()> {
        send_within(
            &mut self.link,
            &Frame::new(id, Bytes::new()),
            self.write_timeout,
        )
        .await
    }

    /// Registers a caller waiting for a request's final reply: the request's token.
    fn caller(&mut self, tx: oneshot::Sender<Result<Reply>>) -> Token {
        let token = self.pairing.token();
        self.callers.insert(token, tx);
        token
    }

    async fn submit(&mut self, req: Request) -> io::Result<()> {
        let id = req.frame.id;
        let callers = &self.callers;
        // One clock read for both (issue 14: the clock is a measurable part of a round trip).
        let now = Instant::now();
        for gone in self.pairing.prune(id, |t| alive(callers, t), now) {
            self.callers.remove(&gone);
        }
        match self.pairing.submit(req, now) {
            Submit::Send(req) => self.transmit(req).await,
            Submit::Queued => Ok(()),
        }
    }

    async fn transmit(&mut self, req: Request) -> io::Result<()> {
        let mut frame = req.frame;
        // A one-off query of a value that is being streamed must not switch the device's
        // updates off (FLAGS bit0 clear would): ask with the stream's flags instead. The device
        // answers with the current value and keeps streaming.
        if let Some(st) = self.streams.get(&frame.id) {
            if frame.payload.first().is_some_and(|flags| flags & 1 == 0) {
                frame = stream_command(frame.id, st.mode);
            }
        }
        // While the device may stream updates of this id, the next frame of the id may be an
        // update it sent before it received this request (an update and the reply share id
        // and form, manual 1.4, 3.4.1-3.4.6). On a byte stream a loop-back sent after the
        // request settles it: the last frame of the id before its echo (Pairing::settle).
        // Only then: a query of a value nobody streams costs no barrier.
        let settle = self.ordered && self.device_streams.contains(&frame.id);
        let streaming = frame.payload.first().map(|flags| flags & 1 == 1);
        if streaming == Some(true)
            && is_streamable(frame.id)
            && !self.device_streams.contains(&frame.id)
        {
            self.device_streams.push(frame.id);
        }
        tracing::trace!(id = frame.id, len = frame.payload.len(), "WSG send");
        send_within(&mut self.link, &frame, self.write_timeout).await?;
        if !settle {
            return Ok(());
        }
        let now = Instant::now();
        let barrier = self.pairing.settle_barrier(frame.id, req.token, now);
        // Queued behind another loop-back, it goes out later: still after the request.
        match self.pairing.submit(barrier, now) {
            Submit::Send(barrier) => {
                send_within(&mut self.link, &barrier.frame, self.write_timeout).await
            }
            Submit::Queued => Ok(()),
        }
    }

    /// The request on the wire of `id` is done: its next queued request (if any) goes out once
    /// every frame already received is paired ([`Task::send_ready`], from the task's loop),
    /// not now. A frame already received cannot answer a request sent after it, yet would be
    /// taken for its answer: a duplicated UDP reply whose copy sits in the socket's buffer.
    fn send_next(&mut self, id: u8) {
        if self.pairing.done(id) && !self.ready.contains(&id) {
            self.ready.push(id);
        }
    }

    /// Sends the next request of each id [`Task::send_next`] set aside.
    async fn send_ready(&mut self) -> io::Result<()> {
        for id in std::mem::take(&mut self.ready) {
            self.send_now(id).await?;
        }
        Ok(())
    }

    /// Sends the next queued request of `id`, if its id is free.
    async fn send_now(&mut self, id: u8) -> io::Result<()> {
        let callers = &self.callers;
        let (next, skipped) = self.pairing.next(id, |t| alive(callers, t), Instant::now());
        for t in skipped {
            self.callers.remove(&t);
        }
        match next {
            Some(req) => self.transmit(req).await,
            None => Ok(()),
        }
    }

    async fn on_frame(&mut self, frame: Frame) -> io::Result<()> {
        let id = frame.id;
        match Reply::from_frame(frame) {
            // Data comes only with E_SUCCESS (PROTOCOLS.md §1, the manual's frame): a refusal
            // that carries data was damaged in a way its checksum did not catch (noise inserted
            // after the header made the CRC come out right, and read as status 7111: the
            // explorer's wsg-serial:0xee92ace7216a7a5d). Dropped as a damaged frame is, never
            // reported as the device's status: its request times out, or is asked again.
            Ok(reply) if reply.status != Status::Success && !reply.data.is_empty() => {
                tracing::warn!(id, status = %reply.status, len = reply.data.len(),
                    "WSG refusal with data (data comes only with E_SUCCESS): damaged, dropped");
                self.pairing.on_damage();
            }
            Ok(reply) => {
                if let Some((token, reply)) = self.pairing.receive(reply, Instant::now) {
                    if reply.status == Status::Success {
                        self.fan_out(id, &reply.data).await?;
                    }
                    if let Some(tx) = self.callers.remove(&token) {
                        if tx.send(Ok(reply)).is_err() {
                            tracing::debug!(
                                id,
                                "late reply of a timed-out or dropped call: discarded"
                            );
                        }
                    }
                    self.send_next(id);
                }
            }
            Err(reason) => {
                tracing::warn!(id, %reason, "malformed WSG reply");
                self.pairing.receive_malformed(id, &reason, Instant::now);
            }
        }
        if self.pairing.has_output() {
            self.act().await?;
        }
        Ok(())
    }

    /// Does what the pairing says, in its order ([`Output`]).
    async fn act(&mut self) -> io::Result<()> {
        while let Some(output) = self.pairing.poll() {
            match output {
                Output::Complete(token, result) => {
                    if let Some(tx) = self.callers.remove(&token) {
                        let _ = tx.send(result);
                    }
                }
                Output::Update(reply) => {
                    if reply.status == Status::Success && self.streams.contains_key(&reply.id) {
                        self.fan_out(reply.id, &reply.data).await?;
                    } else {
                        tracing::debug!(id = reply.id, status = %reply.status,
                            "WSG reply nobody waits for: dropped");
                    }
                }
                Output::Value(reply) => self.fan_out(reply.id, &reply.data).await?,
                Output::Request(kind) => {
                    let req = self.pairing.request(kind, Instant::now());
                    self.submit(req).await?;
                }
                Output::SendStop(id) => self.send_stop(id).await?,
                Output::Resend(req) => self.transmit(req).await?,
                Output::Next(id) => self.send_next(id),
            }
        }
        Ok(())
    }

    /// Hands a value to the subscribers of `id`; turns the device's updates off when the last
    /// one is gone.
    async fn fan_out(&mut self, id: u8, data: &Bytes) -> io::Result<()> {
        let Some(st) = self.streams.get_mut(&id) else {
            return Ok(());
        };
        st.subscribers.retain(|s| s.deliver(data));
        if st.subscribers.is_empty() {
            self.stop_stream(id).await?;
        }
        Ok(())
    }

    async fn unsubscribe(&mut self, id: u8, key: u64) -> io::Result<()> {
        let Some(st) = self.streams.get_mut(&id) else {
            return Ok(());
        };
        st.subscribers.retain(|s| s.key != key);
        if st.subscribers.is_empty() {
            self.stop_stream(id).await?;
        }
        Ok(())
    }

    async fn stop_stream(&mut self, id: u8) -> io::Result<()> {
        self.streams.remove(&id);
        tracing::debug!(id, "last subscriber gone: turning auto-updates off");
        let token = self.pairing.discard_token();
        let deadline = after(Instant::now(), self.query_timeout);
        self.submit(Request {
            token,
            frame: stream_command(id, UpdateMode::ONCE),
            deadline,
        })
        .await
    }

    /// Announces the disconnect (TCP, manual 3.1.2) and waits for its reply, so the gripper does
    /// not go into FAST STOP; then shuts the transport down.
    async fn close(&mut self) -> Result<()> {
        let mut result = Ok(());
        if self.announce_on_close {
            let (tx, mut rx) = oneshot::channel();
            let token = self.caller(tx);
            let deadline = after(Instant::now(), self.query_timeout);
            let frame = Command::AnnounceDisconnect.to_frame();
            if let Err(e) = self
                .submit(Request {
                    token,
                    frame,
                    deadline,
                })
                .await
            {
                return Err(Error::lost(e.to_string()));
            }
            result = loop {
                tokio::select! {
                    // A fixed order, so that a seeded run replays exactly (issue 20): the
                    // answer first; then the deadline, which a steady flow of frames (say
                    // auto-updates) must not starve; then the next frame.
                    biased;
                    r = &mut rx => break match r {
                        Ok(Ok(reply)) if reply.status == Status::Success => Ok(()),
                        Ok(Ok(reply)) => Err(Error::Device { command: id::ANNOUNCE_DISCONNECT, status: reply.status }),
                        Ok(Err(e)) => Err(e),
                        Err(_) => Err(Error::Closed),
                    },
                    _ = sleep_until(deadline) => break Err(Error::Timeout {
                        command: id::ANNOUNCE_DISCONNECT,
                        timeout: self.query_timeout,
                    }),
                    received = self.link.recv() => match received {
                        Some(Ok(frame)) => {
                            // Requests freed here go out at once: closing reads no further.
                            let paired = match self.on_frame(frame).await {
                                Ok(()) => self.send_ready().await,
                                Err(e) => Err(e),
                            };
                            if let Err(e) = paired {
                                break Err(Error::lost(e.to_string()));
                            }
                        }
                        Some(Err(e)) => break Err(Error::lost(e.to_string())),
                        None => break Err(Error::lost("closed by the gripper")),
                    },
                }
            };
        }
        // Bounded like a write: a gripper that stopped reading must not hold close() forever.
        if timeout(self.write_timeout, self.link.shutdown())
            .await
            .is_err()
        {
            tracing::warn!("WSG transport shutdown timed out; the connection is dropped");
        }
        result
    }
}

/// What a WSG reconnect borrows of the task: the queue and the close request (to stop), where
/// events go, how to connect, and the streams to ask for again.
pub(crate) struct Reopen<'a> {
    rx: &'a mpsc::Receiver<Msg>,
    close: &'a CloseRequest,
    events: &'a EventSender,
    reconnect: Option<&'a Reconnect>,
    restore: &'a [Frame],
    write_timeout: Duration,
}

impl Restore for Reopen<'_> {
    type Link = Link;
    type Error = String;

    fn events(&self) -> &EventSender {
        self.events
    }

    fn abandoned(&self) -> bool {
        self.rx.is_closed() || self.close.is_requested()
    }

    fn close_request(&self) -> &CloseRequest {
        self.close
    }

    async fn connect(&self) -> std::result::Result<Link, String> {
        let Some(reconnect) = self.reconnect else {
            // Not reached: the supervisor reconnects only with a policy.
            return Err("no reconnect policy".into());
        };
        reconnect
            .connector
            .connect()
            .await
            .map_err(|e| e.to_string())
    }

    async fn restore(&self, link: &mut Link) -> std::result::Result<(), String> {
        // The new connection starts without auto-updates: ask for them again.
        for frame in self.restore {
            send_within(link, frame, self.write_timeout)
                .await
                .map_err(|e| e.to_string())?;
        }
        Ok(())
    }
}

/// The WSG session the supervisor runs: restored by asking for the auto-update streams that
/// still have subscribers again.
impl Session for Task {
    type Restore<'a> = Reopen<'a>;
    type Link = Link;
    type Error = String;
    type Request = Msg;
    type Close = Closing;

    async fn serve(&mut self) -> Served<Closing, String> {
        match self.serve_link().await {
            Ok(done) => Served::Closed(done),
            Err(reason) => Served::Lost(reason),
        }
    }

    fn requests(&mut self) -> &mut mpsc::Receiver<Msg> {
        &mut self.rx
    }

    fn restorer(&self) -> Reopen<'_> {
        Reopen {
            rx: &self.rx,
            close: &self.close,
            events: &self.events,
            reconnect: self.reconnect.as_ref(),
            restore: &self.restore,
            write_timeout: self.write_timeout,
        }
    }

    fn policy(&self) -> Option<ReconnectPolicy> {
        self.reconnect.as_ref().map(|r| r.policy)
    }

    /// On TCP, that the gripper is now in FAST STOP, which the client never acknowledges on
    /// its own.
    fn loss_report(&self, reason: &String) -> String {
        if self.tcp {
            format!(
                "{reason}; the gripper goes into FAST STOP on an unannounced TCP close (manual \
                 1.4.2): motion is refused until the program calls acknowledge_fast_stop"
            )
        } else {
            reason.to_owned()
        }
    }

    fn lost(&mut self, reason: &String) {
        // Calls in flight fail; nothing is sent again on its own (a move that was cut off must
        // not start again without the program deciding so).
        self.fail_waiters(&Error::lost(reason.clone()));
        if self.reconnect.is_some() {
            self.restore = self.streams_to_restore();
        }
    }

    fn restored(&mut self, link: Link) {
        self.link = link;
        self.partial_since = None;
        self.damage_seen = 0;
        // A new connection streams only what was asked again on it.
        self.device_streams = self.streams.keys().copied().collect();
        // Their replies (the current values) go to the subscribers like any update.
        let deadline = after(Instant::now(), self.query_timeout);
        for frame in std::mem::take(&mut self.restore) {
            let token = self.pairing.discard_token();
            // The ids are all free on a fresh connection: this only records what was sent.
            let _ = self.pairing.submit(
                Request {
                    token,
                    frame,
                    deadline,
                },
                Instant::now(),
            );
        }
    }

    fn ended(&mut self, end: &Served<Closing, String>) {
        let e = match end {
            Served::Lost(reason) => {
                let _ = self.lost.set(reason.clone());
                Error::lost(reason.clone())
            }
            Served::Closed(_) => Error::Closed,
        };
        self.fail_waiters(&e);
        // Dropping the subscribers' senders ends their streams.
        self.streams.clear();
    }

    /// A call still queued fails with the reason set in `ended` (its reply is dropped). The
    /// supervisor's `recv` waits for a call that took its place in the queue before it closed
    /// and puts its request in afterwards; dropping the queue as it is would leave that
    /// request unanswered (its caller waited out its timeout: one call in thousands on a
    /// multi-thread runtime, `tests/error_contract.rs`).
    fn refuse(_request: Msg, _end: &Served<Closing, String>) {}

    async fn finish(self, end: Served<Closing, String>) {
        if let Served::Closed(Some((done, result))) = end {
            let _ = done.send(result);
        }
    }
}

/// Sends one frame within `limit`. A gripper (or a link) that stops reading fills the socket's
/// buffer and would block the write, and with it the task that also reads replies and serves
/// `close()`; on expiry the connection is given up as lost (a frame may be half written).
async fn send_within(link: &mut Link, frame: &Frame, limit: Duration) -> io::Result<()> {
    timeout(limit, link.send(frame)).await.unwrap_or_else(|_| {
        Err(io::Error::new(
            io::ErrorKind::TimedOut,
            format!("the gripper stopped reading commands (a write took over {limit:?})"),
        ))
    })
}

/// Whether the caller of request `token` still waits (the pairing's own requests are alive
/// whatever this says).
fn alive(callers: &IntMap<Token, oneshot::Sender<Result<Reply>>>, token: Token) -> bool {
    callers.get(&token).is_some_and(|tx| !tx.is_closed())
}

/// Whether the device can stream updates of command `id` (auto-update flags, manual 3.4.1,
/// 3.4.2, 3.4.4-3.4.6).
fn is_streamable(id: u8) -> bool {
    matches!(
        id,
        id::SYSTEM_STATE | id::GRIP_STATE | id::WIDTH | id::SPEED | id::FORCE
    )
}

fn io_reason(e: io::Error) -> String {
    e.to_string()
}
