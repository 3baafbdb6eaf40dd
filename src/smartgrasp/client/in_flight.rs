//! SmartGrasp's requests in flight, as a state machine without I/O (issue 30): the link writes a
//! request and hands it here with its caller; it hands every response it reads here, with the
//! time when the give-up timer fires; and it does what comes back: complete a call with a
//! response or an error, record a counter gap, wake at the give-up time, give the connection up.
//! No socket, no clock (`now` is passed in, read lazily where only some paths need it), no
//! channel: a caller is an opaque token ([`Caller`]) that is only asked whether it gave up, so
//! the rules are tested with plain `#[test]`s.
//!
//! The rules it holds: responses pair with the requests in the order they were sent, checked by
//! [`pairing`](super::pairing) (the header, the echoed fields, the response counter and what a
//! gap means); a caller that timed out or went away keeps its place, its response consumed and
//! discarded; a response that fits the next request rather than the oldest drops the oldest's
//! slot when nobody is owed it; the give-up clock of the oldest request (`crate::give_up`); and
//! what each waiting call gets when the connection breaks.

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Duration;

use tokio::time::Instant;

use super::pairing::{ambiguous, check_response, Counted, Pairing};
use crate::caller::Caller;
use crate::give_up::GiveUp;
use crate::smartgrasp::error::{Error, Malformed, Result};
use crate::smartgrasp::frame::{
    AnyRequestFrame as RequestFrame, AnyResponseFrame as ResponseFrame,
};
use crate::smartgrasp::message::Request;
use crate::smartgrasp::types::MessageType;

/// Requests sent and not yet answered, at most (plus one marker, see
/// [`InFlight::marker_before`]). Bounds the waiting queue when a server stops answering; further
/// calls wait in the channel and run into their timeouts.
pub(crate) const MAX_IN_FLIGHT: usize = 16;

/// A call's timeout as the queue keeps it: nanoseconds, saturated at `u64::MAX` (584 years: no
/// timeout). Eight bytes, not a `Duration`'s sixteen, and converted back only where it is used
/// (restoring a set-up request, `Session::record`): a [`Call`](super::link::Call) then stays
/// within the 128 bytes x86-64 moves inline (at 136 bytes every move through the task's channel
/// became a `memcpy` call, +385 instructions per query), and a round trip spends no division on
/// it (BENCHMARKS.md, "Issue 30: the last of SmartGrasp's cost").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct CallTimeout(u64);

impl CallTimeout {
    /// `timeout`, saturated.
    #[inline]
    pub(crate) fn new(timeout: Duration) -> Self {
        CallTimeout(u64::try_from(timeout.as_nanos()).unwrap_or(u64::MAX))
    }

    /// The timeout (to the nanosecond; `Duration::MAX` comes back as 584 years).
    pub(crate) fn duration(self) -> Duration {
        Duration::from_nanos(self.0)
    }
}

/// A request on the wire, waiting for its response.
struct Waiting<C> {
    request: RequestFrame,
    caller: C,
    /// Its call's deadline plus the give-up margin, counted again from when it reaches the front
    /// (`crate::give_up`): a server that has not answered by then is not answering, and the
    /// connection is given up.
    give_up: GiveUp,
    /// Its call's timeout, handed back with its response ([`Event::Paired`]).
    timeout: CallTimeout,
}

/// What pairing a response asks of the link, handed over one at a time, in order.
#[derive(Debug)]
pub(crate) enum Event<'a, C> {
    /// The response counter skipped (manual 3.2.2.3): record it, a warning and the count the
    /// handles read ([`Client::counter_gaps`](super::Client::counter_gaps)).
    Gap {
        /// The counter the response should have carried.
        expected: u8,
        /// The counter it carried.
        received: u8,
        /// The response's message type.
        message_type: MessageType,
    },
    /// Complete `caller`'s call with `response`, the answer to `request` (normalised, see
    /// [`normalised`]), received within the call's `timeout` (the session records the set-up
    /// requests the server accepted, with the timeout they were answered within).
    Paired {
        /// The call's caller (it may have gone away: the response is then discarded).
        caller: C,
        /// The request answered.
        request: &'a RequestFrame,
        /// Its response (by reference: a frame is large, and the link copies it once, into the
        /// reply).
        response: &'a ResponseFrame,
        /// The call's timeout.
        timeout: CallTimeout,
    },
    /// Complete `caller`'s call with `error`.
    Failed {
        /// The call's caller.
        caller: C,
        /// What its call gets.
        error: Error,
    },
}

