//! Where a client's connection task runs: inline in the caller that just queued a request, and
//! otherwise in a spawned *keeper* task (issue 14, BENCHMARKS.md "Round trip").
//!
//! Each client owns its transport in one future, the connection task (it writes requests, pairs
//! replies, runs the timers, fans out auto-updates, reconnects). Spawned on its own, every call
//! costs two hand-overs: the request goes to the task over a channel, and the reply comes back
//! over a oneshot. On tokio's multi-thread runtime, with the caller in `block_on` (where
//! `#[tokio::main]` runs `main`), each hand-over is a cross-thread wake-up — two futex
//! wake/wait pairs per round trip where a blocking driver has none.
//!
//! [`Connection::call`] removes the first one: the caller queues its request as before and then
//! polls the connection future itself, so the request is written from the caller's thread at
//! once. Replies, timers, auto-updates and reconnects wake the keeper, which polls the same
//! future. Nothing about the connection's logic changes: it is one future, polled by one party at
//! a time (a mutex), always with the same waker, so every rule it keeps (pairing, stops never
//! queued, one place where requests fail) holds whoever polls it.
//!
//! Why the keeper is woken for every event even when a caller reads its own reply (the
//! *leader*, on a `current_thread` runtime only: see [`Connection::call`]): a caller's future
//! may legally be left unpolled for a while (a `select!` that went elsewhere, a future kept for
//! later); a connection that relied on it would then stall for every other caller. The keeper
//! is always polled when woken. On a multi-thread runtime the reply goes through the keeper: a
//! caller in `block_on` cannot be woken by the socket any cheaper than by the keeper (tokio's
//! I/O driver runs on a worker thread either way).
//!
//! # Wake-ups, and why none is lost
//!
//! The connection future is always polled with one waker, [`Signal`]'s: it sets `notified` and,
//! unless a caller is inside [`Connection::call`]'s poll (`inline` > 0), notifies the keeper (and
//! wakes the leader, where callers lead).
//! Whoever polls the connection clears `notified` first, under the mutex. A caller leaving its
//! poll decrements `inline` and then, if `notified` is set, notifies the keeper: a wake-up that
//! saw `inline` > 0 is always seen by the caller that made it so (both sides store, then load,
//! sequentially consistent). A party that finds the mutex taken does nothing: the holder polls
//! after the wake-up's `notified` was set, or the flag is still set when the holder's caller
//! leaves or the keeper looks again.

use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering::SeqCst};
use std::sync::{Arc, Mutex, MutexGuard, TryLockError};
use std::task::{Context, Poll, Wake, Waker};

use tokio::runtime::{Handle, RuntimeFlavor};
use tokio::sync::Notify;

type Task = Pin<Box<dyn Future<Output = ()> + Send>>;

/// A handle to a running connection task; cheap to clone.
#[derive(Clone)]
pub(crate) struct Connection {
    shared: Arc<Shared>,
}

struct Shared {
    /// The connection task; `None` once it ended (or its keeper was dropped with the runtime).
    task: Mutex<Option<Task>>,
    signal: Arc<Signal>,
    /// `signal` as a waker, made once.
    waker: Waker,
    /// The runtime the keeper runs on: an inline poll enters it, so the timers and sockets the
    /// connection creates belong to that runtime even when the caller runs on another one.
    runtime: Handle,
}

/// The connection task's waker (see the module docs).
struct Signal {
    notified: AtomicBool,
    /// Callers inside [`Connection::call`]'s poll, each of which looks at `notified` on leaving.
    inline: AtomicUsize,
    keeper: Notify,
    /// Whether a waiting caller becomes the leader: when the keeper runs on a `current_thread`
    /// runtime only (see [`Connection::call`]).
    leads: bool,
    /// The waiting caller woken together with the keeper (see [`Connection::call`]).
    leader: Mutex<Option<Leader>>,
    /// Numbers the calls, to tell the leader apart.
    next_call: AtomicU64,
}

/// A waiting caller that is woken for every event on the connection, so that it can read its
/// reply itself before the keeper gets to it.
struct Leader {
    call: u64,
    waker: Waker,
}

impl Wake for Signal {
    fn wake(self: Arc<Self>) {
        self.wake_by_ref();
    }

