//! Field fidelity of the WSG client (issue 10, items 1 to 5): what a real cell needs when a
//! frame is lost or late. Each test runs the real client over loopback TCP against a scripted
//! fake device (raw socket, frames through `WsgCodec`), which loses a stop reply, never sends a
//! final reply, delays one past the client's probe, or streams 0x40 during recovery. Every
//! check fails with the client's earlier behaviour (a stop queued behind a lost one, an id held
//! for good, a move released on one "not moving" answer).
//!
//! Real sockets, so the real clock: the client's timeouts are short, and `guard` only catches
//! hangs (it is no performance assertion). The fake waits for events, never for time, except
//! where the delay is the fault itself (a final reply held back past the probe).

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

use bytes::{Bytes, BytesMut};
use futures_util::StreamExt;
use gripper::wsg::command::id;
use gripper::wsg::{
    Client, ClientBuilder, Error, Finger, Frame, Reply, Status, SystemState, UpdateOptions,
    WsgCodec,
};
use tokio::io::AsyncWriteExt;
use tokio::net::TcpListener;
use tokio::sync::{mpsc, watch};
use tokio_util::codec::FramedRead;

/// Outer bound of a call that must end on its own: only a hang takes this long.
const HANG: Duration = Duration::from_secs(20);

async fn guard<F: std::future::Future>(what: &str, f: F) -> F::Output {
    tokio::time::timeout(HANG, f)
        .await
        .unwrap_or_else(|_| panic!("{what}: hung"))
}

/// The device side of the wire, handed to the script with every received request.
#[derive(Clone)]
struct Wire(mpsc::UnboundedSender<Frame>);

impl Wire {
    fn reply(&self, id: u8, status: Status, data: &[u8]) {
        let frame = Reply::new(id, status, Bytes::copy_from_slice(data)).to_frame();
        // The connection may be gone at the end of a test: nothing to do then.
        let _ = self.0.send(frame);
    }

    /// Sends a reply after `delay`: a final reply held back by the device.
    fn reply_after(
        &self,
        delay: Duration,
        id: u8,
        status: Status,
        then: impl FnOnce() + Send + 'static,
    ) {
        let wire = self.clone();
        tokio::spawn(async move {
            tokio::time::sleep(delay).await;
            then();
            wire.reply(id, status, &[]);
        });
    }
}

/// A scripted fake WSG serving one TCP connection.
struct Fake {
    addr: SocketAddr,
    /// The ids received so far, in order.
    received: watch::Receiver<Vec<u8>>,
}

impl Fake {
    /// Serves one client with `script`, called for every request; the disconnect announcement
    /// (0x07) is answered for it.
    async fn start(mut script: impl FnMut(&Frame, &Wire) + Send + 'static) -> Fake {
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let (log, received) = watch::channel(Vec::new());
        tokio::spawn(async move {
            let (socket, _) = listener.accept().await.unwrap();
            let (read, mut write) = socket.into_split();
            let mut stream = FramedRead::new(read, WsgCodec::new());
            let (tx, mut rx) = mpsc::unbounded_channel::<Frame>();
            tokio::spawn(async move {
                let mut buf = BytesMut::new();
                while let Some(frame) = rx.recv().await {
                    buf.clear();
                    gripper::wsg::frame::encode(&frame, &mut buf).unwrap();
                    if write.write_all(&buf).await.is_err() {
                        break;
                    }
                }
            });
            let wire = Wire(tx);
            while let Some(Ok(frame)) = stream.next().await {
                log.send_modify(|ids| ids.push(frame.id));
                if frame.id == id::ANNOUNCE_DISCONNECT {
                    wire.reply(frame.id, Status::Success, &[]);
                } else {
                    script(&frame, &wire);
                }
            }
        });
        Fake { addr, received }
    }

    fn count(&self, command: u8) -> usize {
        self.received
            .borrow()
            .iter()
            .filter(|i| **i == command)
            .count()
    }

    async fn wait_for(&self, command: u8, n: usize) {
        let mut rx = self.received.clone();
        guard("waiting for the fake to receive a request", async {
            rx.wait_for(|ids| ids.iter().filter(|i| **i == command).count() >= n)
                .await
                .unwrap();
        })
        .await;
    }
}

fn builder() -> ClientBuilder {
    Client::builder()
}

async fn connect(builder: ClientBuilder, fake: &Fake) -> Client {
    builder.connect_tcp(fake.addr).await.unwrap()
}

/// The nth (1-based) request of `command` the script has seen, counted per id.
fn nth(counts: &mut [usize; 256], command: u8) -> usize {
    counts[usize::from(command)] += 1;
    counts[usize::from(command)]
}

fn state(flags: SystemState) -> [u8; 4] {
    flags.bits().to_le_bytes()
}

