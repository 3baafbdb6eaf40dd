//! Recovery of ids whose requests went unanswered (the task's half of the rules in
//! [`super::super::pairing`]): releases, stop re-sends, loop-back barriers that prove a reply
//! lost before its id is reused, and the "is it still moving?" probes of motions under recovery.

use std::io;
use std::time::Duration;

use bytes::Bytes;
use tokio::time::Instant;

use super::{send_within, Task, Waiter, BARRIER_PREFIX, BARRIER_REFUSALS};
use crate::deadline::after;
use crate::wsg::client::pairing::{Due, Observation, Request, Token, Verdict};
use crate::wsg::command::{id, Command, UpdateMode};
use crate::wsg::{Error, Frame};

impl Task {
    /// A request's time has come: its id is released, or its recovery needs a probe.
    pub(super) async fn on_due(&mut self, due: Due) -> io::Result<()> {
        match due {
            Due::Released(id, token) => {
                tracing::warn!(
                    id,
                    "no (final) reply within timeout + grace: command id released; \
                    a reply arriving later would be taken for the next request of this id"
                );
                self.unanswered(id, token).await?;
                self.send_next(id);
                Ok(())
            }
            Due::Fenced(id, token) => {
                tracing::warn!(
                    id,
                    "no reply within timeout + grace: the next request of this id waits for \
                    the echo of a loop-back (a reply before it is the late one)"
                );
                self.unanswered(id, token).await?;
                self.send_barrier(id, 0).await
            }
            Due::Probe(id, token) => self.send_probe(id, token).await,
            Due::ResendStop(id) => {
                tracing::debug!(
                    id,
                    "no reply to a stop sent at or after a waiting stop call: sent again"
                );
                self.send_stop(id).await
            }
            Due::StopBarrier(id) => {
                tracing::debug!(
                    id,
                    "stops unanswered: a loop-back's echo tells a lost reply from a late one"
                );
                self.send_barrier(id, 0).await
            }
        }
    }

    /// Sends stop or FAST STOP `id` again, at once (the pairing recorded it as sent).
    pub(super) async fn send_stop(&mut self, id: u8) -> io::Result<()> {
        send_within(
            &mut self.link,
            &Frame::new(id, Bytes::new()),
            self.write_timeout,
        )
        .await
    }

    /// Request `token` was released with no usable answer: its waiter goes; a probe counts as
    /// "unknown", a barrier is sent again (its id stays fenced until one comes back).
    pub(super) async fn unanswered(&mut self, id: u8, token: Token) -> io::Result<()> {
        match self.waiters.remove(&token) {
            Some(Waiter::Probe {
                id: motion,
                token: t,
            }) => self.on_probe(motion, t, Observation::Unknown, token).await,
            Some(Waiter::Barrier { id, refused }) => self.send_barrier(id, refused).await,
            Some(Waiter::Settle { id, query }) => {
                self.pairing.settle_failed(id, query);
                Ok(())
            }
            // A caller still waiting is one without timeout (`Duration::MAX`), or a motion
            // command's whose acknowledgement did not come, released by the hold of
            // `Pairing::set_holds`: the timeout applied was the connection's query timeout
            // (the default one when the connection has none). (A caller with a timeout keeps
            // its id past its own deadline, by which its call has failed with its own timeout.)
            Some(Waiter::Caller(tx)) => {
                let _ = tx.send(Err(Error::Timeout {
                    command: id,
                    timeout: self.pairing.reply_hold(),
                }));
                Ok(())
            }
            // An internal request: forgotten.
            Some(Waiter::Internal) | None => Ok(()),
        }
    }

    /// Sends a loop-back (0x06, manual 3.1.1) with a payload no other request carries, for
    /// the fenced command id `id`. On a byte stream its echo comes after the reply to every
    /// request sent before it: the device answers the commands of one connection one after
    /// the other, and the stream keeps the order. (The manual does not promise this in so many
    /// words; it is what its request-reply scheme (1.2.2) implies for immediate replies.)
    pub(super) async fn send_barrier(&mut self, id: u8, refused: u8) -> io::Result<()> {
        let req = self.barrier(Waiter::Barrier { id, refused });
        self.submit(req).await
    }

