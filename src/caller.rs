//! A caller waiting for its answer, as the protocols' pairing state machines without I/O see it
//! (issue 30: GRIPLINK's pipeline, SmartGrasp's queue in flight, the WSG text client's book): an
//! opaque token they hold in a request's place and hand back to their task to complete, and only
//! ask whether it gave up. The task's token is the call's reply channel; a unit test's is
//! whatever it can watch ([`test::Call`]). One trait below the protocols, so that none imports
//! another's.

use tokio::sync::oneshot;

/// A caller waiting for the answer to its request.
pub(crate) trait Caller {
    /// Whether the caller stopped waiting (timed out or went away): nobody is owed its answer.
    fn gave_up(&self) -> bool;
}

/// A call's reply channel: its caller gave up when the receiving end is gone.
impl<T> Caller for oneshot::Sender<T> {
    // Asked on every reply paired (SmartGrasp measured the call boundary, BENCHMARKS.md).
    #[inline]
    fn gave_up(&self) -> bool {
        self.is_closed()
    }
}

/// The caller the state machines' unit tests hold (plain `#[test]`s, no runtime).
#[cfg(test)]
pub(crate) mod test {
    use std::cell::Cell;
    use std::rc::Rc;

    use super::Caller;

    /// A caller: its number, and whether it gave up (shared with the test).
    #[derive(Debug)]
    pub(crate) struct Call {
        pub(crate) id: u8,
        pub(crate) gone: Rc<Cell<bool>>,
    }

    impl Caller for Call {
        fn gave_up(&self) -> bool {
            self.gone.get()
        }
    }
}
