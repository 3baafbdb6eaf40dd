//! The WSG workload: what one caller does, and what each call returned, recorded for the
//! oracle. Calls are self-identifying where the protocol allows it: loop-back payloads and
//! acceleration values are unique in a run.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use bytes::Bytes;
use futures_util::StreamExt;
use gripper::wsg::client::FINGER_POWER_ON_DURATION;
use gripper::wsg::command::id;
use gripper::wsg::sim::SessionId;
use gripper::wsg::{
    Client, Command, Error, Finger, HomingDirection, SoftLimits, Status, Subscription,
    UpdateOptions,
};
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
    /// `Error::InvalidArgument` (the client's refusal of an argument it documents as invalid).
    Invalid,
    /// The call had not ended after [`NEVER_ENDS`] (promise 8; the run then gave it up).
    Hung,
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
    /// The call was drawn with an argument the client must refuse (`Error::InvalidArgument`).
    pub bad: bool,
    /// A loop-back's payload: the reply data that is this call's own and no other's.
    pub echo: Option<Vec<u8>>,
    /// A call of the quiet phase (promise 10).
    pub quiet: bool,
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
    /// Its builder options.
    pub options: super::BuilderOptions,
    /// Violations seen at its opening (an accessor's wrong answer).
    pub notes: Mutex<Vec<String>>,
    /// The kinds of call its callers made (the quiet phase makes each once more).
    pub kinds: Mutex<std::collections::BTreeSet<u64>>,
    /// The simulator (its record).
    pub sim: Arc<gripper::wsg::sim::SimServer>,
    /// The simulator's time zero.
    pub sim_t0: Instant,
    /// Per stream connection, what the client's end saw (`tap.rs`).
    pub taps: Arc<Mutex<Vec<(SessionId, super::tap::SharedTap)>>>,
    /// A stop storm: half of every caller's calls are stops (issue 29 D).
    pub storm: AtomicBool,
}

impl ClientCtx {
    /// [`super::SHORT_OF_BARRIER`] if it applies to this client (a byte stream whose
    /// `max_payload_len` is below a barrier echo's length), else empty.
    pub fn echo_tag(&self) -> &'static str {
        let stream = self.client.transport() != gripper::wsg::TransportKind::Udp;
        if stream && self.options.max_payload() < super::BARRIER_ECHO_LEN {
            super::SHORT_OF_BARRIER
        } else {
            ""
        }
    }

    /// The simulator's record so far.
    pub fn sim_record(&self) -> gripper::wsg::sim::SimRecording {
        self.sim.recording()
    }

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
    /// Violations a caller saw directly (an accessor's wrong answer).
    pub notes: Mutex<Vec<String>>,
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
        Error::InvalidArgument { .. } => Res::Invalid,
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
        let how = How::Drawn { last, previous };
        let pick = one_call(&ctx, &who, &mut rng, how, &log, &trace).await;
        ctx.kinds.lock().unwrap().insert(pick);
        previous = Some(pick);
        // A call that never ended (promise 8, reported) may hold its id for good: the
        // caller's next calls would each wait as long, and the run would not end.
        if log
            .calls
            .lock()
            .unwrap()
            .iter()
            .any(|c| c.who == who && c.res == Res::Hung)
        {
            break;
        }
        if rng.one_in(3) {
            tokio::time::sleep(rng.millis(0, 300)).await;
        }
    }
}

/// The kinds of call a caller draws from (`one_call`'s `pick`); the last, [`CLOSE`], only as
/// a caller's last call. Kinds 0–20 are issue 20's; 21 on call the rest of `wsg::Client`'s
/// public methods by name (issue 29: the API coverage step greps the workload for them).
const KINDS: u64 = 50;
/// `close()`.
const CLOSE: u64 = KINDS;

/// The motion timeout of the quiet phase's calls: far more than any motion takes at
/// [`QUIET_SPEED`] (110 mm in under half a second) or a homing of the simulated WSG 50.
const QUIET_MOTION_TIMEOUT: Duration = Duration::from_secs(30);

/// The finger speed of the quiet phase's motions, mm/s.
const QUIET_SPEED: f32 = 400.0;

