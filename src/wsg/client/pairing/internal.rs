//! The pairing's own requests (recovery probes, loop-back barriers, the barriers that settle a
//! query of a streamed id) and what their answers mean: the pairing interprets every frame,
//! every malformed reply and every due time itself and yields plain [`Output`]s, so the task
//! is a thin shell around it (the shape of quinn-proto's connection: it takes frames and
//! timeouts with the time, and says what to transmit, which calls complete with what, and when
//! it next needs waking). The task keeps only the callers' senders, the I/O, the subscriber
//! lists of the auto-update streams and the clock.
//!
//! The outputs come in the order the task must act on them (its acts, say the request a
//! fan-out sends when a stream's last subscriber is gone, take tokens in that order, and a
//! barrier's payload carries its token). A request of the pairing's own is therefore not
//! made when it is decided on but when the task takes it ([`Output::Request`],
//! [`Pairing::request`]).

use std::time::Duration;

use tokio::time::Instant;

use super::{Due, Event, Observation, Pairing, Request, Settled, Token, Verdict};
use crate::deadline::after;
use crate::wsg::command::{id, Command, UpdateMode};
use crate::wsg::{Error, Frame, Reply, Result, Status, SystemState};

/// Barriers of one fence answered with something other than their echo before the fenced id is
/// released anyway (see [`Pairing::barrier_refused`]).
const BARRIER_REFUSALS: u8 = 3;

/// What the payload of the client's own loop-back barriers begins with; a token follows.
pub(crate) const BARRIER_PREFIX: &[u8] = b"gripper barrier ";

/// The payload length of a barrier's echo: status (2 bytes, manual 1.2.2) + the loop-back's
/// payload (3.1.1). A client must accept replies this long, or every barrier goes unanswered
/// ([`super::super::ClientBuilder::max_payload_len`]).
pub(crate) const BARRIER_ECHO_LEN: usize = 2 + BARRIER_PREFIX.len() + std::mem::size_of::<Token>();

/// A request the pairing makes itself: no caller waits for it, its answer is the pairing's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Internal {
    /// Its answer is discarded (the task's own requests: turning updates off, asking a new
    /// connection for the streams again).
    Discard,
    /// A system-state query asking whether the acknowledged motion `token` of command `id`,
    /// past its caller's deadline, is still running ([`Due::Probe`], [`Pairing::on_probe`]).
    Probe { id: u8, token: Token },
    /// A loop-back whose echo proves that every reply sent before it has been read, so the
    /// fenced command id `id` can send its next request ([`Due::Fenced`],
    /// [`Due::StopBarrier`], [`Pairing::unfence`]); `refused`: how many barriers of this fence
    /// got an answer other than their echo.
    Barrier { id: u8, refused: u8 },
    /// A loop-back sent after request `query` of command `id`, whose updates the device may be
    /// streaming: its echo says which frame answers the query ([`Pairing::settle`]).
    Settle { id: u8, query: Token },
}

/// What the task has to do, in this order ([`Pairing::poll`]).
#[derive(Debug)]
pub(crate) enum Output {
    /// Call `Token` ends with this (an error, or a frame already handed to the subscribers),
    /// if its caller still waits.
    Complete(Token, Result<Reply>),
    /// A frame no request waits for: an E_SUCCESS one goes to the subscribers of its id; any
    /// other is dropped.
    Update(Reply),
    /// The E_SUCCESS answer to a request of the pairing's own: a value for the subscribers of
    /// its id, if any (a recovery probe's system state while 0x40 is streamed).
    Value(Reply),
    /// Submit a request of the pairing's own, taken from [`Pairing::request`] now (like a
    /// call's: it may queue behind the request of its id on the wire).
    Request(Internal),
    /// Send stop or FAST STOP `id` again, at once (recorded as sent).
    SendStop(u8),
    /// Write this request again, at once: it is still the request on the wire of its id, and
    /// its earlier answer may have been damaged ([`Pairing::on_damage`]).
    Resend(Request),
    /// The request on the wire of `id` is done: its next request goes out once every frame
    /// already received is paired ([`Pairing::done`], [`Pairing::next`]).
    Next(u8),
}

/// What a recovery probe's answer (a system state reply, manual 3.4.1) says about the fingers.
fn observation(reply: &Reply) -> Observation {
    match SystemState::decode(&reply.data) {
        Ok(s) if reply.status == Status::Success => {
            if s.contains(SystemState::MOVING) {
                Observation::Moving
            } else {
                Observation::Idle
            }
        }
        _ => Observation::Unknown,
    }
}

