//! A caller waiting for its answer, as the line protocols' state machines without I/O see it
//! (GRIPLINK's pipeline, the WSG text client's book; issue 30): an opaque token they hold in
//! a command's place and hand back to their task to complete, and only ask whether it gave up.
//! The task's token is the call's reply channel; a unit test's is whatever it can watch.

use tokio::sync::oneshot;

/// A caller waiting for the answer to its command (SmartGrasp's queue in flight has the same
/// trait, `smartgrasp::client::in_flight::Caller`).
pub(crate) trait Caller {
    /// Whether the caller stopped waiting (timed out or went away): nobody is owed its answer.
    fn gave_up(&self) -> bool;
}

/// A call's reply channel: its caller gave up when the receiving end is gone.
impl<T> Caller for oneshot::Sender<T> {
    #[inline]
    fn gave_up(&self) -> bool {
        self.is_closed()
    }
}