/// `Client::request_with_timeout`'s own refusal: a command id the framing cannot carry.
const UNFRAMEABLE_ID: u8 = 0xAA;

/// What the device sends for a 0x40 value (u32, little endian).
fn state_data(s: &gripper::wsg::SystemState) -> Vec<u8> {
    s.bits().to_le_bytes().to_vec()
}

/// What the device sends for a 0x41 value (one byte).
fn grip_data(s: &gripper::wsg::GripState) -> Vec<u8> {
    vec![s.to_u8()]
}

/// Encodes a value with its type's own encoder (the inverse of its decoder).
fn encoded(f: impl FnOnce(&mut bytes::BytesMut)) -> Vec<u8> {
    let mut b = bytes::BytesMut::new();
    f(&mut b);
    b.to_vec()
}

/// What following a subscription needs besides the subscription.
struct Follow<'a> {
    /// Notes when the subscription call returned (the end of the call for the oracle).
    subscribed: &'a (dyn Fn() + Sync),
    client: usize,
    period: Duration,
    wanted: u64,
    who: &'a str,
    log: &'a Log,
}

impl Follow<'_> {
    /// Reads up to `wanted` updates of `sub` (each within four periods), checks its own
    /// accessors, records the updates (as the device's bytes, `data`) for the oracle, then
    /// drops it: the subscription call's answer.
    async fn run<T>(
        &self,
        mut sub: Subscription<T>,
        id: u8,
        data: fn(&T) -> Vec<u8>,
    ) -> Result<Expect, Error> {
        (self.subscribed)();
        if sub.command_id() != id {
            self.log.notes.lock().unwrap().push(format!(
                "2 (each answer is the device's): {}'s subscription says command id {:#04x}, not {id:#04x}",
                self.who,
                sub.command_id()
            ));
        }
        let mut got = Vec::new();
        for _ in 0..self.wanted {
            let wait = self.period * 4 + Duration::from_millis(100);
            match tokio::time::timeout(wait, sub.next()).await {
                Ok(Some(v)) => got.push(Update {
                    client: self.client,
                    id,
                    data: data(&v),
                    at: Instant::now(),
                }),
                _ => break,
            }
        }
        // Counted, not judged: a reader that keeps up misses nothing, but the buffer may be 1.
        let _ = sub.missed();
        self.log.updates.lock().unwrap().extend(got);
        Ok(Expect::Success)
    }
}

/// How a call's kind and arguments are chosen.
#[derive(Clone, Copy)]
pub enum How {
    /// Drawn (the fault phase): the caller's last call may be `close()`; a third repeat the
    /// previous kind.
    Drawn {
        /// The caller's last call.
        last: bool,
        /// The kind of the caller's previous call.
        previous: Option<u64>,
    },
    /// This kind, with valid arguments, the client's own timeouts and no cancellation (the
    /// quiet phase, promise 10).
    Quiet(u64),
}

/// Whether kind `pick` is `close()`.
pub fn is_close(pick: u64) -> bool {
    pick == CLOSE
}