    fn wake_by_ref(self: &Arc<Self>) {
        self.notified.store(true, SeqCst);
        if self.inline.load(SeqCst) == 0 {
            if self.leads {
                let leader = lock(&self.leader).as_ref().map(|l| l.waker.clone());
                if let Some(leader) = leader {
                    leader.wake();
                }
            }
            self.keeper.notify_one();
        }
    }
}

impl Signal {
    /// The task ended, maybe in a caller's poll: the keeper has to look to end too.
    fn ended(&self) {
        self.notified.store(true, SeqCst);
        self.keeper.notify_one();
    }

    #[cfg(test)]
    fn has_leader(&self) -> bool {
        lock(&self.leader).is_some()
    }

    /// Makes call `id` the leader if there is none, or updates its waker if it is.
    fn lead(&self, id: u64, waker: &Waker) {
        let mut leader = lock(&self.leader);
        // A replaced waker is dropped after the lock is released: dropping a waker runs code
        // that is not ours.
        let _replaced = match leader.as_mut() {
            Some(leader) if leader.call == id => {
                if leader.waker.will_wake(waker) {
                    return;
                }
                std::mem::replace(&mut leader.waker, waker.clone())
            }
            Some(_) => return,
            None => {
                *leader = Some(Leader {
                    call: id,
                    waker: waker.clone(),
                });
                return;
            }
        };
        drop(leader);
    }
}

/// Gives up a call's leadership when it ends or is dropped.
struct Leaving<'a> {
    signal: &'a Signal,
    call: u64,
}

impl Drop for Leaving<'_> {
    fn drop(&mut self) {
        if !self.signal.leads {
            return;
        }
        let mut leader = lock(&self.signal.leader);
        let _gone = if leader.as_ref().is_some_and(|l| l.call == self.call) {
            leader.take()
        } else {
            None
        };
        // The waker is dropped after the lock is released (see `lead`).
        drop(leader);
    }
}

/// A mutex's content, even after a panic elsewhere (the leader slot stays consistent: it is
/// only ever replaced or cleared whole).
fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// What one attempt to poll the connection task did.
#[derive(Debug, PartialEq, Eq)]
enum Step {
    /// Polled; it is still running.
    Polled,
    /// Somebody else is polling it.
    Busy,
    /// It has ended.
    Ended,
}

impl std::fmt::Debug for Connection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Connection").finish_non_exhaustive()
    }
}

impl Connection {
    /// Runs `task` as a connection task on the current runtime.
    ///
    /// # Panics
    /// Outside a tokio runtime, as [`tokio::spawn`] does.
    pub(crate) fn spawn(task: impl Future<Output = ()> + Send + 'static) -> Connection {
        let signal = Arc::new(Signal {
            // The keeper polls once at the start.
            notified: AtomicBool::new(true),
            inline: AtomicUsize::new(0),
            keeper: Notify::new(),
            leads: Handle::current().runtime_flavor() == RuntimeFlavor::CurrentThread,
            leader: Mutex::new(None),
            next_call: AtomicU64::new(0),
        });
        let shared = Arc::new(Shared {
            task: Mutex::new(Some(Box::pin(task))),
            waker: Waker::from(Arc::clone(&signal)),
            signal,
            runtime: Handle::current(),
        });
        tokio::spawn(Keeper(Arc::clone(&shared)).run());
        Connection { shared }
    }

    /// Awaits `call` (a future that queues a request for the connection task and waits for its
    /// answer), polling the connection task inline after each poll of `call` that left it
    /// something to do: the request goes out from this thread, without waking another one.
    ///
    /// On a `current_thread` runtime, while it waits, the call may be the *leader*: the one
    /// caller woken, with the keeper, for every event on the connection. A `block_on` future is
    /// polled before any task, and tasks run in the order they were woken, so the leader reads
    /// its reply itself, as a bare socket would; the keeper then finds nothing left to do. If
    /// the leader was not polled (its future kept but left alone, say by a `select!` that went
    /// elsewhere), the keeper polls the connection: such a leader delays nobody. On a
    /// multi-thread runtime (the keeper's) no call leads: waking two tasks per event costs more
    /// than it saves (a worker is woken to steal one of them; measured, BENCHMARKS.md), and the
    /// keeper, on the worker that saw the event, hands the reply over at once.
    pub(crate) async fn call<F: Future>(&self, call: F) -> F::Output {
        let signal = &self.shared.signal;
        let leaving = Leaving {
            signal,
            call: signal.next_call.fetch_add(1, SeqCst),
        };
        let mut call = std::pin::pin!(call);
        std::future::poll_fn(|cx| self.shared.poll_call(call.as_mut(), cx, leaving.call)).await
    }