impl Pairing {
    /// A token for a caller's request (tokens grow: [`Pairing::on_probe`] tells calls made
    /// before a probe went out by them).
    pub(crate) fn token(&mut self) -> Token {
        self.next_token += 1;
        self.next_token
    }

    /// A token for a request of the task's own whose answer nobody reads
    /// ([`Internal::Discard`]).
    pub(crate) fn discard_token(&mut self) -> Token {
        let token = self.token();
        self.internal.insert(token, Internal::Discard);
        token
    }

    /// Makes the request `kind` asked for by [`Output::Request`] (or a settle barrier) at
    /// `now`, with a token of its own. ([`Internal::Discard`] is never asked for: the task
    /// makes those frames itself, with [`Pairing::discard_token`]; asked, it is a loop-back.)
    pub(crate) fn request(&mut self, kind: Internal, now: Instant) -> Request {
        let token = self.token();
        self.internal.insert(token, kind);
        match kind {
            Internal::Probe { .. } => Request {
                token,
                frame: Command::SystemState(UpdateMode::ONCE).to_frame(),
                deadline: after(now, self.probe_timeout),
            },
            Internal::Barrier { .. } | Internal::Settle { .. } | Internal::Discard => {
                // A loop-back (0x06, manual 3.1.1) with a payload no other request carries. On
                // a byte stream its echo comes after the reply to every request sent before
                // it: the device answers the commands of one connection one after the other,
                // and the stream keeps the order. (The manual does not promise this in so many
                // words; it is what its request-reply scheme (1.2.2) implies for immediate
                // replies.)
                let mut payload = BARRIER_PREFIX.to_vec();
                payload.extend_from_slice(&token.to_le_bytes());
                Request {
                    token,
                    frame: Frame::new(id::LOOP, payload),
                    // No caller waits, so no deadline: the reply hold releases it the query
                    // timeout plus the grace after it is *sent*. A deadline from now would run
                    // while it waits behind other loop-backs (one per fenced id): it would be
                    // released as soon as sent, before its echo could come, and sent again at
                    // once, keeping the line busy without a pause. A device whose decoder
                    // holds a frame with a corrupted length until the line falls silent never
                    // got that pause: every fenced id stayed fenced (explorer, promise 5,
                    // wsg-serial:0xa5e34824226a756b).
                    deadline: after(now, Duration::MAX),
                }
            }
        }
    }

    /// The request `query` of `id` just sent is answered through a loop-back barrier sent
    /// after it (see [`Pairing::settle_by_barrier`]): returns that barrier, to submit now.
    pub(crate) fn settle_barrier(&mut self, id: u8, query: Token, now: Instant) -> Request {
        self.settle_by_barrier(id, query);
        self.request(Internal::Settle { id, query }, now)
    }

    /// The next thing for the task to do, if any.
    pub(crate) fn poll(&mut self) -> Option<Output> {
        self.out.pop_front()
    }

    /// Whether [`Pairing::poll`] has something (checked before the task walks the outputs:
    /// most frames, a call's reply, leave none).
    pub(crate) fn has_output(&self) -> bool {
        !self.out.is_empty()
    }

    /// Takes a received reply in. `now` reads the clock, only when the rules need the time
    /// (issue 14: a clock read is a measurable part of a round trip).
    ///
    /// Returns the final reply of a call, with its token: the hot path, handed back directly
    /// rather than through [`Pairing::poll`] (a queued output costs a round trip about 2 %,
    /// callgrind). An E_SUCCESS one goes to the subscribers of its id first (a value like any
    /// update), then to the caller (if it still waits); then the id's next request goes out
    /// as for [`Output::Next`]. Everything else comes from [`Pairing::poll`].
    pub(crate) fn receive(
        &mut self,
        reply: Reply,
        now: impl Fn() -> Instant,
    ) -> Option<(Token, Reply)> {
        let id = reply.id;
        match self.on_reply(reply, &now) {
            Event::Accepted(_) => {
                tracing::debug!(id, "WSG command accepted (E_CMD_PENDING)");
                // Motion calls of the id queued behind it: ask the device whether it moves.
                self.verify_queued(id, now());
            }
            Event::Stopped(tokens, reply) => {
                for token in tokens {
                    self.out
                        .push_back(Output::Complete(token, Ok(reply.clone())));
                }
            }
            Event::Resolved(token, reply) => {
                // Checked first: no request of the pairing's own is out on the hot path.
                let own = if self.internal.is_empty() {
                    None
                } else {
                    self.internal.remove(&token)
                };
                let Some(kind) = own else {
                    return Some((token, reply));
                };
                self.answered(kind, token, reply, &now);
                self.out.push_back(Output::Next(id));
            }
            Event::Unsolicited(reply) => self.out.push_back(Output::Update(reply)),
        }
        None
    }

