//! The WSG workload: what one caller does, and what each call returned, recorded for the
//! oracle. Calls are self-identifying where the protocol allows it: loop-back payloads and
//! acceleration values are unique in a run.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use bytes::Bytes;
use futures_util::StreamExt;
use gripper::wsg::command::id;
use gripper::wsg::sim::SessionId;
use gripper::wsg::{Client, Error, HomingDirection, Status, UpdateOptions};
use tokio::time::Instant;

use crate::core::{note, Prng, SharedTrace};

/// What a successful call's reply must have been, on the device's side.
#[derive(Clone, Debug, PartialEq)]
pub enum Expect {
    /// E_SUCCESS, any data.
    Success,
    /// E_SUCCESS with exactly these data.
    Data(Vec<u8>),
    /// A motion's final E_SUCCESS, sent with the fingers stopped.
    Motion,
    /// This status with these data (a raw request returns any final reply).
    Exact(Status, Vec<u8>),
    /// Nothing was sent (closing without announcing).
    Nothing,
}

/// How a call ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Res {
    /// It returned a value; the device must have sent `Expect`.
    Ok(Expect),
    /// `Error::Device`: the device must have sent this status for this command.
    Device(u8, Status),
    /// `Error::Timeout`.
    Timeout,
    /// `Error::ReplyLost`: the device must have acknowledged this motion during the call.
    ReplyLost(u8),
    /// `Error::ConnectionLost`.
    Lost,
    /// `Error::Closed`.
    Closed,
    /// `Error::SubscriptionConflict` (the client's own documented refusal).
    Conflict,
    /// The caller dropped the call (cancellation).
    Cancelled,
    /// Anything else (always a violation: the arguments are valid).
    Other(String),
}

/// One call as the oracle sees it.
#[derive(Clone, Debug)]
pub struct CallRec {
    /// Which client (index).
    pub client: usize,
    /// `client.caller.n`.
    pub who: String,
    /// What was called.
    pub op: String,
    /// The command id.
    pub id: u8,
    /// Call start and end (simulated).
    pub start: Instant,
    /// See `start`.
    pub end: Instant,
    /// The call's timeout (None: the caller gave none the oracle can hold it to).
    pub limit: Option<Duration>,
    /// How it ended.
    pub res: Res,
}

/// An auto-update a subscriber received.
#[derive(Clone, Debug)]
pub struct Update {
    /// Which client.
    pub client: usize,
    /// The command id.
    pub id: u8,
    /// The value's bytes as the device would send them.
    pub data: Vec<u8>,
    /// When the value was received.
    pub at: Instant,
}

/// One client and what the oracle must know about it.
pub struct ClientCtx {
    /// Its index.
    pub index: usize,
    /// The handle.
    pub client: Client,
    /// The simulator sessions its connections were (several after reconnects).
    pub sessions: Arc<Mutex<Vec<SessionId>>>,
    /// The client reconnects after a loss.
    pub reconnect: bool,
    /// `close()` announces the disconnect (0x07).
    pub announce: bool,
    /// `close()` was called (set before the call).
    pub closing: AtomicBool,
    /// Its settings.
    pub query_timeout: Duration,
    /// See `query_timeout`.
    pub motion_timeout: Duration,
    /// See `query_timeout`.
    pub grace: Duration,
    /// When the client reported losing its connection (its `connection_events`).
    pub losses: Arc<Mutex<Vec<Instant>>>,
    /// The replies (datagrams) the fault layer delivered to it duplicated or delayed (UDP).
    pub faulted: crate::core::datagrams::FaultedLog,
    /// The requests (datagrams) the fault layer delivered to the device duplicated or delayed
    /// (UDP).
    pub faulted_requests: crate::core::datagrams::FaultedLog,
    /// Per stream session (TCP, serial), what the link did with the bytes the device sent.
    pub carried: Arc<Mutex<Vec<(SessionId, crate::core::streams::CarriedLog)>>>,
}

impl ClientCtx {
    /// When the connection was first lost, if it was.
    pub fn first_loss(&self) -> Option<Instant> {
        self.losses.lock().unwrap().first().copied()
    }
}

/// Records when `client` reports a lost connection; ends with the client.
pub fn watch_losses(client: &Client, losses: Arc<Mutex<Vec<Instant>>>) {
    let mut events = client.connection_events();
    tokio::spawn(async move {
        while let Some(e) = events.next().await {
            if let gripper::reconnect::ConnectionEvent::Lost { .. } = e {
                losses.lock().unwrap().push(Instant::now());
            }
        }
    });
}