    /// Whether somebody polls the connection task at this moment.
    #[cfg(test)]
    fn polled_now(&self) -> bool {
        matches!(self.shared.task.try_lock(), Err(TryLockError::WouldBlock))
    }

    /// Whether the connection task has ended.
    #[cfg(test)]
    fn ended(&self) -> bool {
        self.shared.lock_task().is_none()
    }
}

impl Shared {
    fn poll_call<F: Future>(
        &self,
        mut call: Pin<&mut F>,
        cx: &mut Context<'_>,
        id: u64,
    ) -> Poll<F::Output> {
        let _inline = Inline::enter(&self.signal);
        let polled = if self.signal.notified.load(SeqCst) {
            // The task has something to do, most often this caller's reply to read (as the
            // leader). The call is polled first without a waker: an answer the task delivers
            // below is seen by the second poll, instead of waking this caller, whose future
            // then returns anyway. (On a `current_thread` runtime such a stale wake-up costs an
            // extra trip through the I/O driver before the next call can wait.)
            if let Poll::Ready(out) = call.as_mut().poll(&mut Context::from_waker(Waker::noop())) {
                return Poll::Ready(out);
            }
            self.poll_task();
            call.poll(cx)
        } else {
            // Nothing for the task yet: most often a new call, whose poll queues its request.
            // Polled once, with its waker (a second poll swaps the waker of its timer and
            // answer channel back and forth: measured, issue 14), then the task writes the
            // request. The task seldom answers in that same poll; when it does, the waker
            // brings the caller back.
            let polled = call.poll(cx);
            if polled.is_pending() && self.signal.notified.load(SeqCst) {
                self.poll_task();
            }
            polled
        };
        if polled.is_pending() && self.signal.leads {
            self.signal.lead(id, cx.waker());
        }
        polled
    }

    /// Polls the connection task once if nobody else is polling it.
    fn poll_task(&self) -> Step {
        let mut task = match self.task.try_lock() {
            Ok(task) => task,
            Err(TryLockError::WouldBlock) => return Step::Busy,
            Err(TryLockError::Poisoned(poisoned)) => {
                // It panicked while polled: what is left of it cannot run again. Dropping it
                // fails its callers (their answer channels close).
                let mut task = poisoned.into_inner();
                *task = None;
                self.task.clear_poison();
                drop(task);
                self.signal.ended();
                return Step::Ended;
            }
        };
        let Some(running) = task.as_mut() else {
            return Step::Ended;
        };
        self.signal.notified.store(false, SeqCst);
        let ready = {
            let _runtime = self.runtime.enter();
            running.as_mut().poll(&mut Context::from_waker(&self.waker))
        };
        if ready.is_pending() {
            return Step::Polled;
        }
        *task = None;
        drop(task);
        self.signal.ended();
        Step::Ended
    }

    /// The task slot, taken even after a panic (to drop what is left).
    fn lock_task(&self) -> MutexGuard<'_, Option<Task>> {
        lock(&self.task)
    }
}

/// Counts a caller as inside its poll; on leaving, hands a wake-up that arrived meanwhile to the
/// keeper (a `Drop`, so that a panicking call leaves the count right and the keeper told).
struct Inline<'a>(&'a Signal);

impl<'a> Inline<'a> {
    fn enter(signal: &'a Signal) -> Self {
        signal.inline.fetch_add(1, SeqCst);
        Inline(signal)
    }
}

impl Drop for Inline<'_> {
    fn drop(&mut self) {
        self.0.inline.fetch_sub(1, SeqCst);
        if std::thread::panicking() {
            // The keeper drops what is left of the task (it finds the mutex poisoned).
            self.0.ended();
        } else if self.0.notified.load(SeqCst) {
            self.0.keeper.notify_one();
        }
    }
}

/// How many times in a row the keeper polls a connection task that was woken while it polled,
/// before it yields to other tasks.
const MAX_REPOLLS: u32 = 3;

