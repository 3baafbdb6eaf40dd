//! What the stream scenarios (GRIPLINK, SmartGrasp) share around their simulator: the server of
//! the moment, which a restart replaces, with the records of the ones it replaced; and each
//! client's own account of a loss.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use futures_util::StreamExt;
use gripper::reconnect::{ConnectionEvent, ConnectionEvents};

use tokio::io::DuplexStream;

use super::streams::{faulty_pipe, StreamProfile};
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
}

/// Follows a client's connection events into the trace; the flag turns true at its first
/// reported loss (the documented errors after it).
pub fn watch_losses(
    mut events: ConnectionEvents,
    index: usize,
    trace: SharedTrace,
) -> Arc<AtomicBool> {
    let lost = Arc::new(AtomicBool::new(false));
    let flag = lost.clone();
    tokio::spawn(async move {
        while let Some(ev) = events.next().await {
            note(&trace, format!("client {index}: event {ev:?}"));
            if matches!(ev, ConnectionEvent::Lost { .. }) {
                flag.store(true, Ordering::SeqCst);
            }
        }
    });
    lost
}

/// A client's sessions: (server generation, session number), in the order opened.
pub type Sessions = Arc<Mutex<Vec<(u64, u64)>>>;

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
            let (client_end, server_end) = faulty_pipe(
                &mut r,
                profile,
                faults_on.clone(),
                trace.clone(),
                format!("c{index}"),
            );
            let session = serve(&sim, server_end);
            sessions.lock().unwrap().push((gen, session));
            note(
                &trace,
                format!("client {index}: open session {gen}/{session}"),
            );
            std::future::ready(Ok(client_end))
        }
    }
}