/// The queue of requests in flight on one connection and its pairing state.
pub(crate) struct InFlight<C> {
    /// At most [`MAX_IN_FLIGHT`], plus a marker.
    waiting: VecDeque<Waiting<C>>,
    pairing: Pairing,
    /// The last response paired, to recognise an exact repeat of it in strict counter mode
    /// (see `on_response`).
    last_response: Option<ResponseFrame>,
    /// See [`ClientConfig::give_up_after`](super::ClientConfig::give_up_after).
    give_up_after: Duration,
}

// The small methods a round trip calls are `#[inline]`: out of line, the queue's boundary cost
// about 20 instructions per call (BENCHMARKS.md, "Issue 30: SmartGrasp's queue in flight").
impl<C: Caller> InFlight<C> {
    /// An empty queue; `strict`: trust the response counter ([`Pairing::strict`]).
    pub(crate) fn new(strict: bool, give_up_after: Duration) -> Self {
        InFlight {
            waiting: VecDeque::with_capacity(MAX_IN_FLIGHT),
            pairing: if strict {
                Pairing::strict()
            } else {
                Pairing::default()
            },
            last_response: None,
            give_up_after,
        }
    }

    /// Whether another call may be sent.
    #[inline]
    pub(crate) fn has_room(&self) -> bool {
        self.waiting.len() < MAX_IN_FLIGHT
    }

