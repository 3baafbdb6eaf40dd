//! What the stream scenarios (GRIPLINK, SmartGrasp) share around their simulator: the server of
//! the moment, which a restart replaces, with the records of the ones it replaced; the replies
//! it drops; each client's own account of a loss; and their quiet phase's call.

use std::fmt::{Debug, Display};
use std::future::Future;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use futures_util::StreamExt;
use gripper::reconnect::{ConnectionEvent, ConnectionEvents};

use tokio::io::DuplexStream;

use super::phases::{after_close, DocumentedErrors};
use super::streams::{faulty_pipe_logged, Carried, CarriedLog, StreamProfile};
use super::{note, Prng, SharedTrace};

/// The server of the moment (`slot`), its generation (0 for the first, then one more per
/// restart), and the records of the servers a restart replaced, by generation.
pub struct Servers<S, R> {
    pub slot: Arc<Mutex<Arc<S>>>,
    pub generation: Arc<AtomicU64>,
    pub records: Arc<Mutex<Vec<R>>>,
}

impl<S, R> Clone for Servers<S, R> {
    fn clone(&self) -> Self {
        Servers {
            slot: self.slot.clone(),
            generation: self.generation.clone(),
            records: self.records.clone(),
        }
    }
}

impl<S: Send + Sync + 'static, R: Send + 'static> Servers<S, R> {
    /// The first server.
    pub fn new(first: Arc<S>) -> Self {
        Servers {
            slot: Arc::new(Mutex::new(first)),
            generation: Arc::new(AtomicU64::new(0)),
            records: Arc::new(Mutex::new(Vec::new())),
        }
    }

    /// The server of the moment and its generation.
    pub fn current(&self) -> (Arc<S>, u64) {
        let sim = self.slot.lock().unwrap().clone();
        (sim, self.generation.load(Ordering::SeqCst))
    }

    /// After `at`, replaces the server by `fresh()`, keeping the old one's `record`; the old
    /// one is dropped, which ends its connections. `end_fault_phase` calls it off if it is not
    /// due by then.
    pub fn restart_at(
        &self,
        at: Duration,
        fresh: impl FnOnce() -> Arc<S> + Send + 'static,
        record: impl FnOnce(&S) -> R + Send + 'static,
        trace: SharedTrace,
    ) -> super::Restart {
        let this = self.clone();
        tokio::spawn(async move {
            tokio::time::sleep(at).await;
            note(&trace, "fault: the server restarts");
            let old = std::mem::replace(&mut *this.slot.lock().unwrap(), fresh());
            let mut r = this.records.lock().unwrap();
            r.push(record(&old));
            this.generation.store(r.len() as u64, Ordering::SeqCst);
            drop(old);
        })
    }

    /// Every server's record, by generation (the one of the moment last).
    pub fn all_records(&self, record: impl FnOnce(&S) -> R) -> Vec<R> {
        let mut records = std::mem::take(&mut *self.records.lock().unwrap());
        records.push(record(&self.slot.lock().unwrap()));
        records
    }

    /// [`Servers::all_records`], each entry also noted in the trace (the digest covers it) as
    /// `sim GENERATION/` and what `describe` says of it.
    pub fn all_records_noted<E>(
        &self,
        record: impl FnOnce(&S) -> R,
        trace: &SharedTrace,
        describe: impl Fn(&E) -> String,
    ) -> Vec<R>
    where
        for<'a> &'a R: IntoIterator<Item = &'a E>,
    {
        let records = self.all_records(record);
        for (g, rec) in records.iter().enumerate() {
            for e in rec {
                note(trace, format!("sim {g}/{}", describe(e)));
            }
        }
        records
    }
}

/// Each loss a client reported: when (simulated) and the reason it gave (rule 6 judges it).
pub type Losses = Arc<Mutex<Vec<(tokio::time::Instant, String)>>>;

/// Follows a client's connection events into the trace; the flag turns true at its first
/// reported loss (the documented errors after it), and each loss is kept with its time and
/// reason.
pub fn watch_losses_logged(
    mut events: ConnectionEvents,
    index: usize,
    trace: SharedTrace,
) -> (Arc<AtomicBool>, Losses) {
    let lost = Arc::new(AtomicBool::new(false));
    let losses = Losses::default();
    let (flag, log) = (lost.clone(), losses.clone());
    tokio::spawn(async move {
        while let Some(ev) = events.next().await {
            note(&trace, format!("client {index}: event {ev:?}"));
            if let ConnectionEvent::Lost { reason } = &ev {
                flag.store(true, Ordering::SeqCst);
                log.lock()
                    .unwrap()
                    .push((tokio::time::Instant::now(), reason.clone()));
            }
        }
    });
    (lost, losses)
}

