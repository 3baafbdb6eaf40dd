//! The serve loop's wait for [`Client::close`](super::Client::close), cheap to poll again.
//!
//! The loop's `select!` polls the shutdown branch first on every poll of the task, several times
//! per round trip. A `CancellationToken`'s wait takes two mutexes on each poll (the token's
//! state, then its waiter list), a measurable part of a round trip's cost (issue 14). Once the
//! wait is registered with the task's waker it only needs polling again if the token was
//! cancelled (one mutex) or the waker changed: `cancel()` wakes the registered waker.

use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll, Waker};

use tokio_util::sync::{CancellationToken, WaitForCancellationFuture};

/// Completes when the token is cancelled, like [`CancellationToken::cancelled`].
pub(crate) struct Shutdown<'a> {
    token: &'a CancellationToken,
    wait: Pin<Box<WaitForCancellationFuture<'a>>>,
    /// The waker `wait` was last polled with; `None` before its first poll.
    registered: Option<Waker>,
}

impl<'a> Shutdown<'a> {
    pub(crate) fn new(token: &'a CancellationToken) -> Shutdown<'a> {
        Shutdown {
            token,
            wait: Box::pin(token.cancelled()),
            registered: None,
        }
    }
}

impl Future for Shutdown<'_> {
    type Output = ();

    fn poll(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<()> {
        let this = self.get_mut();
        let same_waker = this
            .registered
            .as_ref()
            .is_some_and(|w| w.will_wake(cx.waker()));
        if same_waker && !this.token.is_cancelled() {
            // Registered with this waker and not cancelled: polling `wait` would return
            // `Pending` and change nothing.
            return Poll::Pending;
        }
        let polled = this.wait.as_mut().poll(cx);
        if polled.is_pending() && !same_waker {
            this.registered = Some(cx.waker().clone());
        }
        polled
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Arc;
    use std::task::Wake;

    #[derive(Default)]
    struct Count(AtomicUsize);

    impl Wake for Count {
        fn wake(self: Arc<Self>) {
            self.0.fetch_add(1, Ordering::SeqCst);
        }
    }

    fn poll(shutdown: &mut Shutdown<'_>, waker: &Waker) -> Poll<()> {
        Pin::new(shutdown).poll(&mut Context::from_waker(waker))
    }

    #[test]
    fn cancel_wakes_the_last_waker_and_completes() {
        let token = CancellationToken::new();
        let mut shutdown = Shutdown::new(&token);
        let (first, second) = (Arc::new(Count::default()), Arc::new(Count::default()));
        let (first_waker, second_waker) = (Waker::from(first.clone()), Waker::from(second.clone()));
        assert!(poll(&mut shutdown, &first_waker).is_pending());
        assert!(poll(&mut shutdown, &first_waker).is_pending());
        // A new waker is registered, not skipped.
        assert!(poll(&mut shutdown, &second_waker).is_pending());
        token.cancel();
        assert_eq!(second.0.load(Ordering::SeqCst), 1);
        assert_eq!(first.0.load(Ordering::SeqCst), 0);
        assert!(poll(&mut shutdown, &second_waker).is_ready());
    }

    #[test]
    fn a_token_cancelled_before_the_first_poll_completes_at_once() {
        let token = CancellationToken::new();
        token.cancel();
        let waker = Waker::from(Arc::new(Count::default()));
        assert!(poll(&mut Shutdown::new(&token), &waker).is_ready());
    }
}