    /// How many requests wait for their response.
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.waiting.len()
    }

    /// The give-up clock of a request sent now whose caller waits until `deadline`: its response
    /// is awaited until `deadline` plus the give-up margin (the call's own deadline, not the
    /// configured timeout of its type: a handle made with
    /// [`Client::with_timeout`](super::Client::with_timeout) for a slow detection must not lose
    /// a healthy connection at the configured timeout; issue 21). Its
    /// [`limit`](GiveUp::limit) bounds the request's write too. Behind other requests its clock
    /// starts again when it reaches the front, with the time its caller had left when it was
    /// sent (`crate::give_up`): `now` is read only then.
    #[inline]
    pub(crate) fn give_up_for(&self, deadline: Instant, now: impl FnOnce() -> Instant) -> GiveUp {
        GiveUp::new(
            deadline,
            self.give_up_after,
            self.waiting.is_empty(),
            || deadline.saturating_duration_since(now()),
        )
    }

    /// Queues a request that was written, with its clock from [`InFlight::give_up_for`].
    #[inline]
    pub(crate) fn push(
        &mut self,
        request: RequestFrame,
        caller: C,
        give_up: GiveUp,
        timeout: CallTimeout,
    ) {
        self.waiting.push_back(Waiting {
            request,
            caller,
            give_up,
            timeout,
        });
    }

    /// When the oldest request's response is so late that the connection must be given up
    /// (later responses cannot come before it); `None` with nothing in flight. `now` is read only
    /// when a request has just reached the front behind another (its give-up clock starts then).
    #[inline]
    pub(crate) fn give_up_at(&mut self, now: impl FnOnce() -> Instant) -> Option<Instant> {
        self.waiting.front_mut().map(|w| w.give_up.at_front(now))
    }

    /// The give-up time has come (`now`): the reason the connection is given up
    /// ([`Error::ConnectionLost`]), or `None` if nothing is overdue. A server that stays
    /// connected but stops answering would otherwise hold every slot for ever, and every later
    /// call would time out.
    pub(crate) fn on_timeout(&mut self, now: Instant) -> Option<Error> {
        let front = self.waiting.front_mut()?;
        if front.give_up.at_front(|| now) > now {
            return None;
        }
        let request = front.request.header().message_type;
        tracing::error!(?request, give_up_after = ?self.give_up_after, "smartgrasp: response overdue, giving up on the connection");
        Some(Error::ConnectionLost {
            reason: format!(
                "no response to {request} within its timeout and {:?} more: the server stopped answering",
                self.give_up_after
            )
            .into(),
        })
    }

    /// Responses carry no request id. Right behind a request whose caller gave up, the response
    /// to a request of the same type could be either's: the abandoned one's, late, or this one's
    /// if the abandoned request never reached the server. A request of another type in between
    /// (a side-effect-free query, returned here in `version` to be sent first, its caller one
    /// that has given up) tells them apart: whichever way the abandoned request went, its slot
    /// is settled by the time the marker's response arrives (see `on_response`), and the next
    /// response is this request's. Costs one query, only after a call was given up.
    pub(crate) fn marker_before(&self, next: &RequestFrame, version: u16) -> Option<RequestFrame> {
        let back = self.waiting.back()?;
        let ambiguous = ambiguous(
            back.request.header().message_type,
            next.header().message_type,
        );
        if !ambiguous || !back.caller.gave_up() {
            return None;
        }
        let marker = match next.header().message_type {
            MessageType::GetProtocolVersion => Request::GetState,
            _ => Request::GetProtocolVersion,
        };
        marker.to_any_frame(version).ok()
    }

    /// Pairs the response to `request`, sent with nothing else in flight (the opening sequence):
    /// its counter (a gap is an [`Event::Gap`]) and [`check_response`]. `Ok`: the response,
    /// normalised. `Err`: the connection must be dropped.
    pub(crate) fn on_exchange(
        &mut self,
        request: &RequestFrame,
        frame: &ResponseFrame,
        out: &mut impl FnMut(Event<'_, C>),
    ) -> Result<ResponseFrame> {
        let counted = self.pairing.counter(frame.header().response_counter, 1)?;
        gap(&counted, frame, out);
        check_response(request, frame)?;
        self.last_response = Some(*frame);
        Ok(normalised(request, frame))
    }

    /// Pairs one response: the calls it completes, in order, and a counter gap go to `out`.
    /// `Err`: the connection must be given up (the paired call, if any, got the error too; the
    /// others are completed by [`InFlight::drain`]).
    pub(crate) fn on_response(
        &mut self,
        frame: &ResponseFrame,
        out: &mut impl FnMut(Event<'_, C>),
    ) -> Result<()> {
        if self.pairing.is_strict() && self.last_response.as_ref() == Some(frame) {
            // The same bytes again, counter included, from a server known to count its responses
            // per connection (strict mode): a copy, not a new answer. Skipped. Only in strict
            // mode: a server whose counter never moves (SCHUNK's KRL never reads it) or counts
            // across its clients (the same value after 256 responses) sends identical responses
            // that are real answers (issue 21), and TCP itself never duplicates a segment.
            tracing::warn!(
                counter = frame.header().response_counter,
                "repeated response skipped"
            );
            return Ok(());
        }
        let received = frame.header().response_counter;
        let counted = self.pairing.counter(received, self.waiting.len())?;
        gap(&counted, frame, out);
        for i in 0..counted.lost {
            if let Some(w) = self.waiting.pop_front() {
                let expected = counted.expected.wrapping_add(i as u8);
                tracing::warn!(expected, received, request = %w.request.header().message_type, "response lost");
                out(Event::Failed {
                    caller: w.caller,
                    error: Error::ResponseLost { expected, received },
                });
            }
        }
        let Some(mut w) = self.waiting.pop_front() else {
            // `counter` guarantees one is left; treat it as unsolicited all the same.
            return Err(Malformed::Unsolicited { counter: received }.into());
        };
        if let Err(e) = check_response(&w.request, frame) {
            // The server answers in order, so a response that does not fit the oldest request
            // but fits the next one means the oldest was never answered: it was lost before it
            // reached the server (no counter gap), or the server answered nothing (the counter
            // skipped). If its caller has already given up, nobody is owed anything: drop its
            // slot and go on. A caller still waiting gets [`Error::ResponseLost`] when the
            // counter skipped too (two signs agree); otherwise the error, and the connection is
            // closed.
            let fits_next = counted.lost == 0
                && self
                    .waiting
                    .front()
                    .is_some_and(|next| check_response(&next.request, frame).is_ok());
            if !fits_next || !(w.caller.gave_up() || counted.gap != 0) {
                let e = Error::from(e);
                out(Event::Failed {
                    caller: w.caller,
                    error: e.clone(),
                });
                return Err(e);
            }
            tracing::warn!(request = %w.request.header().message_type, "a request was never answered; its slot is dropped");
            out(Event::Failed {
                caller: w.caller,
                error: Error::ResponseLost {
                    expected: counted.expected,
                    received,
                },
            });
            match self.waiting.pop_front() {
                Some(next) => w = next,
                None => return Err(Malformed::Unsolicited { counter: received }.into()),
            }
        }
        self.last_response = Some(*frame);
        // Copied only to be normalised: a frame is large, and the link copies it into the reply.
        let erratum;
        let response = if frame.header().message_type == w.request.header().message_type {
            frame
        } else {
            erratum = normalised(&w.request, frame);
            &erratum
        };
        out(Event::Paired {
            response,
            request: &w.request,
            caller: w.caller,
            timeout: w.timeout,
        });
        Ok(())
    }

    /// The connection broke for `reason`: every call still waiting, oldest first, with what it
    /// gets ([`waiting_error`]). The queue is empty afterwards.
    pub(crate) fn drain(&mut self, reason: &Error, mut out: impl FnMut(C, Error)) {
        for w in self.waiting.drain(..) {
            out(w.caller, waiting_error(reason));
        }
    }
}

/// Hands a counter gap to `out`.
fn gap<C>(counted: &Counted, frame: &ResponseFrame, out: &mut impl FnMut(Event<'_, C>)) {
    if counted.gap != 0 {
        out(Event::Gap {
            expected: counted.expected,
            received: frame.header().response_counter,
            message_type: frame.header().message_type,
        });
    }
}

/// A paired response with the message type of its request: a GET_OBJECT_COUNT answered as type
/// 17 (see [`answers`](super::pairing::answers)) is read as the count it is.
fn normalised(request: &RequestFrame, frame: &ResponseFrame) -> ResponseFrame {
    let mut frame = *frame;
    if frame.header().message_type != request.header().message_type {
        tracing::warn!(
            request = %request.header().message_type,
            response = %frame.header().message_type,
            "smartgrasp: response with the manual's erratum message type accepted"
        );
        frame.header_mut().message_type = request.header().message_type;
    }
    frame
}

/// What a call that was sent and still waits gets when the connection breaks. A header error
/// was already given to the call whose response carried it; the others only lost the connection.
fn waiting_error(reason: &Error) -> Error {
    match reason {
        Error::MalformedReply(
            Malformed::MessageType { .. }
            | Malformed::CommunicationType(_)
            | Malformed::Version { .. }
            | Malformed::Echo { .. }
            | Malformed::Unsolicited { .. },
        ) => closed_error(Some(reason)),
        // Stream-level reasons (I/O, bad length, too old, lost responses) concern every call.
        other => other.clone(),
    }
}

/// What a call gets on a connection that is already gone (or never got to send its request).
pub(crate) fn closed_error(reason: Option<&Error>) -> Error {
    match reason {
        Some(Error::ConnectionLost { reason }) => Error::ConnectionLost {
            reason: Arc::clone(reason),
        },
        // Still the answer to every later call, and typed so a program can tell the user.
        Some(e @ (Error::ServerTooOld { .. } | Error::Closed)) => e.clone(),
        Some(reason) => Error::ConnectionLost {
            reason: reason.to_string().into(),
        },
        None => Error::ConnectionLost {
            reason: "the connection task has ended".into(),
        },
    }
}

/// The rules driven without a runtime: plain `#[test]`s, the clock passed in.
#[cfg(test)]
mod tests {
    use std::cell::Cell;
    use std::rc::Rc;

    use super::*;
    use crate::caller::test::Call;
    use crate::deadline::after;
    use crate::smartgrasp::frame::ResponseFrame as V3Response;
    use crate::smartgrasp::types::ResponseCode;

    const S: Duration = Duration::from_secs(1);
    const GIVE_UP_AFTER: Duration = Duration::from_secs(30);

    /// What the queue asked of the link, by caller number.
    #[derive(Debug)]
    enum Done {
        Gap { expected: u8, received: u8 },
        Paired(u8, ResponseFrame, Duration),
        Failed(u8, Error),
    }

    fn queue(strict: bool) -> InFlight<Call> {
        InFlight::new(strict, GIVE_UP_AFTER)
    }

    /// Sends `request` as call `id` at `now`, its caller waiting `timeout`; the handle that makes
    /// its caller give up.
    fn send(
        q: &mut InFlight<Call>,
        id: u8,
        request: &Request,
        now: Instant,
        timeout: Duration,
    ) -> Rc<Cell<bool>> {
        let gone = Rc::new(Cell::new(false));
        let deadline = after(now, timeout);
        let give_up = q.give_up_for(deadline, || now);
        let call = Call {
            id,
            gone: Rc::clone(&gone),
        };
        q.push(
            request.to_any_frame(3).unwrap(),
            call,
            give_up,
            CallTimeout::new(timeout),
        );
        gone
    }

    fn respond(q: &mut InFlight<Call>, frame: V3Response) -> (Result<()>, Vec<Done>) {
        let mut done = Vec::new();
        let result = q.on_response(&frame.into(), &mut |event| done.push(record(event)));
        (result, done)
    }

    fn record(event: Event<'_, Call>) -> Done {
        match event {
            Event::Gap {
                expected, received, ..
            } => Done::Gap { expected, received },
            Event::Paired {
                caller,
                response,
                timeout,
                ..
            } => Done::Paired(caller.id, *response, timeout.duration()),
            Event::Failed { caller, error } => Done::Failed(caller.id, error),
        }
    }

    fn count_of(object_class: u16, counter: u8) -> V3Response {
        let mut f = V3Response::new(MessageType::GetObjectCount, ResponseCode::Success, counter);
        f.object_class = object_class;
        f
    }

    fn state(counter: u8) -> V3Response {
        V3Response::new(MessageType::GetState, ResponseCode::Success, counter)
    }

    fn paired_ids(done: &[Done]) -> Vec<u8> {
        done.iter()
            .filter_map(|d| match d {
                Done::Paired(id, ..) => Some(*id),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn responses_complete_the_calls_in_the_order_they_were_sent() {
        let t0 = Instant::now();
        let mut q = queue(false);
        send(&mut q, 1, &Request::GetState, t0, 2 * S);
        send(
            &mut q,
            2,
            &Request::GetObjectCount { object_class: 2 },
            t0,
            5 * S,
        );
        let (result, done) = respond(&mut q, state(7));
        assert!(result.is_ok());
        assert!(
            matches!(&done[..], [Done::Paired(1, r, t)] if *r == state(7).into() && *t == 2 * S),
            "{done:?}"
        );
        let (result, done) = respond(&mut q, count_of(2, 8));
        assert!(result.is_ok());
        assert_eq!(paired_ids(&done), [2]);
        assert_eq!(q.len(), 0);
    }

    #[test]
    fn an_abandoned_call_keeps_its_place_and_its_response_is_its_own() {
        let t0 = Instant::now();
        let mut q = queue(false);
        let gone = send(&mut q, 1, &Request::GetState, t0, S);
        send(&mut q, 2, &Request::GetState, t0, S);
        gone.set(true);
        // The late response still goes to call 1's slot (the link discards it), not to call 2.
        let (_, done) = respond(&mut q, state(0));
        assert_eq!(paired_ids(&done), [1]);
        let (_, done) = respond(&mut q, state(1));
        assert_eq!(paired_ids(&done), [2]);
    }

    #[test]
    fn a_response_that_fits_the_next_request_drops_an_abandoned_slot() {
        let t0 = Instant::now();
        let mut q = queue(false);
        let gone = send(&mut q, 1, &Request::GetState, t0, S);
        send(
            &mut q,
            2,
            &Request::GetObjectCount { object_class: 2 },
            t0,
            S,
        );
        gone.set(true);
        let (result, done) = respond(&mut q, count_of(2, 0));
        assert!(result.is_ok());
        assert!(
            matches!(
                &done[..],
                [
                    Done::Failed(1, Error::ResponseLost { .. }),
                    Done::Paired(2, ..)
                ]
            ),
            "{done:?}"
        );
        assert_eq!(q.len(), 0);
    }

    #[test]
    fn a_response_that_fits_nobody_waiting_breaks_the_connection() {
        let t0 = Instant::now();
        let mut q = queue(false);
        send(&mut q, 1, &Request::GetState, t0, S);
        send(
            &mut q,
            2,
            &Request::GetObjectCount { object_class: 2 },
            t0,
            S,
        );
        // Call 1 still waits and the counter did not skip: the error, not call 2's answer.
        let (result, done) = respond(&mut q, count_of(2, 0));
        let reason = result.unwrap_err();
        assert!(
            matches!(
                &reason,
                Error::MalformedReply(Malformed::MessageType { .. })
            ),
            "{reason}"
        );
        assert!(
            matches!(
                &done[..],
                [Done::Failed(
                    1,
                    Error::MalformedReply(Malformed::MessageType { .. })
                )]
            ),
            "{done:?}"
        );
        // The others only lost the connection.
        let mut rest = Vec::new();
        q.drain(&reason, |call, error| rest.push((call.id, error)));
        assert!(
            matches!(&rest[..], [(2, Error::ConnectionLost { .. })]),
            "{rest:?}"
        );
        assert_eq!(q.len(), 0);
    }

    #[test]
    fn a_stream_level_reason_reaches_every_waiting_call_as_it_is() {
        let t0 = Instant::now();
        let mut q = queue(false);
        send(&mut q, 1, &Request::GetState, t0, S);
        send(&mut q, 2, &Request::GetState, t0, S);
        let reason = Error::ResponseLost {
            expected: 1,
            received: 3,
        };
        let mut rest = Vec::new();
        q.drain(&reason, |call, error| rest.push((call.id, error)));
        assert!(
            matches!(
                &rest[..],
                [
                    (1, Error::ResponseLost { .. }),
                    (2, Error::ResponseLost { .. })
                ]
            ),
            "{rest:?}"
        );
    }

    #[test]
    fn a_counter_gap_is_recorded_and_by_default_charges_nobody() {
        let t0 = Instant::now();
        let mut q = queue(false);
        send(&mut q, 1, &Request::GetState, t0, S);
        send(&mut q, 2, &Request::GetState, t0, S);
        assert!(respond(&mut q, state(10)).0.is_ok());
        let (result, done) = respond(&mut q, state(12));
        assert!(result.is_ok());
        assert!(
            matches!(
                &done[..],
                [
                    Done::Gap {
                        expected: 11,
                        received: 12
                    },
                    Done::Paired(2, ..)
                ]
            ),
            "{done:?}"
        );
    }

    #[test]
    fn in_strict_mode_a_gap_fails_the_oldest_calls_with_response_lost() {
        let t0 = Instant::now();
        let mut q = queue(true);
        send(&mut q, 1, &Request::GetState, t0, S);
        assert!(respond(&mut q, state(10)).0.is_ok());
        send(&mut q, 2, &Request::GetState, t0, S);
        send(&mut q, 3, &Request::GetState, t0, S);
        let (result, done) = respond(&mut q, state(12));
        assert!(result.is_ok());
        assert!(
            matches!(
                &done[..],
                [
                    Done::Gap { .. },
                    Done::Failed(
                        2,
                        Error::ResponseLost {
                            expected: 11,
                            received: 12
                        }
                    ),
                    Done::Paired(3, ..)
                ]
            ),
            "{done:?}"
        );
    }

    #[test]
    fn in_strict_mode_an_exact_repeat_is_skipped_by_default_it_is_an_answer() {
        let t0 = Instant::now();
        for (strict, paired) in [(true, vec![]), (false, vec![2])] {
            let mut q = queue(strict);
            send(&mut q, 1, &Request::GetState, t0, S);
            send(&mut q, 2, &Request::GetState, t0, S);
            assert!(respond(&mut q, state(4)).0.is_ok());
            let (result, done) = respond(&mut q, state(4));
            assert!(result.is_ok());
            assert_eq!(paired_ids(&done), paired, "strict: {strict}");
        }
    }

    #[test]
    fn a_response_with_nothing_in_flight_is_unsolicited() {
        let (result, done) = respond(&mut queue(false), state(0));
        assert!(matches!(
            result,
            Err(Error::MalformedReply(Malformed::Unsolicited { counter: 0 }))
        ));
        assert!(done.is_empty());
    }

    #[test]
    fn the_erratum_type_of_a_count_is_read_as_the_count() {
        let t0 = Instant::now();
        let mut q = queue(false);
        send(
            &mut q,
            1,
            &Request::GetObjectCount { object_class: 2 },
            t0,
            S,
        );
        let mut seventeen = count_of(2, 0);
        seventeen.header.message_type = MessageType::GraspFeedback;
        let (_, done) = respond(&mut q, seventeen);
        assert!(
            matches!(&done[..], [Done::Paired(1, r, _)] if r.header().message_type == MessageType::GetObjectCount),
            "{done:?}"
        );
    }

    #[test]
    fn the_oldest_request_gives_the_connection_up_past_its_deadline_and_the_margin() {
        let t0 = Instant::now();
        let mut q = queue(false);
        assert_eq!(q.give_up_at(|| unreachable!("nothing in flight")), None);
        assert!(q.on_timeout(t0).is_none());
        // Sent to an idle connection: the clock is not read.
        let deadline = t0 + 2 * S;
        let give_up = q.give_up_for(deadline, || unreachable!("not asked at the front"));
        assert_eq!(give_up.limit(), t0 + 32 * S);
        q.push(
            Request::GetState.to_any_frame(3).unwrap(),
            Call {
                id: 1,
                gone: Rc::default(),
            },
            give_up,
            CallTimeout::new(2 * S),
        );
        assert_eq!(
            q.give_up_at(|| unreachable!("at the front from the start")),
            Some(t0 + 32 * S)
        );
        assert!(q.on_timeout(t0 + 31 * S).is_none());
        let overdue = q.on_timeout(t0 + 32 * S).unwrap();
        assert!(
            matches!(&overdue, Error::ConnectionLost { reason } if reason.contains("stopped answering")),
            "{overdue}"
        );
    }

    #[test]
    fn a_request_behind_another_counts_its_give_up_clock_from_the_front() {
        let t0 = Instant::now();
        let mut q = queue(false);
        // A 60 s call, then a 2 s query behind it sent at t0.
        send(&mut q, 1, &Request::GetState, t0, 60 * S);
        send(&mut q, 2, &Request::GetState, t0, 2 * S);
        assert_eq!(q.give_up_at(|| t0), Some(t0 + 90 * S));
        // The long call is answered at t0 + 40 s: the query has 2 s and the margin from then.
        assert!(respond(&mut q, state(0)).0.is_ok());
        assert_eq!(q.give_up_at(|| t0 + 40 * S), Some(t0 + 72 * S));
        assert!(q.on_timeout(t0 + 71 * S).is_none());
        assert!(q.on_timeout(t0 + 72 * S).is_some());
    }

    #[test]
    fn a_marker_goes_between_an_abandoned_call_and_one_its_response_could_answer() {
        let t0 = Instant::now();
        let mut q = queue(false);
        let count = Request::GetObjectCount { object_class: 1 }
            .to_any_frame(3)
            .unwrap();
        let version = Request::GetProtocolVersion.to_any_frame(3).unwrap();
        assert!(q.marker_before(&count, 3).is_none());
        let gone = send(
            &mut q,
            1,
            &Request::GetObjectCount { object_class: 1 },
            t0,
            S,
        );
        // Its caller still waits: the next response is its own.
        assert!(q.marker_before(&count, 3).is_none());
        gone.set(true);
        let marker = q.marker_before(&count, 3).unwrap();
        assert_eq!(
            marker.header().message_type,
            MessageType::GetProtocolVersion
        );
        // Another type cannot be mistaken for it.
        assert!(q
            .marker_before(&Request::GetState.to_any_frame(3).unwrap(), 3)
            .is_none());
        // Behind an abandoned GET_PROTOCOL_VERSION, the marker is GET_STATE.
        let gone = send(&mut q, 2, &Request::GetProtocolVersion, t0, S);
        gone.set(true);
        let marker = q.marker_before(&version, 3).unwrap();
        assert_eq!(marker.header().message_type, MessageType::GetState);
    }

    #[test]
    fn there_is_room_for_max_in_flight_requests() {
        let t0 = Instant::now();
        let mut q = queue(false);
        for id in 0..MAX_IN_FLIGHT as u8 {
            assert!(q.has_room());
            send(&mut q, id, &Request::GetState, t0, S);
        }
        assert!(!q.has_room());
        assert!(respond(&mut q, state(0)).0.is_ok());
        assert!(q.has_room());
    }

    #[test]
    fn an_exchange_checks_its_response_and_learns_the_counter() {
        let mut q = queue(false);
        let request = Request::GetState.to_any_frame(3).unwrap();
        let mut gaps = Vec::new();
        let mut out = |event: Event<'_, Call>| gaps.push(record(event));
        assert_eq!(
            q.on_exchange(&request, &state(5).into(), &mut out).unwrap(),
            state(5).into()
        );
        assert!(q
            .on_exchange(&request, &count_of(0, 6).into(), &mut out)
            .is_err());
        // The counter was learned across both: 8 where 7 was due is a gap.
        q.on_exchange(&request, &state(8).into(), &mut out).unwrap();
        assert!(
            matches!(
                &gaps[..],
                [Done::Gap {
                    expected: 7,
                    received: 8
                }]
            ),
            "{gaps:?}"
        );
        // The calls served next are paired from there: 9 is on time.
        let t0 = Instant::now();
        send(&mut q, 1, &Request::GetState, t0, S);
        let (result, done) = respond(&mut q, state(9));
        assert!(result.is_ok());
        assert_eq!(paired_ids(&done), [1]);
    }
}