    /// A loop-back request (0x06) with a payload no other request carries, for `waiter`.
    pub(super) fn barrier(&mut self, waiter: Waiter) -> Request {
        let token = self.waiter(waiter);
        let mut payload = BARRIER_PREFIX.to_vec();
        payload.extend_from_slice(&token.to_le_bytes());
        Request {
            token,
            frame: Frame::new(id::LOOP, payload),
            // No caller waits, so no deadline: the pairing's reply hold releases it the query
            // timeout plus the grace after it is *sent*. A deadline from now would run while
            // it waits behind other loop-backs (one per fenced id): it would be released as
            // soon as sent, before its echo could come, and sent again at once, keeping the
            // line busy without a pause. A device whose decoder holds a frame with a corrupted
            // length until the line falls silent never got that pause: every fenced id stayed
            // fenced (explorer, promise 5, wsg-serial:0xa5e34824226a756b).
            deadline: after(Instant::now(), Duration::MAX),
        }
    }

    /// A barrier of fenced id `id` got an answer other than its echo (a refusal, a malformed
    /// reply): it may be a stale answer to an earlier loop-back, so another barrier goes out.
    /// Not for ever: a device that refuses every loop-back would have the task send them as
    /// fast as it answers. After [`BARRIER_REFUSALS`] the id is released as on UDP (a reply
    /// later than the grace may then answer its next request).
    pub(super) async fn barrier_refused(&mut self, id: u8, refused: u8) -> io::Result<()> {
        let refused = refused.saturating_add(1);
        if refused < BARRIER_REFUSALS {
            return self.send_barrier(id, refused).await;
        }
        tracing::warn!(
            id,
            "the device answers no loop-back with its echo: command id released without proof \
            that no late reply is on its way"
        );
        self.unfence(id).await
    }

    /// The fence of `id` is over (its barrier's echo came, or the barrier was given up): its
    /// next request goes out, or, for a stop id, the stop is sent again if a caller still
    /// waits for one.
    pub(super) async fn unfence(&mut self, id: u8) -> io::Result<()> {
        if self.pairing.unfence(id, Instant::now()) {
            self.send_stop(id).await?;
        }
        self.send_next(id);
        Ok(())
    }

    /// Asks the device whether the acknowledged motion `token` of command `id` still runs: its
    /// caller's deadline has passed, and its final reply may be lost (see [`super::pairing`]
    /// for the rule that decides).
    pub(super) async fn send_probe(&mut self, id: u8, token: Token) -> io::Result<()> {
        let probe = self.waiter(Waiter::Probe { id, token });
        let req = Request {
            token: probe,
            frame: Command::SystemState(UpdateMode::ONCE).to_frame(),
            deadline: after(Instant::now(), self.query_timeout),
        };
        self.submit(req).await
    }

    /// Hands what probe `probe` saw to the pairing and acts on its verdict.
    pub(super) async fn on_probe(
        &mut self,
        id: u8,
        token: Token,
        seen: Observation,
        probe: Token,
    ) -> io::Result<()> {
        match self
            .pairing
            .on_probe(id, token, seen, Instant::now(), probe)
        {
            Verdict::Abandoned => {
                tracing::warn!(
                    id,
                    "the final reply of a motion command was lost (the device said twice, a \
                     grace period apart, that it does not move): id released"
                );
                if let Some(Waiter::Caller(tx)) = self.waiters.remove(&token) {
                    let _ = tx.send(Err(Error::ReplyLost { command: id }));
                }
                self.send_next(id);
                Ok(())
            }
            Verdict::Running(refused) => {
                for t in refused {
                    self.refuse(id, t);
                }
                Ok(())
            }
            Verdict::Undecided => Ok(()),
        }
    }
}
