//! Deadlines on a connection task's hot path without a timer per operation (issue 14: making
//! and dropping a tokio timer for every request and reply was a measurable part of a round
//! trip's cost).

use std::io::ErrorKind;
use std::pin::Pin;
use std::task::Poll;

use std::time::Duration;

use tokio::io::{AsyncWrite, AsyncWriteExt};
use tokio::time::error::Elapsed;
use tokio::time::{Instant, Sleep};

/// Writes all of `bytes` by `deadline()`, as `timeout_at(deadline(), write.write_all(bytes))`
/// does. A request is short and the stream nearly always takes it whole at once, so that is
/// tried first (one write attempt), without a timer; only what the stream did not take waits,
/// timed. (`deadline` is asked only then: reading the clock for every write would cost more
/// than the write.) Any byte stream: a socket's write half, or a program's own stream.
pub(crate) async fn write_all_by<W: AsyncWrite + Unpin + ?Sized>(
    write: &mut W,
    bytes: &[u8],
    deadline: impl FnOnce() -> Instant,
) -> Result<std::io::Result<()>, Elapsed> {
    // One attempt: a stream that cannot take anything now counts as 0 bytes taken (its waker
    // is registered, and `write_all` below polls it again).
    let attempt = std::future::poll_fn(|cx| match Pin::new(&mut *write).poll_write(cx, bytes) {
        Poll::Pending => Poll::Ready(Ok(0)),
        done => done,
    })
    .await;
    let written = match attempt {
        Ok(n) => n,
        // As `write_all` would: try again.
        Err(e) if e.kind() == ErrorKind::Interrupted => 0,
        Err(e) => return Ok(Err(e)),
    };
    match bytes.get(written..) {
        Some(rest) if !rest.is_empty() => {
            tokio::time::timeout_at(deadline(), write.write_all(rest)).await
        }
        _ => Ok(Ok(())),
    }
}

/// Points a connection loop's timer, kept across its `select!` passes, at `at`: resetting it
/// costs a timer-wheel operation, so only when the deadline changes.
pub(crate) fn move_timer(timer: Pin<&mut Sleep>, at: Instant) {
    if timer.deadline() != at {
        timer.reset(at);
    }
}

/// How far ahead "never" is: what `at + d` saturates to when it would overflow (about 30
/// years, as tokio's own timers use; `Instant` has no maximum to saturate to).
const FAR_FUTURE: Duration = Duration::from_secs(86_400 * 365 * 30);

/// `at + d`, saturated: a duration too long for the clock (`Duration::MAX` is the common way
/// to say "no timeout") means "never", never a panic.
pub(crate) fn after(at: Instant, d: Duration) -> Instant {
    at.checked_add(d)
        .or_else(|| at.checked_add(FAR_FUTURE))
        .unwrap_or(at)
}

/// Whether `deadline` means "no timeout": further than half of [`FAR_FUTURE`] (15 years)
/// from `now`, as [`after`] makes it of `Duration::MAX` and of any duration too long for the
/// clock. Such a caller is bounded by its connection's holds instead (wsg `Pairing`).
pub(crate) fn is_never(deadline: Instant, now: Instant) -> bool {
    // The same as `deadline - now > FAR_FUTURE / 2`, but an addition and a comparison cost
    // less than the saturating subtraction (this runs for every request).
    now.checked_add(FAR_FUTURE / 2)
        .is_none_or(|half| deadline > half)
}

/// Whether a timeout `d` means "no timeout": long enough that [`after`] makes a deadline of it
/// that [`is_never`] takes for "never" (`Duration::MAX`, or any duration over 15 years).
pub(crate) fn is_unbounded(d: Duration) -> bool {
    d > FAR_FUTURE / 2
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn after_saturates_instead_of_overflowing() {
        let now = Instant::now();
        assert_eq!(
            after(now, Duration::from_secs(1)),
            now + Duration::from_secs(1)
        );
        assert!(after(now, Duration::MAX) >= now + FAR_FUTURE);
        assert!(after(after(now, Duration::MAX), Duration::MAX) > now);
    }

    #[test]
    fn only_a_saturated_deadline_is_never() {
        let now = Instant::now();
        assert!(is_never(after(now, Duration::MAX), now));
        assert!(is_never(after(now, Duration::from_secs(u64::MAX)), now));
        assert!(!is_never(
            after(now, Duration::from_secs(86_400 * 365)),
            now
        ));
        assert!(!is_never(now, now));
        // A timeout is unbounded exactly when the deadline it makes is never.
        for d in [
            Duration::MAX,
            FAR_FUTURE / 2 + Duration::from_nanos(1),
            FAR_FUTURE / 2,
            Duration::from_secs(86_400 * 365),
        ] {
            assert_eq!(is_unbounded(d), is_never(after(now, d), now), "{d:?}");
        }
        assert!(is_unbounded(Duration::MAX));
    }
}