// ---- item 1: stop and FAST STOP are never queued ----------------------------------------------

#[tokio::test]
async fn a_stop_is_sent_at_once_even_while_an_earlier_stops_reply_is_lost() {
    // The first stop and the first FAST STOP get no reply (lost); later ones are answered. A
    // loop-back is echoed (3.1.1): on TCP the client proves a stop lost by a loop-back's echo
    // before it sends the stop again.
    let mut counts = [0; 256];
    let fake = Fake::start(move |f, wire| {
        if (f.id == id::STOP || f.id == id::FAST_STOP) && nth(&mut counts, f.id) == 1 {
            return;
        }
        let echo: &[u8] = if f.id == id::LOOP { &f.payload } else { &[] };
        wire.reply(f.id, Status::Success, echo);
    })
    .await;
    // A long query timeout: a stop queued behind the lost one would wait that long.
    let client = connect(builder().query_timeout(Duration::from_secs(60)), &fake).await;
    for command in [id::STOP, id::FAST_STOP] {
        let stop = |c: Client| async move {
            if command == id::STOP {
                c.stop().await
            } else {
                c.fast_stop().await
            }
        };
        let first = tokio::spawn(stop(client.clone()));
        fake.wait_for(command, 1).await;
        // The second goes out although the first is unanswered, and completes ...
        guard("the second stop", stop(client.clone()))
            .await
            .unwrap();
        // ... on a reply that cannot be the first stop's (issue 20.2 #3): the first reply is
        // taken for the oldest unanswered stop, so the stop is sent again for the second call
        // (after a loop-back's echo proved the first stop lost).
        assert!(fake.count(command) >= 3, "{}", fake.count(command));
        // ... and so does the first: it was sent before the reply that came.
        guard("the first stop", first).await.unwrap().unwrap();
    }
}

/// The explorer's `wsg-tcp:0x2082b0e305e913c4` over a real socket: the replies stall in transit
/// past the first stop call's deadline plus the grace, and the second call's stop never reaches
/// the device (corrupted on its way). The stalled reply of the first stop must not complete
/// the second call: on TCP a stop is never given up on time, so the second call's `Ok` comes
/// only from a stop the device received after it (sent again once a loop-back proved the lost
/// one lost).
#[tokio::test]
async fn a_stop_reply_stalled_past_the_grace_does_not_complete_a_later_stop() {
    let mut counts = [0; 256];
    let mut held: Option<Vec<Frame>> = Some(Vec::new());
    let fake = Fake::start(move |f, wire| {
        let n = if f.id == id::STOP {
            nth(&mut counts, f.id)
        } else {
            0
        };
        if n == 2 {
            // The second call's stop is lost on its way; the stall ends with it.
            for frame in held.take().unwrap_or_default() {
                let _ = wire.0.send(frame);
            }
            return;
        }
        let echo: &[u8] = if f.id == id::LOOP { &f.payload } else { &[] };
        let reply = Reply::new(f.id, Status::Success, Bytes::copy_from_slice(echo)).to_frame();
        match held.as_mut() {
            Some(stalled) => stalled.push(reply),
            None => {
                let _ = wire.0.send(reply);
            }
        }
    })
    .await;
    let grace = Duration::from_millis(50);
    let client = connect(
        builder()
            .query_timeout(Duration::from_millis(50))
            .late_reply_grace(grace),
        &fake,
    )
    .await;
    let err = guard("the first stop", client.stop()).await.unwrap_err();
    assert!(matches!(err, Error::Timeout { .. }), "{err}");
    // The fault itself: the stall lasts well past the first call's deadline plus the grace.
    tokio::time::sleep(grace * 4).await;
    let patient = client.with_timeouts(Duration::from_secs(5), Duration::from_secs(5));
    guard("the second stop", patient.stop()).await.unwrap();
    // Stop 1 was the first call's, stop 2 (the second call's) was lost: the reply that
    // completed the second call must be one to a stop received after it.
    assert!(fake.count(id::STOP) >= 3, "{}", fake.count(id::STOP));
}

// ---- item 2: no id stays busy for good after a lost final reply --------------------------------

