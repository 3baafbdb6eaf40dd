//! Pairing replies with requests: a pure state machine, no I/O (the model of rumqttc's state).
//!
//! The protocol has no sequence numbers: a reply carries only its command id. So:
//! - at most one request per command id is on the wire; later calls with the same id queue
//!   behind it, while different ids run concurrently;
//! - an E_CMD_PENDING reply (manual 1.3) acknowledges an asynchronous command and keeps the id
//!   busy until the final reply; any other status is final;
//! - a request whose caller timed out or went away stays on the wire until its reply arrives
//!   (the late reply is consumed here and discarded by the task), so the reply can never reach
//!   the next caller of that id.
//!
//! How long an id stays "poisoned" by a request that got no reply: until its caller's deadline
//! plus a grace period ([`Pairing::new`]); then the id is released so a lost frame cannot block it
//! forever. The residual risk is a reply arriving later than that grace: it would be taken as the
//! reply to the next request of the same id. Once a device has acknowledged an asynchronous
//! command (E_CMD_PENDING) it always sends a final reply (manual 1.3; a stop ends a motion with
//! E_CMD_ABORTED), so an acknowledged request is never released early: the next motion command of
//! that id waits for the final reply of the previous one, whatever the callers' timeouts.
//! (If that reply is lost on the wire, the task, not this state machine, finds out by asking the
//! device whether it still moves, and [`Pairing::abandon`]s the request.)
//!
//! Two kinds of reply provably answer another request of the same id and are treated as
//! unsolicited: a loop reply that does not echo the payload on the wire, and E_ALREADY_RUNNING
//! for an acknowledged request (the device's refusal of a duplicate of it).

use std::collections::{HashMap, VecDeque};
use std::time::Duration;

use bytes::Bytes;
use tokio::time::Instant;

use crate::wsg::command::id;
use crate::wsg::{Frame, Reply, Status};

/// Identifies one request for the task.
pub(crate) type Token = u64;

/// A request waiting to be sent or on the wire.
#[derive(Debug)]
pub(crate) struct Request {
    pub(crate) token: Token,
    pub(crate) frame: Frame,
    /// When the caller stops waiting.
    pub(crate) deadline: Instant,
}

#[derive(Debug)]
struct InFlight {
    token: Token,
    /// E_CMD_PENDING seen: a final reply is guaranteed to follow.
    acknowledged: bool,
    release_at: Instant,
    /// The payload sent: a loop reply (0x06) must echo it.
    payload: Bytes,
}

impl InFlight {
    fn new(req: &Request, grace: Duration) -> Self {
        Self {
            token: req.token,
            acknowledged: false,
            release_at: req.deadline + grace,
            payload: req.frame.payload.clone(),
        }
    }

    /// Whether `reply` provably answers some other request of the same id: a duplicate of an
    /// earlier reply, or the device's answer to a duplicated request (faults seen on UDP and by
    /// the fault matrix). Such a reply is consumed as unsolicited instead of ending this request.
    fn rejects(&self, reply: &Reply) -> bool {
        // A loop reply carries the payload it echoes (3.1.1): another payload is not ours.
        let foreign_echo =
            reply.id == id::LOOP && reply.status == Status::Success && reply.data != self.payload;
        // Once the device has acknowledged this command, E_ALREADY_RUNNING cannot be its final
        // reply (1.3: that code is only ever an immediate refusal): it refuses a duplicate of it.
        let refused_duplicate = self.acknowledged && reply.status == Status::AlreadyRunning;
        foreign_echo || refused_duplicate
    }
}

#[derive(Debug, Default)]
struct IdState {
    in_flight: Option<InFlight>,
    queue: VecDeque<Request>,
}

/// What a received reply means.
#[derive(Debug, PartialEq)]
pub(crate) enum Event {
    /// The final reply of the request `Token`.
    Resolved(Token, Reply),
    /// The asynchronous request `Token` was accepted (E_CMD_PENDING); its result follows.
    Accepted(Token),
    /// No request of this id is on the wire (an auto-update, or a reply that came after its id
    /// was released).
    Unsolicited(Reply),
}

/// The pairing state of one connection.
#[derive(Debug)]
pub(crate) struct Pairing {
    ids: HashMap<u8, IdState>,
    grace: Duration,
}

impl Pairing {
    /// `grace`: how long after its caller's deadline an unanswered request keeps its id.
    pub(crate) fn new(grace: Duration) -> Self {
        Self {
            ids: HashMap::new(),
            grace,
        }
    }

