//! The bounded tokio channels of every client (its request queue, a subscriber's or a push
//! stream's buffer), sized from a configured length the one way.

/// The capacity of a bounded tokio channel for a configured queue length `n`: at least 1 (tokio
/// panics on 0) and at most [`tokio::sync::Semaphore::MAX_PERMITS`] (tokio panics above it, e.g.
/// on `usize::MAX`). A queue that long is unbounded in practice; the channel allocates per use,
/// not up front.
pub(crate) fn channel_capacity(n: usize) -> usize {
    n.clamp(1, tokio::sync::Semaphore::MAX_PERMITS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_length_is_a_capacity_tokio_takes() {
        assert_eq!(channel_capacity(0), 1);
        assert_eq!(channel_capacity(64), 64);
        assert_eq!(
            channel_capacity(usize::MAX),
            tokio::sync::Semaphore::MAX_PERMITS
        );
        for n in [0, usize::MAX] {
            let _ = tokio::sync::mpsc::channel::<()>(channel_capacity(n));
        }
    }
}