/// Everything the callers of a run record.
#[derive(Default)]
pub struct Log {
    /// Every call.
    pub calls: Mutex<Vec<CallRec>>,
    /// Every auto-update received.
    pub updates: Mutex<Vec<Update>>,
    /// Source of unique values.
    pub unique: AtomicU32,
}

/// How an error counts for the oracle.
pub fn classify(e: &Error) -> Res {
    match e {
        Error::Device { command, status } => Res::Device(*command, *status),
        Error::Timeout { .. } => Res::Timeout,
        Error::ReplyLost { command } => Res::ReplyLost(*command),
        Error::ConnectionLost { .. } => Res::Lost,
        Error::Closed => Res::Closed,
        Error::SubscriptionConflict { .. } => Res::Conflict,
        other => Res::Other(format!("{other:?}")),
    }
}

fn f32_data(v: f32) -> Vec<u8> {
    v.to_le_bytes().to_vec()
}

/// One caller: `ops` random calls on `ctx`, one after the other.
pub async fn caller(
    ctx: Arc<ClientCtx>,
    n: usize,
    mut rng: Prng,
    ops: u32,
    log: Arc<Log>,
    trace: SharedTrace,
) {
    tokio::time::sleep(rng.millis(0, 500)).await;
    let mut previous = None;
    for i in 0..ops {
        let who = format!("{}.{n}.{i}", ctx.index);
        let last = i + 1 == ops;
        previous = Some(one_call(&ctx, &who, &mut rng, last, previous, &log, &trace).await);
        if rng.one_in(3) {
            tokio::time::sleep(rng.millis(0, 300)).await;
        }
    }
}