    /// Queues `req`; returns it back when it may be sent now (its id is free).
    pub(crate) fn submit(&mut self, req: Request) -> Option<Request> {
        let st = self.ids.entry(req.frame.id).or_default();
        if st.in_flight.is_none() && st.queue.is_empty() {
            st.in_flight = Some(InFlight::new(&req, self.grace));
            Some(req)
        } else {
            st.queue.push_back(req);
            None
        }
    }

    /// Drops the queued (never sent) requests of `id` whose caller is gone; returns their
    /// tokens. Called before queueing another, so that callers who keep timing out behind a
    /// long move cannot grow the queue: it holds at most one request per live caller.
    pub(crate) fn prune(&mut self, id: u8, alive: impl Fn(Token) -> bool) -> Vec<Token> {
        let Some(st) = self.ids.get_mut(&id) else {
            return Vec::new();
        };
        let mut gone = Vec::new();
        st.queue.retain(|r| {
            let keep = alive(r.token);
            if !keep {
                gone.push(r.token);
            }
            keep
        });
        gone
    }

    /// Pairs a received reply.
    pub(crate) fn on_reply(&mut self, reply: Reply) -> Event {
        let Some(f) = self
            .ids
            .get_mut(&reply.id)
            .and_then(|st| st.in_flight.as_mut())
        else {
            return Event::Unsolicited(reply);
        };
        if f.rejects(&reply) {
            tracing::warn!(id = reply.id, status = %reply.status,
                "WSG reply that cannot answer the request on the wire: dropped");
            return Event::Unsolicited(reply);
        }
        if reply.status == Status::CmdPending {
            f.acknowledged = true;
            return Event::Accepted(f.token);
        }
        let token = f.token;
        if let Some(st) = self.ids.get_mut(&reply.id) {
            st.in_flight = None;
        }
        Event::Resolved(token, reply)
    }

    /// A reply of `id` too short to carry a status code: it still ends the request on the wire
    /// (it is that request's answer, just unusable). Returns its token.
    pub(crate) fn on_malformed(&mut self, id: u8) -> Option<Token> {
        self.ids.get_mut(&id)?.in_flight.take().map(|f| f.token)
    }

    /// The next request of `id` to send once its id is free, skipping requests whose caller is
    /// gone (they were never sent, so nothing needs to be consumed for them). Returns the
    /// skipped tokens too, so their bookkeeping can be dropped.
    pub(crate) fn next(
        &mut self,
        id: u8,
        alive: impl Fn(Token) -> bool,
    ) -> (Option<Request>, Vec<Token>) {
        let mut skipped = Vec::new();
        let Some(st) = self.ids.get_mut(&id) else {
            return (None, skipped);
        };
        if st.in_flight.is_some() {
            return (None, skipped);
        }
        while let Some(req) = st.queue.pop_front() {
            if alive(req.token) {
                st.in_flight = Some(InFlight::new(&req, self.grace));
                return (Some(req), skipped);
            }
            skipped.push(req.token);
        }
        self.ids.remove(&id);
        (None, skipped)
    }

    /// The token of the acknowledged request of `id` on the wire, if there is one.
    pub(crate) fn acknowledged(&self, id: u8) -> Option<Token> {
        let f = self.ids.get(&id)?.in_flight.as_ref()?;
        f.acknowledged.then_some(f.token)
    }

    /// Gives up on request `token` of `id` (still on the wire) because its final reply is known
    /// to be lost; returns whether it was. Call [`Pairing::next`] for `id` afterwards.
    pub(crate) fn abandon(&mut self, id: u8, token: Token) -> bool {
        let Some(st) = self.ids.get_mut(&id) else {
            return false;
        };
        if st.in_flight.as_ref().is_some_and(|f| f.token == token) {
            st.in_flight = None;
            true
        } else {
            false
        }
    }

    /// When the next unanswered, unacknowledged request is released.
    pub(crate) fn next_release(&self) -> Option<Instant> {
        self.ids
            .values()
            .filter_map(|st| st.in_flight.as_ref())
            .filter(|f| !f.acknowledged)
            .map(|f| f.release_at)
            .min()
    }

    /// Releases the ids whose request got no reply by `now` (deadline + grace); returns the ids
    /// and tokens released. Call [`Pairing::next`] for each id afterwards.
    pub(crate) fn release_expired(&mut self, now: Instant) -> Vec<(u8, Token)> {
        let mut out = Vec::new();
        for (id, st) in &mut self.ids {
            if let Some(f) = &st.in_flight {
                if !f.acknowledged && f.release_at <= now {
                    out.push((*id, f.token));
                    st.in_flight = None;
                }
            }
        }
        out
    }