/// One session a client opened: the server generation and session number, when it opened, and
/// what the link did with the server's bytes (when each reached the client intact: rules 6-8).
#[derive(Clone, Debug)]
pub struct SessionRec {
    pub gen: u64,
    pub session: u64,
    pub opened: tokio::time::Instant,
    pub down: CarriedLog,
}

impl SessionRec {
    /// When the first `end` bytes the server wrote on this session had all reached the client
    /// (`None`: never, e.g. cut off).
    pub fn delivered_by(&self, end: u64) -> Option<tokio::time::Instant> {
        let c: std::sync::MutexGuard<'_, Carried> = self.down.lock().unwrap();
        c.delivered
            .iter()
            .find(|&&(_, e)| e >= end)
            .map(|&(t, _)| t)
    }
}

/// A client's sessions, in the order opened.
pub type Sessions = Arc<Mutex<Vec<SessionRec>>>;

impl<S: Send + Sync + 'static, R: Send + 'static> Servers<S, R> {
    /// The opener a client `index` reconnects through: each call makes a new in-memory pipe
    /// through the fault layer (`profile`, on while `faults_on`), serves its far end on the
    /// server of the moment (`serve`: its `serve_stream`), and notes the session in `sessions`.
    #[allow(clippy::too_many_arguments)]
    pub fn opener(
        &self,
        index: usize,
        rng: Prng,
        profile: StreamProfile,
        faults_on: Arc<AtomicBool>,
        trace: SharedTrace,
        sessions: Sessions,
        serve: fn(&S, DuplexStream) -> u64,
    ) -> impl Fn() -> std::future::Ready<std::io::Result<DuplexStream>> + Clone + Send + Sync + 'static
    {
        let sims = self.clone();
        let rng = Arc::new(Mutex::new(rng));
        move || {
            let (sim, gen) = sims.current();
            let mut r = rng.lock().unwrap();
            let down = CarriedLog::default();
            let (client_end, server_end) = faulty_pipe_logged(
                &mut r,
                profile,
                faults_on.clone(),
                trace.clone(),
                format!("c{index}"),
                Some(down.clone()),
            );
            let session = serve(&sim, server_end);
            sessions.lock().unwrap().push(SessionRec {
                gen,
                session,
                opened: tokio::time::Instant::now(),
                down,
            });
            note(
                &trace,
                format!("client {index}: open session {gen}/{session}"),
            );
            std::future::ready(Ok(client_end))
        }
    }
}

/// How many replies the server drops in a run (a real server's bug, or a test's): in one run of
/// two from fault level 1, 1 to 3. A call without timeout is then left out (a dropped reply
/// would hold it for ever), and so is the quiet phase (the pairing may be out of step).
pub fn draw_drops(rng: &mut Prng, level: u32) -> u64 {
    if level >= 1 && rng.one_in(2) {
        rng.between(1, 3)
    } else {
        0
    }
}

impl<S: Send + Sync + 'static, R: Send + 'static> Servers<S, R> {
    /// Schedules `drops` dropped replies at 0–5 s each: then notes `what` and calls `inject`
    /// (its `inject(Fault::DropReply)`) on the server of the moment.
    pub fn drop_replies(
        &self,
        rng: &mut Prng,
        drops: u64,
        trace: &SharedTrace,
        what: &'static str,
        inject: fn(&S),
    ) {
        for _ in 0..drops {
            let at = rng.millis(0, 5000);
            let (sims, trace) = (self.clone(), trace.clone());
            tokio::spawn(async move {
                tokio::time::sleep(at).await;
                note(&trace, what);
                inject(&sims.current().0);
            });
        }
    }
}