/// The spawned task that polls the connection task whenever something other than a caller's
/// request wakes it. Dropped with its runtime, it drops the connection task (and so fails the
/// calls in flight), as a spawned connection task would have been dropped.
struct Keeper(Arc<Shared>);

impl Keeper {
    async fn run(self) {
        let signal = &self.0.signal;
        let mut repolls = 0;
        loop {
            if signal.notified.load(SeqCst) {
                match self.0.poll_task() {
                    Step::Ended => return,
                    // Woken again while polled. Most often a caller queued its next request and
                    // found the task busy (with this poll, which delivered that caller's last
                    // reply): poll again at once, so the request goes out now rather than after
                    // a trip through the scheduler (issue 14). Not once the keeper's budget has
                    // run out: tokio's resources then wake their task at once and stay pending,
                    // so polling again would only spin; and not forever for a task that keeps
                    // waking itself otherwise: both let other tasks run first.
                    Step::Polled if signal.notified.load(SeqCst) => {
                        repolls += 1;
                        if repolls > MAX_REPOLLS || !tokio::task::coop::has_budget_remaining() {
                            repolls = 0;
                            tokio::task::yield_now().await;
                        }
                        continue;
                    }
                    Step::Polled | Step::Busy => {}
                }
            }
            repolls = 0;
            // On a current_thread runtime a leader, woken before the keeper, has been polled by
            // now: a `block_on` future is polled before any task, and tasks run in the order
            // they were woken. If it read the event, `notified` is clear again.
            signal.keeper.notified().await;
        }
    }
}