    /// Forgets everything; returns every token still waiting or on the wire.
    pub(crate) fn drain(&mut self) -> Vec<Token> {
        let mut out = Vec::new();
        for (_, st) in self.ids.drain() {
            out.extend(st.in_flight.map(|f| f.token));
            out.extend(st.queue.into_iter().map(|r| r.token));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn req(token: Token, id: u8, deadline: Instant) -> Request {
        Request {
            token,
            frame: Frame::new(id, Bytes::new()),
            deadline,
        }
    }

    fn reply(id: u8, status: Status) -> Reply {
        Reply::new(id, status, Bytes::new())
    }

    #[test]
    fn same_id_queues_different_ids_run() {
        let t = Instant::now() + Duration::from_secs(1);
        let mut p = Pairing::new(Duration::from_secs(1));
        assert!(p.submit(req(1, 0x43, t)).is_some());
        assert!(p.submit(req(2, 0x43, t)).is_none());
        assert!(p.submit(req(3, 0x40, t)).is_some());
        assert_eq!(
            p.on_reply(reply(0x40, Status::Success)),
            Event::Resolved(3, reply(0x40, Status::Success))
        );
        assert_eq!(
            p.on_reply(reply(0x43, Status::Success)),
            Event::Resolved(1, reply(0x43, Status::Success))
        );
        let (next, skipped) = p.next(0x43, |_| true);
        assert_eq!(next.map(|r| r.token), Some(2));
        assert!(skipped.is_empty());
        assert!(matches!(
            p.on_reply(reply(0x43, Status::Success)),
            Event::Resolved(2, _)
        ));
        assert!(matches!(
            p.on_reply(reply(0x43, Status::Success)),
            Event::Unsolicited(_)
        ));
    }

    #[test]
    fn pending_then_final_and_stop_is_not_blocked() {
        let t = Instant::now() + Duration::from_secs(1);
        let mut p = Pairing::new(Duration::from_secs(1));
        assert!(p.submit(req(1, 0x21, t)).is_some());
        assert_eq!(
            p.on_reply(reply(0x21, Status::CmdPending)),
            Event::Accepted(1)
        );
        assert!(
            p.submit(req(2, 0x22, t)).is_some(),
            "stop must not wait for the move"
        );
        assert!(matches!(
            p.on_reply(reply(0x22, Status::Success)),
            Event::Resolved(2, _)
        ));
        assert!(
            matches!(p.on_reply(reply(0x21, Status::CmdAborted)), Event::Resolved(1, r) if r.status == Status::CmdAborted)
        );
    }

    #[test]
    fn dead_queued_callers_are_skipped_and_unanswered_ids_released_after_grace() {
        let now = Instant::now();
        let mut p = Pairing::new(Duration::from_millis(500));
        assert!(p.submit(req(1, 0x50, now)).is_some());
        assert!(p.submit(req(2, 0x50, now)).is_none());
        assert!(p.submit(req(3, 0x50, now)).is_none());
        assert_eq!(p.next_release(), Some(now + Duration::from_millis(500)));
        assert!(p.release_expired(now).is_empty());
        assert_eq!(
            p.release_expired(now + Duration::from_millis(500)),
            vec![(0x50, 1)]
        );
        let (next, skipped) = p.next(0x50, |t| t != 2);
        assert_eq!(next.map(|r| r.token), Some(3));
        assert_eq!(skipped, vec![2]);
    }

    #[test]
    fn acknowledged_motion_is_never_released() {
        let now = Instant::now();
        let mut p = Pairing::new(Duration::ZERO);
        assert!(p.submit(req(1, 0x25, now)).is_some());
        assert_eq!(
            p.on_reply(reply(0x25, Status::CmdPending)),
            Event::Accepted(1)
        );
        assert_eq!(p.next_release(), None);
        assert!(p
            .release_expired(now + Duration::from_secs(3600))
            .is_empty());
        assert!(p.submit(req(2, 0x25, now)).is_none());
        assert!(matches!(
            p.on_reply(reply(0x25, Status::Success)),
            Event::Resolved(1, _)
        ));
        assert_eq!(p.drain(), vec![2]);
    }

    #[test]
    fn replies_that_cannot_answer_the_request_on_the_wire_are_unsolicited() {
        let t = Instant::now() + Duration::from_secs(1);
        let mut p = Pairing::new(Duration::from_secs(1));
        let looped = |data: &'static [u8]| Reply::new(id::LOOP, Status::Success, data);
        let mut echo = req(1, id::LOOP, t);
        echo.frame.payload = Bytes::from_static(b"mine");
        assert!(p.submit(echo).is_some());
        // A copy of an earlier loop reply: another payload.
        assert_eq!(
            p.on_reply(looped(b"old")),
            Event::Unsolicited(looped(b"old"))
        );
        assert_eq!(
            p.on_reply(looped(b"mine")),
            Event::Resolved(1, looped(b"mine"))
        );
        // An acknowledged move refuses a duplicate of itself; its final reply still ends it.
        assert!(p.submit(req(2, 0x21, t)).is_some());
        assert_eq!(
            p.on_reply(reply(0x21, Status::CmdPending)),
            Event::Accepted(2)
        );
        assert!(matches!(
            p.on_reply(reply(0x21, Status::AlreadyRunning)),
            Event::Unsolicited(_)
        ));
        assert_eq!(
            p.on_reply(reply(0x21, Status::Success)),
            Event::Resolved(2, reply(0x21, Status::Success))
        );
        // Not acknowledged: E_ALREADY_RUNNING is this request's own refusal.
        assert!(p.submit(req(3, 0x21, t)).is_some());
        assert!(matches!(
            p.on_reply(reply(0x21, Status::AlreadyRunning)),
            Event::Resolved(3, _)
        ));
    }

    #[test]
    fn prune_drops_only_queued_dead_callers() {
        let t = Instant::now() + Duration::from_secs(1);
        let mut p = Pairing::new(Duration::from_secs(1));
        assert!(p.submit(req(1, 0x21, t)).is_some());
        for token in 2..=5 {
            assert!(p.submit(req(token, 0x21, t)).is_none());
        }
        assert_eq!(p.prune(0x21, |t| t == 1 || t == 4), vec![2, 3, 5]);
        assert!(matches!(
            p.on_reply(reply(0x21, Status::Success)),
            Event::Resolved(1, _)
        ));
        let (next, skipped) = p.next(0x21, |_| true);
        assert_eq!(next.map(|r| r.token), Some(4));
        assert!(skipped.is_empty());
        assert_eq!(p.drain(), vec![4]);
    }

    proptest::proptest! {
        /// Any interleaving of calls (three ids, some asynchronous) and device replies: every
        /// final reply reaches the request it answers, one request per id is on the wire, and
        /// every call is sent once.
        #[test]
        fn replies_always_reach_their_own_request(
            ops in proptest::collection::vec((0u8..3, proptest::bool::ANY, proptest::bool::ANY), 1..200)
        ) {
            use std::collections::{HashMap, VecDeque};
            let deadline = Instant::now() + Duration::from_secs(60);
            let mut p = Pairing::new(Duration::from_secs(1));
            // What the device has received and not finally answered, per id: (token, async, acked).
            let mut wire: HashMap<u8, VecDeque<(Token, bool, bool)>> = HashMap::new();
            let mut is_async: HashMap<Token, bool> = HashMap::new();
            let mut sent = 0u64;
            let mut resolved = 0u64;
            let mut next_token = 0;
            for (id, submit, asynchronous) in ops {
                if submit {
                    next_token += 1;
                    is_async.insert(next_token, asynchronous);
                    let r = Request { token: next_token, frame: Frame::new(id, Bytes::new()), deadline };
                    if let Some(r) = p.submit(r) {
                        wire.entry(id).or_default().push_back((r.token, asynchronous, false));
                        sent += 1;
                    }
                } else if let Some(front) = wire.get_mut(&id).and_then(|q| q.front_mut()) {
                    let (token, asynchronous, acked) = *front;
                    if asynchronous && !acked {
                        front.2 = true;
                        proptest::prop_assert_eq!(p.on_reply(reply(id, Status::CmdPending)), Event::Accepted(token));
                        continue;
                    }
                    wire.get_mut(&id).map(VecDeque::pop_front);
                    // The reply carries the token it answers, so a mix-up shows.
                    let r = Reply::new(id, Status::Success, Bytes::copy_from_slice(&token.to_le_bytes()));
                    match p.on_reply(r) {
                        Event::Resolved(t, r) => {
                            proptest::prop_assert_eq!(&t.to_le_bytes()[..], &r.data[..]);
                            resolved += 1;
                        }
                        other => proptest::prop_assert!(false, "{:?}", other),
                    }
                    let (next, skipped) = p.next(id, |_| true);
                    proptest::prop_assert!(skipped.is_empty());
                    if let Some(r) = next {
                        let asynchronous = is_async[&r.token];
                        wire.entry(id).or_default().push_back((r.token, asynchronous, false));
                        sent += 1;
                    }
                }
                for q in wire.values() {
                    proptest::prop_assert!(q.len() <= 1, "two requests of one id on the wire");
                }
            }
            let waiting = p.drain().len() as u64;
            proptest::prop_assert_eq!(resolved + waiting, next_token);
            proptest::prop_assert!(sent >= resolved);
        }
    }
}