    /// The final reply `reply` of the pairing's own request `token` (`kind`).
    fn answered(&mut self, kind: Internal, token: Token, reply: Reply, now: &impl Fn() -> Instant) {
        let success = reply.status == Status::Success;
        match kind {
            Internal::Probe { id, token: motion } => {
                let seen = observation(&reply);
                if success {
                    self.out.push_back(Output::Value(reply));
                }
                self.probe_seen(id, motion, seen, now(), token);
            }
            // The echo is the barrier's own (a loop reply must echo the payload on the wire):
            // every reply sent before it has been read.
            Internal::Barrier { id, .. } if success => self.unfenced(id, now()),
            Internal::Barrier { id, refused } => self.barrier_refused(id, refused, now),
            Internal::Settle { id, query } if success => self.settled(id, query, now),
            Internal::Settle { id, query } => self.settle_failed(id, query),
            Internal::Discard => {
                if success {
                    self.out.push_back(Output::Value(reply));
                }
            }
        }
    }

    /// Takes in a reply of `id` too short to carry a status code (`reason`): it ends the
    /// request(s) on the wire, unusable.
    pub(crate) fn receive_malformed(&mut self, id: u8, reason: &str, now: impl Fn() -> Instant) {
        let tokens = self.on_malformed(id);
        for &token in &tokens {
            match self.internal.remove(&token) {
                None => self.out.push_back(Output::Complete(
                    token,
                    Err(Error::MalformedReply {
                        command: id,
                        reason: reason.to_owned(),
                    }),
                )),
                Some(Internal::Probe {
                    id: motion,
                    token: t,
                }) => {
                    self.probe_seen(motion, t, Observation::Unknown, now(), token);
                }
                Some(Internal::Barrier {
                    id: fenced,
                    refused,
                }) => {
                    self.barrier_refused(fenced, refused, &now);
                }
                Some(Internal::Settle { id, query }) => self.settle_failed(id, query),
                Some(Internal::Discard) => {}
            }
        }
        if !tokens.is_empty() {
            self.out.push_back(Output::Next(id));
        }
    }

    /// The requests whose time has come by `now`: releases, stop re-sends, barriers, probes.
    pub(crate) fn expire(&mut self, now: Instant) {
        for due in self.due(now) {
            match due {
                Due::Released(id, token) => {
                    tracing::warn!(
                        id,
                        "no (final) reply within timeout + grace: command id released; \
                        a reply arriving later would be taken for the next request of this id"
                    );
                    self.unanswered(id, token, now);
                    self.out.push_back(Output::Next(id));
                }
                Due::Fenced(id, token) => {
                    tracing::warn!(
                        id,
                        "no reply within timeout + grace: the next request of this id waits \
                        for the echo of a loop-back (a reply before it is the late one)"
                    );
                    self.unanswered(id, token, now);
                    self.out
                        .push_back(Output::Request(Internal::Barrier { id, refused: 0 }));
                }
                Due::Probe(id, token) => self
                    .out
                    .push_back(Output::Request(Internal::Probe { id, token })),
                Due::ResendStop(id) => {
                    tracing::debug!(
                        id,
                        "no reply to a stop sent at or after a waiting stop call: sent again"
                    );
                    self.out.push_back(Output::SendStop(id));
                }
                Due::StopBarrier(id) => {
                    tracing::debug!(
                        id,
                        "stops unanswered: a loop-back's echo tells a lost reply from a late one"
                    );
                    self.out
                        .push_back(Output::Request(Internal::Barrier { id, refused: 0 }));
                }
            }
        }
    }