async fn one_call(
    ctx: &ClientCtx,
    who: &str,
    rng: &mut Prng,
    last: bool,
    previous: Option<u64>,
    log: &Log,
    trace: &SharedTrace,
) -> u64 {
    // Timeouts: the client's, or the caller's own (sometimes "none": Duration::MAX).
    let (q, m) = match rng.below(60) {
        0 => (Duration::MAX, Duration::MAX),
        1..=12 => (rng.millis(20, 1000), rng.millis(200, 8000)),
        _ => (ctx.query_timeout, ctx.motion_timeout),
    };
    let cl = if (q, m) == (ctx.query_timeout, ctx.motion_timeout) {
        ctx.client.clone()
    } else {
        ctx.client.with_timeouts(q, m)
    };
    let unique = log.unique.fetch_add(1, Ordering::Relaxed);
    // A third of the calls repeat the caller's previous kind of call: the same command id
    // right after a timeout or a cancellation is where a late reply can reach the wrong call.
    let pick = match previous {
        Some(p) if p < 21 && rng.one_in(3) => p,
        _ => rng.below(if last { 22 } else { 21 }),
    };
    let width = rng.float(0.0, 110.0);
    let speed = rng.float(5.0, 420.0);
    let (op, cmd, limit): (String, u8, Duration) = match pick {
        0 | 1 => ("home".into(), id::HOMING, m),
        2 | 3 => (
            format!("pre_position({width:.1}, {speed:.0})"),
            id::PRE_POSITION,
            m,
        ),
        4 => (
            format!("grasp({:.1}, {speed:.0})", width.min(60.0)),
            id::GRASP,
            m,
        ),
        5 => (format!("release({width:.1}, {speed:.0})"), id::RELEASE, m),
        6 | 7 => ("stop".into(), id::STOP, q),
        8 => ("fast_stop".into(), id::FAST_STOP, q),
        9 | 10 => ("acknowledge_fast_stop".into(), id::ACK_FAST_STOP, q),
        11 => ("width_mm".into(), id::WIDTH, q),
        12 => ("acceleration".into(), id::GET_ACCELERATION, q),
        13 | 14 => (
            format!("set_acceleration({})", 100 + unique),
            id::SET_ACCELERATION,
            q,
        ),
        15 | 16 => (format!("loop_back({unique})"), id::LOOP, q),
        17 => ("request(0x46)".into(), id::TEMPERATURE, q),
        18 => ("request(0x50)".into(), id::SYSTEM_INFO, q),
        19 | 20 => ("subscribe_width_mm".into(), id::WIDTH, q),
        // close() documents no bound of its own: the task may be in a write (bounded by
        // query timeout + grace) when it gets the request, then waits for the announcement's
        // reply (query timeout), then shuts the transport down (query timeout + grace).
        _ => (
            "close".into(),
            id::ANNOUNCE_DISCONNECT,
            q.saturating_add(2 * ctx.query_timeout.saturating_add(ctx.grace)),
        ),
    };
    let payload = Bytes::from(format!("explore-{unique}").into_bytes());
    let period = rng.millis(10, 200);
    let updates_wanted = rng.between(1, 5);
    // When `subscribe_width_mm` returned: the end of the call the oracle pairs with a reply (the
    // wait for updates after it is no part of the answer, `wsg-udp:0x5ac281a1a85df0a1`).
    let subscribed_at: Mutex<Option<Instant>> = Mutex::new(None);
    let call = async {
        match pick {
            0 | 1 => cl
                .home(HomingDirection::Default)
                .await
                .map(|()| Expect::Motion),
            2 | 3 => cl.pre_position(width, speed).await.map(|()| Expect::Motion),
            4 => cl
                .grasp(width.min(60.0), speed)
                .await
                .map(|()| Expect::Motion),
            5 => cl.release(width, speed).await.map(|()| Expect::Motion),
            6 | 7 => cl.stop().await.map(|()| Expect::Success),
            8 => cl.fast_stop().await.map(|()| Expect::Success),
            9 | 10 => cl.acknowledge_fast_stop().await.map(|()| Expect::Success),
            11 => cl.width_mm().await.map(|v| Expect::Data(f32_data(v))),
            12 => cl
                .acceleration_mm_per_s2()
                .await
                .map(|v| Expect::Data(f32_data(v))),
            13 | 14 => cl
                .set_acceleration((100 + unique) as f32)
                .await
                .map(|()| Expect::Success),
            15 | 16 => {
                let r = cl.request(id::LOOP, payload.clone()).await?;
                Ok(Expect::Exact(r.status, r.data.to_vec()))
            }
            17 | 18 => {
                let r = cl.request(cmd, Bytes::new()).await?;
                Ok(Expect::Exact(r.status, r.data.to_vec()))
            }
            19 | 20 => {
                let mut sub = cl
                    .subscribe_width_mm(UpdateOptions::periodic(period))
                    .await?;
                *subscribed_at.lock().unwrap() = Some(Instant::now());
                note(trace, format!("call {who} {op} subscribed"));
                let client = ctx.index;
                // The updates are checked apart from the call (they come after it).
                let got = async {
                    let mut got = Vec::new();
                    for _ in 0..updates_wanted {
                        match tokio::time::timeout(
                            period * 4 + Duration::from_millis(100),
                            sub.next(),
                        )
                        .await
                        {
                            Ok(Some(v)) => got.push(Update {
                                client,
                                id: id::WIDTH,
                                data: f32_data(v),
                                at: Instant::now(),
                            }),
                            _ => break,
                        }
                    }
                    got
                };
                let got = got.await;
                log.updates.lock().unwrap().extend(got);
                Ok(Expect::Success)
            }
            _ => {
                ctx.closing.store(true, Ordering::SeqCst);
                let announced = if ctx.announce {
                    Expect::Success
                } else {
                    Expect::Nothing
                };
                cl.close().await.map(|()| announced)
            }
        }
    };
    // Cancellation: now and then the caller gives up early (the future is dropped); a call
    // without a timeout is given up after a minute so that the run ends.
    let cancel_after = if q == Duration::MAX {
        Some(Duration::from_secs(60))
    } else if rng.one_in(8) {
        Some(rng.millis(0, 2 * limit.as_millis().min(20_000) as u64))
    } else {
        None
    };
    let start = Instant::now();
    note(trace, format!("call {who} {op} start"));
    let r = match cancel_after {
        Some(d) => tokio::select! {
            biased;
            r = call => Some(r),
            _ = tokio::time::sleep(d) => None,
        },
        None => Some(call.await),
    };
    let end = subscribed_at
        .into_inner()
        .unwrap()
        .unwrap_or_else(Instant::now);
    let res = match r {
        None => Res::Cancelled,
        Some(Ok(e)) => Res::Ok(e),
        Some(Err(e)) => classify(&e),
    };
    note(trace, format!("call {who} {op} end {res:?}"));
    let limit = Some(limit).filter(|l| *l != Duration::MAX);
    log.calls.lock().unwrap().push(CallRec {
        client: ctx.index,
        who: who.to_owned(),
        op,
        id: cmd,
        start,
        end,
        limit,
        res,
    });
    pick
}