impl Drop for Keeper {
    fn drop(&mut self) {
        let task = self.0.lock_task().take();
        drop(task);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::thread::ThreadId;
    use std::time::Duration;
    use tokio::sync::{mpsc, oneshot};

    fn multi_thread(workers: usize) -> tokio::runtime::Runtime {
        tokio::runtime::Builder::new_multi_thread()
            .worker_threads(workers)
            .enable_all()
            .build()
            .expect("runtime")
    }

    fn current_thread() -> tokio::runtime::Runtime {
        tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("runtime")
    }

    /// Who did what for one request.
    #[derive(Debug)]
    struct Seen {
        /// The thread the request was taken on.
        request: ThreadId,
        /// The task that polled the connection when the reply was read (`None`: a `block_on`
        /// future, not a task).
        reply: Option<tokio::task::Id>,
    }

    type Requests = mpsc::Sender<oneshot::Sender<Seen>>;

    /// A connection task in miniature: answers each request with [`Seen`], after a round trip
    /// over loopback TCP, so that a reply needs a wake-up from the I/O driver.
    fn echo() -> (Connection, Requests) {
        let (tx, mut rx) = mpsc::channel::<oneshot::Sender<Seen>>(64);
        let connection = Connection::spawn(async move {
            use tokio::io::{AsyncReadExt, AsyncWriteExt};
            let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
                .await
                .expect("bind");
            let addr = listener.local_addr().expect("address");
            let (a, b) = tokio::join!(tokio::net::TcpStream::connect(addr), listener.accept());
            let (mut a, (mut b, _)) = (a.expect("connect"), b.expect("accept"));
            let mut waiting = std::collections::VecDeque::new();
            let mut byte = [0u8; 1];
            loop {
                tokio::select! {
                    request = rx.recv() => match request {
                        Some(answer) => {
                            waiting.push_back((answer, std::thread::current().id()));
                            if a.write_all(&[1]).await.is_err() {
                                return;
                            }
                        }
                        None => return,
                    },
                    read = b.read(&mut byte) => {
                        if !matches!(read, Ok(1)) {
                            return;
                        }
                        if let Some((answer, request)) = waiting.pop_front() {
                            let reply = tokio::task::try_id();
                            let _ = answer.send(Seen { request, reply });
                        }
                    }
                }
            }
        });
        (connection, tx)
    }

    async fn ask(connection: &Connection, tx: &Requests) -> Seen {
        connection
            .call(async {
                let (answer, rx) = oneshot::channel();
                tx.send(answer).await.expect("the task runs");
                rx.await.expect("the task answers")
            })
            .await
    }

    #[test]
    fn a_request_from_block_on_is_taken_on_the_callers_thread() {
        let rt = multi_thread(2);
        let (connection, tx) = rt.block_on(async { echo() });
        let caller = std::thread::current().id();
        let inline = rt.block_on(async {
            let mut inline = 0;
            for _ in 0..200 {
                // The keeper polls the task after it delivered the last reply; a request that
                // arrives meanwhile is left to it (it is awake, on its worker). Wait for it to
                // finish, so that what is measured is the path of a request to an idle
                // connection.
                while connection.polled_now() {
                    std::hint::spin_loop();
                }
                if ask(&connection, &tx).await.request == caller {
                    inline += 1;
                }
            }
            inline
        });
        // Without inline polling the keeper takes them all.
        assert!(
            inline >= 190,
            "only {inline} of 200 requests were taken inline"
        );
    }

    #[test]
    fn on_current_thread_the_caller_reads_its_own_reply() {
        let rt = current_thread();
        let (connection, tx) = rt.block_on(async { echo() });
        let mut own = 0;
        for _ in 0..200 {
            if rt.block_on(ask(&connection, &tx)).reply.is_none() {
                own += 1;
            }
        }
        // Without a leader the keeper task reads every reply.
        assert!(own >= 150, "the caller read only {own} of 200 replies");
    }

    #[tokio::test]
    async fn a_leader_left_unpolled_delays_nobody() {
        let (connection, tx) = echo();
        let mut stalled = std::pin::pin!(ask(&connection, &tx));
        // Polled once: it sent its request and leads; then it is kept but not polled.
        tokio::select! {
            biased;
            _ = &mut stalled => panic!("answered before the task ran"),
            _ = std::future::ready(()) => {}
        }
        assert!(connection.shared.signal.has_leader());
        let other = {
            let (connection, tx) = (connection.clone(), tx.clone());
            tokio::spawn(async move {
                for _ in 0..100 {
                    ask(&connection, &tx).await;
                }
            })
        };
        tokio::time::timeout(Duration::from_secs(10), other)
            .await
            .expect("the keeper served the other caller")
            .expect("the other caller ran");
        // And the stalled call's answer is waiting for it.
        let seen = stalled.await;
        assert!(seen.reply.is_some(), "read by the keeper: {seen:?}");
    }

    #[tokio::test]
    async fn the_keeper_alone_serves_requests_sent_around_call() {
        let (_connection, tx) = echo();
        // Bounded, so that a keeper that stops polling fails the test instead of hanging it.
        tokio::time::timeout(Duration::from_secs(10), async {
            for _ in 0..100 {
                let (answer, rx) = oneshot::channel();
                tx.send(answer).await.expect("the task runs");
                rx.await.expect("the keeper polls the task");
            }
        })
        .await
        .expect("the keeper served every request");
    }

    #[test]
    fn many_callers_on_two_workers_all_get_their_answers() {
        let rt = multi_thread(2);
        rt.block_on(async {
            let (connection, tx) = echo();
            let mut callers = Vec::new();
            for _ in 0..16 {
                let (connection, tx) = (connection.clone(), tx.clone());
                callers.push(tokio::spawn(async move {
                    for round in 0..500 {
                        // Some calls are abandoned half-way, as a timed-out call is.
                        if round % 7 == 0 {
                            let abandoned = ask(&connection, &tx);
                            let _ = tokio::time::timeout(Duration::ZERO, abandoned).await;
                        } else {
                            ask(&connection, &tx).await;
                        }
                    }
                }));
            }
            for caller in callers {
                tokio::time::timeout(Duration::from_secs(60), caller)
                    .await
                    .expect("no wake-up was lost")
                    .expect("the caller ran");
            }
        });
    }

    /// A caller's mix of calls: most complete, some are abandoned at once (as a timed-out call
    /// is), some are polled once and then kept unpolled while the caller makes another call,
    /// and then awaited or dropped.
    async fn mixed_calls(connection: Connection, tx: Requests, seed: u64, rounds: u32) {
        let mut state = seed | 1;
        let mut next = move || {
            // xorshift64: enough to vary the mix, and reproducible from the seed.
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for _ in 0..rounds {
            match next() % 8 {
                0 => {
                    let _ = tokio::time::timeout(Duration::ZERO, ask(&connection, &tx)).await;
                }
                1 => {
                    let mut kept = std::pin::pin!(ask(&connection, &tx));
                    let polled = tokio::select! {
                        biased;
                        seen = &mut kept => Some(seen),
                        _ = std::future::ready(()) => None,
                    };
                    ask(&connection, &tx).await;
                    if polled.is_none() && next() % 2 == 0 {
                        kept.await;
                    }
                }
                _ => {
                    ask(&connection, &tx).await;
                }
            }
        }
    }

    /// Callers on the keeper's runtime (tasks and `block_on`) and on a second runtime's
    /// threads, with calls abandoned and kept unpolled: every call that is awaited gets its
    /// answer (a lost wake-up hangs one, and the timeout fails the test).
    fn callers_everywhere(keeper_runtime: tokio::runtime::Runtime) {
        let other = multi_thread(1);
        let (connection, tx) = keeper_runtime.block_on(async { echo() });
        let mut elsewhere = Vec::new();
        for seed in 0..3 {
            elsewhere.push(other.spawn(mixed_calls(
                connection.clone(),
                tx.clone(),
                100 + seed,
                60,
            )));
        }
        keeper_runtime.block_on(async {
            let mut here = Vec::new();
            for seed in 0..3 {
                here.push(tokio::spawn(mixed_calls(
                    connection.clone(),
                    tx.clone(),
                    200 + seed,
                    60,
                )));
            }
            tokio::time::timeout(Duration::from_secs(20), async {
                mixed_calls(connection.clone(), tx.clone(), 300, 60).await;
                for caller in here.into_iter().chain(elsewhere) {
                    caller.await.expect("the caller ran");
                }
            })
            .await
            .expect("no wake-up was lost");
        });
        drop(other);
    }

    #[test]
    fn callers_on_two_runtimes_all_get_their_answers_current_thread() {
        callers_everywhere(current_thread());
    }

    #[test]
    fn callers_on_two_runtimes_all_get_their_answers_multi_thread() {
        callers_everywhere(multi_thread(2));
    }

    /// A task that panics on its 20th request, called from the keeper's runtime and from a
    /// second one: every call ends (it panics with the task or its answer channel closes), what
    /// is left of the task is dropped and the keeper ends, whoever polled it when it panicked.
    fn a_panic_anywhere_ends_everything(keeper_runtime: tokio::runtime::Runtime) {
        let other = multi_thread(1);
        let (tx, mut rx) = mpsc::channel::<oneshot::Sender<()>>(4);
        let connection = keeper_runtime.block_on(async {
            Connection::spawn(async move {
                let mut taken = 0;
                while let Some(answer) = rx.recv().await {
                    taken += 1;
                    assert!(taken < 20, "a bug in a connection task");
                    let _ = answer.send(());
                }
            })
        });
        let calls = |connection: Connection, tx: mpsc::Sender<oneshot::Sender<()>>| async move {
            loop {
                let answered = connection
                    .call(async {
                        let (answer, reply) = oneshot::channel();
                        if tx.send(answer).await.is_err() {
                            return false;
                        }
                        reply.await.is_ok()
                    })
                    .await;
                if !answered {
                    return;
                }
            }
        };
        let mut callers = Vec::new();
        for _ in 0..3 {
            callers.push(other.spawn(calls(connection.clone(), tx.clone())));
            callers.push(keeper_runtime.spawn(calls(connection.clone(), tx.clone())));
        }
        drop(tx);
        keeper_runtime.block_on(async {
            tokio::time::timeout(Duration::from_secs(20), async {
                for caller in callers {
                    // Ended: normally, or with the task's panic.
                    let _ = caller.await;
                }
                while Arc::strong_count(&connection.shared) > 1 {
                    tokio::task::yield_now().await;
                }
            })
            .await
            .expect("every call ended, and the keeper too");
        });
        assert!(connection.ended(), "what was left of the task was dropped");
    }

    #[test]
    fn a_panic_anywhere_ends_everything_current_thread() {
        a_panic_anywhere_ends_everything(current_thread());
    }

    #[test]
    fn a_panic_anywhere_ends_everything_multi_thread() {
        a_panic_anywhere_ends_everything(multi_thread(2));
    }

    #[test]
    fn the_task_ends_with_its_runtime() {
        let rt = current_thread();
        let (connection, tx) = rt.block_on(async { echo() });
        let (answer, rx) = oneshot::channel();
        rt.block_on(tx.send(answer)).expect("the task runs");
        drop(rt);
        assert!(connection.ended(), "the keeper dropped the task");
        assert!(rx.blocking_recv().is_err(), "the waiting call failed");
    }

    #[test]
    fn a_call_from_another_runtime_fails_when_the_keepers_runtime_shuts_down() {
        let keeper_runtime = current_thread();
        let other = multi_thread(1);
        let (tx, mut rx) = mpsc::channel::<oneshot::Sender<()>>(1);
        let (held, is_held) = std::sync::mpsc::channel();
        // Keeps each request unanswered.
        let connection = keeper_runtime.block_on(async {
            Connection::spawn(async move {
                let mut unanswered = Vec::new();
                while let Some(answer) = rx.recv().await {
                    unanswered.push(answer);
                    let _ = held.send(());
                }
            })
        });
        let caller = other.spawn(async move {
            connection
                .call(async {
                    let (answer, reply) = oneshot::channel();
                    tx.send(answer).await.expect("the task runs");
                    reply.await
                })
                .await
        });
        // Taken by the caller's inline poll: nobody drives the keeper's runtime.
        is_held
            .recv_timeout(Duration::from_secs(10))
            .expect("the request was taken inline");
        drop(keeper_runtime);
        let answer = other
            .block_on(async { tokio::time::timeout(Duration::from_secs(10), caller).await })
            .expect("the call fails instead of hanging")
            .expect("the caller ran");
        assert!(answer.is_err(), "no answer can have come");
    }

    #[tokio::test]
    async fn the_keeper_ends_when_the_task_ends_inline() {
        let (connection, tx) = echo();
        ask(&connection, &tx).await;
        drop(tx);
        // The task ends when its request channel closes; a caller's poll may be the one that
        // sees it, and the keeper (which holds the other reference) must end anyway.
        connection.call(async {}).await;
        tokio::time::timeout(Duration::from_secs(10), async {
            while Arc::strong_count(&connection.shared) > 1 {
                tokio::task::yield_now().await;
            }
        })
        .await
        .expect("the keeper ended");
        assert!(connection.ended());
    }

    #[tokio::test]
    async fn a_task_that_panicked_is_dropped_and_its_callers_hear_of_it() {
        let (tx, mut rx) = mpsc::channel::<oneshot::Sender<()>>(1);
        let connection = Connection::spawn(async move {
            if let Some(_answer) = rx.recv().await {
                panic!("a bug in a connection task");
            }
        });
        let (answer, reply) = oneshot::channel();
        let caller = {
            let connection = connection.clone();
            tokio::spawn(async move {
                connection
                    .call(async {
                        tx.send(answer).await.expect("the task runs");
                        reply.await
                    })
                    .await
            })
        };
        let result = tokio::time::timeout(Duration::from_secs(10), caller)
            .await
            .expect("the call does not hang");
        // Whoever polled the task when it panicked (the caller inline, or the keeper), the call
        // ends: it panics with the task, or its answer channel closes.
        match result {
            Err(joined) => assert!(joined.is_panic()),
            Ok(answer) => assert!(answer.is_err(), "no answer can have come"),
        }
        tokio::time::timeout(Duration::from_secs(10), async {
            while !connection.ended() {
                tokio::task::yield_now().await;
            }
        })
        .await
        .expect("what was left of the task was dropped");
    }

    #[test]
    fn a_task_that_keeps_waking_itself_lets_other_tasks_run() {
        // On one thread, a keeper that polled such a task for as long as it was woken would
        // never return to the scheduler: the other task below would never run.
        let (done_tx, done_rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            current_thread().block_on(async {
                // Woken at once, as a tokio resource does when the task's budget has run out
                // (`yield_now` defers its wake-up to the scheduler instead).
                let _connection = Connection::spawn(std::future::poll_fn(|cx| {
                    cx.waker().wake_by_ref();
                    Poll::<()>::Pending
                }));
                let other = tokio::spawn(async {});
                other.await.expect("the other task ran");
                let _ = done_tx.send(());
            });
        });
        done_rx
            .recv_timeout(Duration::from_secs(10))
            .expect("the other task ran while the connection task kept waking itself");
    }
}