    /// Request `token` of `id` was released with no usable answer: a probe counts as
    /// "unknown", a barrier is sent again (its id stays fenced until one comes back).
    fn unanswered(&mut self, id: u8, token: Token, now: Instant) {
        match self.internal.remove(&token) {
            Some(Internal::Probe {
                id: motion,
                token: t,
            }) => {
                self.probe_seen(motion, t, Observation::Unknown, now, token);
            }
            Some(Internal::Barrier { id, refused }) => {
                self.out
                    .push_back(Output::Request(Internal::Barrier { id, refused }));
            }
            Some(Internal::Settle { id, query }) => self.settle_failed(id, query),
            // A caller still waiting is one without timeout (`Duration::MAX`), or a motion
            // command's whose acknowledgement did not come, released by the hold of
            // `Pairing::set_holds`: the timeout applied was the connection's query timeout
            // (the default one when the connection has none). (A caller with a timeout keeps
            // its id past its own deadline, by which its call has failed with its own timeout.)
            None => self.out.push_back(Output::Complete(
                token,
                Err(Error::Timeout {
                    command: id,
                    timeout: self.reply_hold(),
                }),
            )),
            // An internal request: forgotten.
            Some(Internal::Discard) => {}
        }
    }

    /// A barrier of fenced id `id` got an answer other than its echo (a refusal, a malformed
    /// reply): it may be a stale answer to an earlier loop-back, so another barrier goes out.
    /// Not for ever: a device that refuses every loop-back would have the task send them as
    /// fast as it answers. After [`BARRIER_REFUSALS`] the id is released as on UDP (a reply
    /// later than the grace may then answer its next request).
    fn barrier_refused(&mut self, id: u8, refused: u8, now: &impl Fn() -> Instant) {
        let refused = refused.saturating_add(1);
        if refused < BARRIER_REFUSALS {
            self.out
                .push_back(Output::Request(Internal::Barrier { id, refused }));
            return;
        }
        tracing::warn!(
            id,
            "the device answers no loop-back with its echo: command id released without proof \
            that no late reply is on its way"
        );
        self.unfenced(id, now());
    }

    /// The fence of `id` is over at `now` (its barrier's echo came, or the barrier was given
    /// up): its next request goes out, or, for a stop id, the stop is sent again if a caller
    /// still waits for one.
    fn unfenced(&mut self, id: u8, now: Instant) {
        if self.unfence(id, now) {
            self.out.push_back(Output::SendStop(id));
        }
        self.out.push_back(Output::Next(id));
    }

    /// The echo of the barrier sent after query `query` of streamed command `id` came: the
    /// query is answered by the last frame of `id` before it, if there was one.
    fn settled(&mut self, id: u8, query: Token, now: &impl Fn() -> Instant) {
        let reply = match self.settle(id, query, now()) {
            Settled::Answer(reply) => reply,
            Settled::Again(request) => {
                tracing::debug!(
                    id,
                    "WSG frame damaged before a streamed query's echo: asked again"
                );
                self.out.push_back(Output::Resend(request));
                return;
            }
            Settled::Nothing => return,
        };
        self.out.push_back(Output::Next(id));
        // An E_SUCCESS frame: it went to the subscribers when it came.
        match self.internal.remove(&query) {
            None => self.out.push_back(Output::Complete(query, Ok(reply))),
            // A recovery probe of a motion while system state (0x40) is streamed: what it saw
            // goes to the pairing as from any probe. Dropped, it left the motion with a probe
            // out for ever, its id held (wsg-serial:0x81263a75df4c46d4).
            Some(Internal::Probe { id: motion, token }) => {
                self.probe_seen(motion, token, observation(&reply), now(), query);
            }
            Some(_) => {}
        }
    }

    /// What probe `probe` of the motion `token` of `id` saw, and what follows from it.
    fn probe_seen(&mut self, id: u8, token: Token, seen: Observation, now: Instant, probe: Token) {
        match self.on_probe(id, token, seen, now, probe) {
            Verdict::Abandoned => {
                tracing::warn!(
                    id,
                    "the final reply of a motion command was lost (the device said twice, a \
                     grace period apart, that it does not move): id released"
                );
                self.out.push_back(Output::Complete(
                    token,
                    Err(Error::ReplyLost { command: id }),
                ));
                self.out.push_back(Output::Next(id));
            }
            Verdict::Running(refused) => {
                // A motion command of that id is on the wire, and a system-state query sent
                // after these calls found the fingers moving, so the device would refuse them
                // the same way (3.2.2).
                for t in refused {
                    tracing::debug!(id, "motion command refused: the device moves (SF_MOVING)");
                    self.out.push_back(Output::Complete(
                        t,
                        Err(Error::Device {
                            command: id,
                            status: Status::AlreadyRunning,
                        }),
                    ));
                }
            }
            Verdict::Undecided => {}
        }
    }
}