#[tokio::test]
async fn a_lost_final_reply_of_finger_power_fails_the_call_and_frees_the_id() {
    // Finger power on (0x62): E_CMD_PENDING, then the final reply "nach etwa 500 ms" (3.6.3);
    // the first final reply is lost. Loop-backs are echoed (3.1.1): on a stream the released
    // finger power on fences its id until a barrier's echo comes back.
    let mut counts = [0; 256];
    let fake = Fake::start(move |f, wire| match f.id {
        0x62 => {
            wire.reply(f.id, Status::CmdPending, &[]);
            if nth(&mut counts, f.id) > 1 {
                wire.reply(f.id, Status::Success, &[]);
            }
        }
        id::LOOP => wire.reply(f.id, Status::Success, &f.payload),
        _ => wire.reply(f.id, Status::Success, &[]),
    })
    .await;
    let client = connect(
        builder()
            .query_timeout(Duration::from_millis(200))
            // A motion timeout finger power must not wait for.
            .motion_timeout(Duration::from_secs(600))
            .late_reply_grace(Duration::from_millis(200)),
        &fake,
    )
    .await;
    let err = guard("finger power", client.set_finger_power(Finger::One, true))
        .await
        .unwrap_err();
    assert!(
        matches!(err, Error::Timeout { command: 0x62, timeout } if timeout < Duration::from_secs(2)),
        "{err}"
    );
    // The id is released a grace period later: the next call is sent and answered.
    guard(
        "finger power again",
        client.set_finger_power(Finger::One, true),
    )
    .await
    .unwrap();
    assert_eq!(fake.count(0x62), 2);
}

#[tokio::test]
async fn a_lost_final_reply_of_a_raw_request_frees_the_id_after_its_timeout_and_grace() {
    const RAW: u8 = 0x5A;
    let mut counts = [0; 256];
    // Loop-backs are echoed (3.1.1): on a stream the released request fences its id until a
    // barrier's echo comes back.
    let fake = Fake::start(move |f, wire| {
        if f.id == RAW {
            wire.reply(RAW, Status::CmdPending, &[]);
            if nth(&mut counts, RAW) > 1 {
                wire.reply(RAW, Status::Success, b"done");
            }
        } else if f.id == id::LOOP {
            wire.reply(f.id, Status::Success, &f.payload);
        } else {
            wire.reply(f.id, Status::Success, &[]);
        }
    })
    .await;
    let client = connect(
        builder().late_reply_grace(Duration::from_millis(200)),
        &fake,
    )
    .await;
    let err = guard(
        "raw request",
        client.request_with_timeout(RAW, Bytes::new(), Duration::from_millis(200)),
    )
    .await
    .unwrap_err();
    assert!(matches!(err, Error::Timeout { command: RAW, .. }), "{err}");
    let reply = guard(
        "raw request again",
        client.request_with_timeout(RAW, Bytes::new(), Duration::from_secs(5)),
    )
    .await
    .unwrap();
    assert_eq!(
        (reply.status, &reply.data[..]),
        (Status::Success, &b"done"[..])
    );
    assert_eq!(fake.count(RAW), 2);
}

// ---- item 3: recovery must not release a move early --------------------------------------------

/// A fake whose first pre-position is acknowledged and whose final reply (E_AXIS_BLOCKED, so
/// that it cannot pass for another's) is held back `delay` past the first probe that follows
/// the move, while every 0x40 answer says "not moving" (the flags are not synchronised with
/// the end of a move, Anhang B). With `stream`, the fake also streams 0x40 every 10 ms once the
/// client subscribes. Returns the fake and a flag set if the second pre-position arrived
/// before the first one's final reply was sent: the client released the id early.
async fn late_final_reply_fake(delay: Duration, stream: bool) -> (Fake, Arc<AtomicBool>) {
    let early = Arc::new(AtomicBool::new(false));
    let final_sent = Arc::new(AtomicBool::new(false));
    let probes_after_move = Arc::new(AtomicUsize::new(0));
    let (e, sent, probes) = (early.clone(), final_sent.clone(), probes_after_move.clone());
    let mut counts = [0; 256];
    let mut streaming = false;
    let idle = state(SystemState::REFERENCED);
    let fake = Fake::start(move |f, wire| match f.id {
        id::PRE_POSITION => {
            wire.reply(f.id, Status::CmdPending, &[]);
            if nth(&mut counts, f.id) == 1 {
                probes.store(1, Ordering::SeqCst);
            } else {
                e.store(!sent.load(Ordering::SeqCst), Ordering::SeqCst);
                wire.reply(f.id, Status::Success, &[]);
            }
        }
        id::SYSTEM_STATE => {
            wire.reply(f.id, Status::Success, &idle);
            if stream && f.payload.first().is_some_and(|flags| flags & 1 == 1) && !streaming {
                streaming = true;
                let wire = wire.clone();
                tokio::spawn(async move {
                    let mut tick = tokio::time::interval(Duration::from_millis(10));
                    while !wire.0.is_closed() {
                        tick.tick().await;
                        wire.reply(id::SYSTEM_STATE, Status::Success, &idle);
                    }
                });
            }
            // The first 0x40 after the move started is the client's probe (or, streaming, a
            // re-sent stream command): the final reply comes `delay` after it.
            if probes.load(Ordering::SeqCst) == 1 {
                probes.store(2, Ordering::SeqCst);
                let sent = sent.clone();
                wire.reply_after(delay, id::PRE_POSITION, Status::AxisBlocked, move || {
                    sent.store(true, Ordering::SeqCst)
                });
            }
        }
        _ => wire.reply(f.id, Status::Success, &[]),
    })
    .await;
    (fake, early)
}