/// Promise 5 in the quiet phase of a stream scenario: 5 s after the faults stop, a call
/// (`what`, made by `call`) of client `index` succeeds, or fails with `ConnectionLost` if the
/// client does not reconnect and reported a loss (`lost`); the violation otherwise.
pub async fn quiet_call<T: Debug, E: DocumentedErrors + Debug + Display, F>(
    index: usize,
    reconnects: bool,
    lost: &AtomicBool,
    what: &str,
    trace: &SharedTrace,
    call: impl FnOnce() -> F,
) -> Option<String>
where
    F: Future<Output = Result<T, E>>,
{
    tokio::time::sleep(Duration::from_secs(5)).await;
    let r = call().await;
    note(trace, format!("quiet client {index}: {what} {r:?}"));
    match &r {
        Ok(_) => None,
        Err(e) if e.is_connection_lost() && !reconnects && lost.load(Ordering::SeqCst) => None,
        Err(e) => Some(format!(
            "5 (recovery): client {index} (reconnect {reconnects}) failed a call in the quiet phase: {e}"
        )),
    }
}

/// Closes client `index` at the end of a stream scenario's run (`close`, a `close()` with a
/// timeout), then makes a call (`after`, named `what`) that must fail as documented (promise 5,
/// [`after_close`]); a loss counts if the client reported one (`lost`) or if `close()` itself
/// said so (the event of a loss at the instant of the close may not have reached its watcher
/// yet). With `check` false the call's result is only noted.
pub async fn close_and_check<T: Debug, E: DocumentedErrors + Debug, FC, FA>(
    index: usize,
    what: &str,
    lost: &AtomicBool,
    check: bool,
    trace: &SharedTrace,
    close: FC,
    after: impl FnOnce() -> FA,
) -> Option<String>
where
    FC: Future<Output = Result<(), E>>,
    FA: Future<Output = Result<T, E>>,
{
    let r = close.await;
    note(trace, format!("close client {index}: {r:?}"));
    let after = after().await;
    if !check {
        note(trace, format!("client {index} after close(): {after:?}"));
        return None;
    }
    let lost = lost.load(Ordering::SeqCst) || r.as_ref().is_err_and(|e| e.is_connection_lost());
    after_close(index, what, &after, lost)
}

/// One reply a server sent on one of a client's sessions, and when it reached the client intact
/// (the evidence of rules 6-8 of the stream scenarios).
pub struct Sent<'a, E> {
    /// Its place in the records: (server generation, index).
    pub key: (u64, usize),
    pub gen: u64,
    pub session: u64,
    pub exchange: &'a E,
    /// When its last byte reached the client (`None`: never, e.g. cut off).
    pub delivered: Option<tokio::time::Instant>,
}

/// Every reply sent on one of `sessions`, in order: each record of `records` (by generation)
/// whose session (`session_of`) is one of them, with when its bytes (`len` long, written one
/// after another on the session) reached the client.
pub fn sent_on<'a, E>(
    sessions: &[SessionRec],
    records: &'a [Vec<E>],
    session_of: impl Fn(&E) -> u64,
    len: impl Fn(&E) -> u64,
) -> Vec<Sent<'a, E>> {
    let mut out = Vec::new();
    for s in sessions {
        let mut end = 0u64;
        for (j, e) in records[s.gen as usize].iter().enumerate() {
            if session_of(e) != s.session {
                continue;
            }
            end += len(e);
            out.push(Sent {
                key: (s.gen, j),
                gen: s.gen,
                session: s.session,
                exchange: e,
                delivered: s.delivered_by(end),
            });
        }
    }
    out
}

/// The session a client used at `t` (the last one opened by then).
pub fn session_at(sessions: &[SessionRec], t: tokio::time::Instant) -> Option<&SessionRec> {
    sessions.iter().rev().find(|s| s.opened <= t)
}

/// Rule 6's measure: how long before `t` the last reply on session `s` reached the client (or
/// the session opened, if later). The documented give-up time counts from when a request waits
/// at the front, so a give-up needs at least `give_up_after` of it.
pub fn silence_before<E>(
    s: &SessionRec,
    sent: &[Sent<'_, E>],
    t: tokio::time::Instant,
) -> (Duration, tokio::time::Instant) {
    let last = sent
        .iter()
        .filter(|x| x.gen == s.gen && x.session == s.session)
        .filter_map(|x| x.delivered)
        .filter(|&d| d <= t)
        .max()
        .unwrap_or(s.opened)
        .max(s.opened);
    (t - last, last)
}