/// One call; returns its kind.
pub async fn one_call(
    ctx: &ClientCtx,
    who: &str,
    rng: &mut Prng,
    how: How,
    log: &Log,
    trace: &SharedTrace,
) -> u64 {
    let quiet = matches!(how, How::Quiet(_));
    let (last, previous) = match how {
        How::Drawn { last, previous } => (last, previous),
        How::Quiet(_) => (false, None),
    };
    // Timeouts: the client's, or the caller's own (sometimes "none": Duration::MAX, or zero).
    let (q, m) = match rng.below(60) {
        // The quiet phase: the client's query timeout, and time enough for any motion of the
        // simulated WSG 50 (homing included) at the quiet phase's speed.
        _ if quiet => (ctx.query_timeout, QUIET_MOTION_TIMEOUT),
        0 => (Duration::MAX, Duration::MAX),
        1 => (Duration::ZERO, Duration::ZERO),
        2 => (ctx.query_timeout, Duration::MAX),
        3..=12 => (rng.millis(20, 1000), rng.millis(200, 8000)),
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
    let pick = match (how, previous) {
        (How::Quiet(p), _) => p,
        _ if ctx.storm.load(Ordering::Relaxed) && rng.one_in(2) => 6 + rng.below(3),
        (_, Some(p)) if p < CLOSE && rng.one_in(3) => p,
        _ => rng.below(if last { KINDS + 1 } else { KINDS }),
    };
    let width = rng.float(0.0, 110.0);
    let speed = if quiet {
        QUIET_SPEED
    } else {
        rng.float(5.0, 420.0)
    };
    // Now and then an argument the client must refuse with Error::InvalidArgument (bad input is
    // a typed error, never a panic or a request sent).
    let bad = rng.one_in(25) && !quiet;
    let finger = if rng.one_in(2) {
        Finger::One
    } else {
        Finger::Two
    };
    let flag = rng.one_in(2);
    let short = rng.float(0.0, 5.0);
    let long = rng.float(60.0, 110.0);
    let limits = SoftLimits {
        minus_mm: short,
        plus_mm: long,
    };
    let force = rng.float(5.0, 80.0);
    let distance = rng.float(-30.0, 30.0);
    let raw_timeout = match rng.below(4) {
        _ if quiet => ctx.query_timeout,
        0 => Duration::MAX,
        1 => Duration::ZERO,
        _ => rng.millis(20, 1000),
    };
    let fq = q.saturating_add(FINGER_POWER_ON_DURATION);
    let tag = if bad {
        "x".repeat(gripper::wsg::command::MAX_TAG_LEN + 1)
    } else {
        format!("tag-{unique}")
    };
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
        21 => (
            format!(
                "loop_back typed ({unique}{})",
                if bad { ", too long" } else { "" }
            ),
            id::LOOP,
            q,
        ),
        22 => (
            format!("pre_position_relative({distance:.1}, {speed:.0})"),
            id::PRE_POSITION,
            m,
        ),
        23 => (format!("set_grasping_force({force:.1})"), id::SET_FORCE, q),
        24 => ("grasping_force_n".into(), id::GET_FORCE, q),
        25 => (
            format!("set_soft_limits({limits:?})"),
            id::SET_SOFT_LIMITS,
            q,
        ),
        26 => ("soft_limits".into(), id::GET_SOFT_LIMITS, q),
        27 => ("clear_soft_limits".into(), id::CLEAR_SOFT_LIMITS, q),
        28 => (format!("set_overdrive({flag})"), id::OVERDRIVE, q),
        29 => ("tare_force_sensor".into(), id::TARE, q),
        30 => ("system_state".into(), id::SYSTEM_STATE, q),
        31 => ("grip_state".into(), id::GRIP_STATE, q),
        32 => (
            format!("grasping_statistics({flag})"),
            id::GRASPING_STATISTICS,
            q,
        ),
        33 => ("speed_mm_per_s".into(), id::SPEED, q),
        34 => ("force_n".into(), id::FORCE, q),
        35 => ("temperature_c".into(), id::TEMPERATURE, q),
        36 => ("system_info".into(), id::SYSTEM_INFO, q),
        37 => (
            format!("set_device_tag({} chars)", tag.len()),
            id::SET_TAG,
            q,
        ),
        38 => ("device_tag".into(), id::GET_TAG, q),
        39 => ("system_limits".into(), id::SYSTEM_LIMITS, q),
        40 => (format!("finger_info({finger:?})"), finger.base_id(), q),
        41 => (format!("finger_flags({finger:?})"), finger.base_id() + 1, q),
        42 => (
            format!("set_finger_power({finger:?}, {flag})"),
            finger.base_id() + 2,
            if flag { fq } else { q },
        ),
        43 => (format!("finger_data({finger:?})"), finger.base_id() + 3, q),
        44 => (
            format!("command({})", if flag { "Loop" } else { "GetForce" }),
            if flag { id::LOOP } else { id::GET_FORCE },
            q,
        ),
        45 => (
            format!(
                "request_with_timeout({:#04x}, {raw_timeout:?})",
                if bad { UNFRAMEABLE_ID } else { id::LOOP }
            ),
            if bad { UNFRAMEABLE_ID } else { id::LOOP },
            raw_timeout,
        ),
        46 => ("subscribe_system_state".into(), id::SYSTEM_STATE, q),
        47 => ("subscribe_grip_state".into(), id::GRIP_STATE, q),
        48 => ("subscribe_speed_mm_per_s".into(), id::SPEED, q),
        49 => ("subscribe_force_n".into(), id::FORCE, q),
        // close() documents no bound of its own: the task may be in a write (bounded by
        // query timeout + grace) when it gets the request, then waits for the announcement's
        // reply (query timeout), then shuts the transport down (query timeout + grace).
        _ => (
            "close".into(),
            id::ANNOUNCE_DISCONNECT,
            q.saturating_add(2 * ctx.query_timeout.saturating_add(ctx.grace)),
        ),
    };
    // Which kinds take the bad argument (the others ignore `bad`).
    let bad = bad && matches!(pick, 2 | 3 | 19..=21 | 37 | 45 | 46..=49);
    let op = if bad {
        format!("{op} [invalid argument]")
    } else {
        op
    };
    let echo = !bad && matches!(pick, 15 | 16 | 21 | 45) || pick == 44 && flag;
    // A NaN target (motion) or an update period below 10 ms (subscription): refused.
    let width = if bad { f32::NAN } else { width };
    let payload = Bytes::from(format!("explore-{unique}").into_bytes());
    let typed_payload = if bad {
        Bytes::from(vec![b'x'; gripper::wsg::command::MAX_LOOP_LEN + 1])
    } else {
        payload.clone()
    };
    let period = if bad {
        Duration::ZERO
    } else {
        rng.millis(10, 200)
    };
    let options = if rng.one_in(3) {
        UpdateOptions::on_change(period)
    } else {
        UpdateOptions::periodic(period)
    };
    let updates_wanted = rng.between(1, 5);
    // When a subscription call returned: the end of the call the oracle pairs with a reply (the
    // wait for updates after it is no part of the answer, `wsg-udp:0x5ac281a1a85df0a1`).
    let subscribed_at: Mutex<Option<Instant>> = Mutex::new(None);
    let subscribed = || {
        *subscribed_at.lock().unwrap() = Some(Instant::now());
        note(trace, format!("call {who} {op} subscribed"));
    };
    let follow = Follow {
        subscribed: &subscribed,
        client: ctx.index,
        period,
        wanted: updates_wanted,
        who,
        log,
    };
    let f32d = |v: f32| Expect::Data(f32_data(v));
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
            11 => cl.width_mm().await.map(f32d),
            12 => cl.acceleration_mm_per_s2().await.map(f32d),
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
                let sub = cl.subscribe_width_mm(options).await?;
                follow.run(sub, id::WIDTH, |v| f32_data(*v)).await
            }
            21 => cl
                .loop_back(typed_payload.clone())
                .await
                .map(|d| Expect::Data(d.to_vec())),
            22 => cl
                .pre_position_relative(distance, speed)
                .await
                .map(|()| Expect::Motion),
            23 => cl.set_grasping_force(force).await.map(|()| Expect::Success),
            24 => cl.grasping_force_n().await.map(f32d),
            25 => cl.set_soft_limits(limits).await.map(|()| Expect::Success),
            26 => cl.soft_limits().await.map(|l| match l {
                Some(l) => Expect::Data(encoded(|b| l.encode(b))),
                None => Expect::Exact(Status::NotAvailable, Vec::new()),
            }),
            27 => cl.clear_soft_limits().await.map(|()| Expect::Success),
            28 => cl.set_overdrive(flag).await.map(|()| Expect::Success),
            29 => cl.tare_force_sensor().await.map(|()| Expect::Success),
            30 => cl
                .system_state()
                .await
                .map(|s| Expect::Data(state_data(&s))),
            31 => cl.grip_state().await.map(|s| Expect::Data(grip_data(&s))),
            32 => cl
                .grasping_statistics(flag)
                .await
                .map(|s| Expect::Data(encoded(|b| s.encode(b)))),
            33 => cl.speed_mm_per_s().await.map(f32d),
            34 => cl.force_n().await.map(f32d),
            35 => cl.temperature_c().await.map(|_| Expect::Success),
            36 => cl
                .system_info()
                .await
                .map(|s| Expect::Data(encoded(|b| s.encode(b)))),
            37 => cl.set_device_tag(&tag).await.map(|()| Expect::Success),
            38 => cl.device_tag().await.map(|t| match t {
                Some(t) => Expect::Data(t.into_bytes()),
                None => Expect::Exact(Status::NotAvailable, Vec::new()),
            }),
            39 => cl
                .system_limits()
                .await
                .map(|s| Expect::Data(encoded(|b| s.encode(b)))),
            40 => cl
                .finger_info(finger)
                .await
                .map(|s| Expect::Data(encoded(|b| s.encode(b)))),
            41 => cl
                .finger_flags(finger)
                .await
                .map(|f| Expect::Data(f.bits().to_le_bytes().to_vec())),
            42 => cl
                .set_finger_power(finger, flag)
                .await
                .map(|()| Expect::Success),
            43 => cl
                .finger_data(finger)
                .await
                .map(|d| Expect::Data(d.to_vec())),
            44 => {
                let command = if flag {
                    Command::Loop(payload.clone())
                } else {
                    Command::GetForce
                };
                cl.command(command).await.map(|d| Expect::Data(d.to_vec()))
            }
            45 => {
                let r = cl
                    .request_with_timeout(cmd, payload.clone(), raw_timeout)
                    .await?;
                Ok(Expect::Exact(r.status, r.data.to_vec()))
            }
            46 => {
                let sub = cl.subscribe_system_state(options).await?;
                follow.run(sub, id::SYSTEM_STATE, state_data).await
            }
            47 => {
                let sub = cl.subscribe_grip_state(options).await?;
                follow.run(sub, id::GRIP_STATE, grip_data).await
            }
            48 => {
                let sub = cl.subscribe_speed_mm_per_s(options).await?;
                follow.run(sub, id::SPEED, |v| f32_data(*v)).await
            }
            49 => {
                let sub = cl.subscribe_force_n(options).await?;
                follow.run(sub, id::FORCE, |v| f32_data(*v)).await
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
    // Cancellation: now and then the caller gives up early (the future is dropped). A call
    // without a timeout is not given up: promise 8 wants it to end on its own; the watchdog
    // below only keeps a run that breaks it finite (and reports it).
    let cancel_after = if limit == Duration::MAX || quiet {
        None
    } else if rng.one_in(8) {
        Some(rng.millis(0, 2 * limit.as_millis().min(20_000) as u64))
    } else {
        None
    };
    let start = Instant::now();
    note(trace, format!("call {who} {op} start"));
    let r = tokio::select! {
        biased;
        r = crate::core::phases::unless_given_up(cancel_after, call) => r.map(Some),
        _ = tokio::time::sleep(NEVER_ENDS) => Some(None),
    };
    let end = subscribed_at
        .into_inner()
        .unwrap()
        .unwrap_or_else(Instant::now);
    let res = match r {
        None => Res::Cancelled,
        Some(None) => Res::Hung,
        Some(Some(Ok(e))) => Res::Ok(e),
        Some(Some(Err(e))) => classify(&e),
    };
    note(trace, format!("call {who} {op} end {res:?}"));
    log.calls.lock().unwrap().push(CallRec {
        client: ctx.index,
        who: who.to_owned(),
        op,
        id: cmd,
        start,
        end,
        limit: Some(limit).filter(|l| *l != Duration::MAX),
        bad,
        echo: echo.then(|| payload.to_vec()),
        quiet,
        res,
    });
    pick
}

/// How long a call may go on before the run gives it up as one that never ends (promise 8):
/// far beyond every bound the client documents for a call without timeout (the query timeout
/// plus the grace for a request; the motion timeout, a motion's run and two probes a grace
/// apart for a motion: at most about 10 + 22 + 2 × 2 s here, and the calls of its id queued
/// before it, each bounded by its own timeout), so that only a call that would wait for ever
/// reaches it.
pub const NEVER_ENDS: Duration = Duration::from_secs(300);