/// The client for the recovery tests: moves time out after 300 ms.
async fn recovering_client(fake: &Fake, grace: Duration) -> Client {
    connect(
        builder()
            .query_timeout(Duration::from_secs(5))
            .motion_timeout(Duration::from_millis(300))
            .late_reply_grace(grace),
        fake,
    )
    .await
}

/// Times a first pre-position out (its final reply does not come in time) and returns a
/// patient handle for the next move, which the client holds past the first one's deadline.
async fn time_out_a_move(client: &Client) -> Client {
    let err = guard("first move", client.pre_position(20.0, 50.0))
        .await
        .unwrap_err();
    assert!(
        matches!(
            err,
            Error::Timeout {
                command: id::PRE_POSITION,
                ..
            }
        ),
        "{err}"
    );
    client.with_timeouts(Duration::from_secs(5), Duration::from_secs(10))
}

/// Times the first move out, then starts a second one of the same id and checks that it gets
/// its own reply, sent after the first one's delayed final reply.
async fn second_move_gets_its_own_reply(client: &Client, fake: &Fake, early: &AtomicBool) {
    // Past the first move's deadline: the second waits for the recovery's verdict.
    let patient = time_out_a_move(client).await;
    guard("second move", patient.pre_position(60.0, 50.0))
        .await
        .expect("the second move got the first one's late final reply");
    assert!(
        !early.load(Ordering::SeqCst),
        "the id was released before the first move's final reply"
    );
    assert_eq!(fake.count(id::PRE_POSITION), 2);
}

#[tokio::test]
async fn a_final_reply_delayed_past_the_probe_is_not_taken_for_the_next_move() {
    let (fake, early) = late_final_reply_fake(Duration::from_millis(300), false).await;
    let client = recovering_client(&fake, Duration::from_secs(1)).await;
    second_move_gets_its_own_reply(&client, &fake, &early).await;
}

#[tokio::test]
async fn a_streamed_system_state_during_recovery_does_not_release_the_move() {
    let (fake, early) = late_final_reply_fake(Duration::from_millis(300), true).await;
    let client = recovering_client(&fake, Duration::from_secs(1)).await;
    let mut states = client
        .subscribe_system_state(UpdateOptions::periodic(Duration::from_millis(10)))
        .await
        .unwrap();
    assert!(states.next().await.is_some());
    second_move_gets_its_own_reply(&client, &fake, &early).await;
    // The stream went on meanwhile.
    assert!(states.next().await.is_some());
}

#[tokio::test]
async fn a_move_whose_final_reply_is_lost_frees_its_id_after_two_idle_answers() {
    // The first pre-position's final reply never comes; the device does not move.
    let mut counts = [0; 256];
    let idle = state(SystemState::REFERENCED);
    let fake = Fake::start(move |f, wire| match f.id {
        id::PRE_POSITION => {
            wire.reply(f.id, Status::CmdPending, &[]);
            if nth(&mut counts, f.id) > 1 {
                wire.reply(f.id, Status::Success, &[]);
            }
        }
        id::SYSTEM_STATE => wire.reply(f.id, Status::Success, &idle),
        _ => wire.reply(f.id, Status::Success, &[]),
    })
    .await;
    let client = recovering_client(&fake, Duration::from_millis(200)).await;
    let patient = time_out_a_move(&client).await;
    guard("second move", patient.pre_position(60.0, 50.0))
        .await
        .unwrap();
    assert!(
        fake.count(id::SYSTEM_STATE) >= 2,
        "released on fewer than two probes"
    );
}

#[tokio::test]
async fn a_move_that_still_runs_past_its_deadline_refuses_the_next_one() {
    // The device reports MOVING and never ends the first move: the id stays busy, and each
    // later call of it gets a typed refusal instead of a silent wait.
    let moving = state(SystemState::REFERENCED | SystemState::MOVING);
    let fake = Fake::start(move |f, wire| match f.id {
        id::PRE_POSITION => wire.reply(f.id, Status::CmdPending, &[]),
        id::SYSTEM_STATE => wire.reply(f.id, Status::Success, &moving),
        _ => wire.reply(f.id, Status::Success, &[]),
    })
    .await;
    let client = recovering_client(&fake, Duration::from_millis(200)).await;
    let patient = time_out_a_move(&client).await;
    for _ in 0..2 {
        let err = guard("next move", patient.pre_position(60.0, 50.0))
            .await
            .unwrap_err();
        assert_eq!(err.status(), Some(Status::AlreadyRunning), "{err}");
    }
    assert_eq!(fake.count(id::PRE_POSITION), 1);
}
