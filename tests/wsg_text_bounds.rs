//! The WSG text client's bounds (issue 29 K–O): what no configuration or caller may do to the
//! connection. Each test runs the client against a scripted gripper on loopback TCP (port 0)
//! that answers exactly what the test says, on a paused clock where the test waits on time.

use std::time::Duration;

use gripper::wsg::text::{Client, ClientConfig};
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use tokio::net::{TcpListener, TcpStream};

/// Upper bound for anything that should happen promptly; only reached when a test fails.
const LIMIT: Duration = Duration::from_secs(20);

/// The gripper's side of one connection: reads the client's lines, writes replies.
struct Gripper {
    lines: tokio::io::Lines<BufReader<OwnedReadHalf>>,
    write: OwnedWriteHalf,
}

impl Gripper {
    /// The next line the client wrote (`None` once it closed the connection).
    async fn line(&mut self) -> Option<String> {
        tokio::time::timeout(LIMIT, self.lines.next_line())
            .await
            .expect("the client wrote nothing")
            .unwrap()
    }

    async fn reply(&mut self, line: &str) {
        self.write
            .write_all(format!("{line}\n").as_bytes())
            .await
            .unwrap();
    }
}

/// A client with `config` connected to a scripted gripper.
async fn pair(config: ClientConfig) -> (Client, Gripper) {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let (client, accepted) = tokio::join!(Client::connect_with(addr, config), listener.accept());
    let (stream, _) = accepted.unwrap();
    (client.unwrap(), gripper(stream))
}

fn gripper(stream: TcpStream) -> Gripper {
    let (read, write) = stream.into_split();
    Gripper {
        lines: BufReader::new(read).lines(),
        write,
    }
}

/// Issue 29 O: `queue_len` and `push_buffer` `usize::MAX` (unbounded in practice) are taken as
/// tokio's largest channel, not a panic in its semaphore.
#[tokio::test]
async fn queue_len_and_push_buffer_usize_max_serve_calls() {
    let config = ClientConfig {
        queue_len: usize::MAX,
        push_buffer: usize::MAX,
        ..ClientConfig::default()
    };
    let (client, mut gripper) = pair(config).await;
    let mut pushes = client.pushes();
    let call = tokio::spawn({
        let client = client.clone();
        async move { client.position_mm().await }
    });
    assert_eq!(gripper.line().await.as_deref(), Some("POS?"));
    gripper.reply("@POS=12.5").await;
    gripper.reply("POS=12.5").await;
    assert_eq!(call.await.unwrap().unwrap(), 12.5);
    assert_eq!(pushes.recv().await.unwrap().value, 12.5);
}

/// The next line the client wrote, within `within` (a line that never comes fails the test).
async fn line_within(gripper: &mut Gripper, within: Duration, what: &str) -> String {
    tokio::time::timeout(within, gripper.lines.next_line())
        .await
        .unwrap_or_else(|_| panic!("not written within {within:?}: {what}"))
        .unwrap()
        .expect("the client closed the connection")
}

/// A MOVE acknowledged and running (its FIN not sent), and a second MOVE waiting for the name:
/// with `queue_len` 1 the client's queue is full.
async fn full_queue(client: &Client, gripper: &mut Gripper) -> [tokio::task::JoinHandle<()>; 1] {
    let first = tokio::spawn({
        let client = client.clone();
        async move { client.move_to(10.0, None).await.unwrap() }
    });
    let line = gripper.line().await.unwrap();
    assert!(line.starts_with("MOVE(10"), "{line}");
    gripper.reply("ACK MOVE").await;
    [first]
}

/// A client with `queue_len` whose `MOVE(10)` runs (see [`full_queue`]), a `MOVE(20)` made
/// behind it that waits for the name, and a `POS?` made after that: the calls queued behind a
/// busy name, for the tests below to end in their own ways (a stop, a `BYE()`).
async fn calls_behind_a_busy_move(
    queue_len: usize,
) -> (
    Client,
    Gripper,
    tokio::task::JoinHandle<()>,
    tokio::task::JoinHandle<gripper::wsg::text::Result<()>>,
    tokio::task::JoinHandle<gripper::wsg::text::Result<f64>>,
) {
    let config = ClientConfig {
        queue_len,
        ..ClientConfig::default()
    };
    let (client, mut gripper) = pair(config).await;
    let [first] = full_queue(&client, &mut gripper).await;
    let second = tokio::spawn({
        let client = client.clone();
        async move { client.move_to(20.0, None).await }
    });
    let query = tokio::spawn({
        let client = client.clone();
        async move { client.position_mm().await }
    });
    (client, gripper, first, second, query)
}

/// Issue 29 K: `STOP()` is written at once while the queue is full of calls waiting for a busy
/// name (and the channel holds a call behind them): a stop never waits behind the queue.
#[tokio::test]
async fn stop_is_written_at_once_behind_a_full_queue() {
    let (client, mut gripper, first, second, query) = calls_behind_a_busy_move(1).await;
    let stop = tokio::spawn({
        let client = client.clone();
        async move { client.stop().await }
    });
    let line = line_within(&mut gripper, Duration::from_secs(5), "STOP()").await;
    assert_eq!(line, "STOP()");
    gripper.reply("ACK STOP").await;
    stop.await.unwrap().unwrap();
    // The queue then drains in order as names free.
    gripper.reply("FIN MOVE").await;
    first.await.unwrap();
    let line = gripper.line().await.unwrap();
    assert!(line.starts_with("MOVE(20"), "{line}");
    gripper.reply("ACK MOVE").await;
    gripper.reply("FIN MOVE").await;
    second.await.unwrap().unwrap();
    assert_eq!(gripper.line().await.as_deref(), Some("POS?"));
    gripper.reply("POS=20").await;
    assert_eq!(query.await.unwrap().unwrap(), 20.0);
}

/// Issue 29 K: a call that gave up while waiting for its name leaves the queue when it gives
/// up, not when its name frees: the calls behind it go out meanwhile.
#[tokio::test]
async fn a_call_given_up_leaves_a_full_queue() {
    let config = ClientConfig {
        queue_len: 1,
        ..ClientConfig::default()
    };
    let (client, mut gripper) = pair(config).await;
    let [_first] = full_queue(&client, &mut gripper).await;
    let gave_up = client
        .with_timeout(Duration::from_millis(200))
        .move_to(20.0, None)
        .await;
    assert!(
        matches!(gave_up, Err(gripper::wsg::text::Error::Timeout { .. })),
        "{gave_up:?}"
    );
    let query = tokio::spawn({
        let client = client.clone();
        async move { client.position_mm().await }
    });
    let line = line_within(&mut gripper, Duration::from_secs(5), "POS?").await;
    assert_eq!(line, "POS?");
    gripper.reply("POS=10").await;
    assert_eq!(query.await.unwrap().unwrap(), 10.0);
}

/// The connection's end as the gripper sees it: every line the client writes until it closes
/// the connection (bounded: a connection left open fails the test).
async fn lines_until_closed(gripper: &mut Gripper) -> Vec<String> {
    let mut lines = Vec::new();
    while let Some(line) = gripper.line().await {
        lines.push(line);
    }
    lines
}

/// The end of the tests below whose `close()` ends the session: the client writes nothing more
/// before it closes the connection, and a later call fails `Closed` (within [`LIMIT`]).
async fn closed_with_nothing_more_written(client: &Client, gripper: &mut Gripper) {
    assert_eq!(lines_until_closed(gripper).await, Vec::<String>::new());
    let after = tokio::time::timeout(LIMIT, client.position_mm()).await;
    assert!(
        matches!(after, Ok(Err(gripper::wsg::text::Error::Closed))),
        "{after:?}"
    );
}

/// Issue 29 N: a call waiting for a busy name when `BYE()` goes out is never written, even
/// when a reply frees its name before `ACK BYE`; it fails `Closed`.
#[tokio::test]
async fn nothing_is_written_after_bye() {
    let (client, mut gripper, first, second, query) = calls_behind_a_busy_move(4).await;
    // The query is written once MOVE(20) waits in the task (the channel is read in order).
    assert_eq!(gripper.line().await.as_deref(), Some("POS?"));
    gripper.reply("POS=10").await;
    query.await.unwrap().unwrap();
    let close = tokio::spawn({
        let client = client.clone();
        async move { client.close().await }
    });
    assert_eq!(gripper.line().await.as_deref(), Some("BYE()"));
    gripper.reply("FIN MOVE").await;
    first.await.unwrap();
    let waited = second.await.unwrap();
    assert!(
        matches!(waited, Err(gripper::wsg::text::Error::Closed)),
        "{waited:?}"
    );
    gripper.reply("ACK BYE").await;
    close.await.unwrap().unwrap();
    assert_eq!(lines_until_closed(&mut gripper).await, Vec::<String>::new());
}

/// Issue 29 N: `BYE()` refused (`ERR BYE …`): `close()` returns the refusal, and the
/// connection is closed all the same: a later call fails `Closed` at once.
#[tokio::test]
async fn bye_refused_still_closes() {
    let (client, mut gripper) = pair(ClientConfig::default()).await;
    let close = tokio::spawn({
        let client = client.clone();
        async move { client.close().await }
    });
    assert_eq!(gripper.line().await.as_deref(), Some("BYE()"));
    gripper.reply("ERR BYE 2").await;
    let refused = close.await.unwrap();
    assert!(
        matches!(refused, Err(gripper::wsg::text::Error::Device { .. })),
        "{refused:?}"
    );
    closed_with_nothing_more_written(&client, &mut gripper).await;
}

/// Issue 29 N: `BYE()` unanswered: `close()` times out, and the connection is closed then: a
/// later call fails `Closed`, not `Timeout`.
#[tokio::test]
async fn bye_unanswered_closes_when_close_times_out() {
    let (client, mut gripper) = pair(ClientConfig::default()).await;
    let impatient = client.with_timeout(Duration::from_millis(200));
    let (closed, line) = tokio::join!(impatient.close(), gripper.line());
    assert_eq!(line.as_deref(), Some("BYE()"));
    assert!(
        matches!(closed, Err(gripper::wsg::text::Error::Timeout { .. })),
        "{closed:?}"
    );
    let after = client.position_mm().await;
    assert!(
        matches!(after, Err(gripper::wsg::text::Error::Closed)),
        "{after:?}"
    );
    assert_eq!(lines_until_closed(&mut gripper).await, Vec::<String>::new());
}

/// A call without timeout whose reply arrived damaged still ends (within [`LIMIT`]: a hang
/// fails the test, naming `what`), and it fails `MalformedReply`.
async fn ends_malformed<T: std::fmt::Debug>(
    what: &str,
    call: tokio::task::JoinHandle<gripper::wsg::text::Result<T>>,
) {
    let ended = tokio::time::timeout(LIMIT, call)
        .await
        .unwrap_or_else(|_| panic!("{what} never ended"));
    assert!(
        matches!(
            ended,
            Ok(Err(gripper::wsg::text::Error::MalformedReply { .. }))
        ),
        "{ended:?}"
    );
}

/// A client's `VERBOSE=0` without timeout, written to a scripted gripper (not answered yet):
/// the handle without timeout, the gripper, the call.
async fn verbose_without_timeout() -> (
    Client,
    Gripper,
    tokio::task::JoinHandle<gripper::wsg::text::Result<bool>>,
) {
    let (client, mut gripper) = pair(ClientConfig::default()).await;
    let forever = client.with_timeout(Duration::MAX);
    let call = tokio::spawn({
        let forever = forever.clone();
        async move { forever.set_verbose(false).await }
    });
    assert_eq!(gripper.line().await.as_deref(), Some("VERBOSE=0"));
    (forever, gripper, call)
}

/// `VERBOSE` is free again after its call ended: the next one is written and answered.
async fn verbose_is_free_again(forever: Client, gripper: &mut Gripper) {
    let again = tokio::spawn(async move { forever.set_verbose(true).await });
    assert_eq!(gripper.line().await.as_deref(), Some("VERBOSE=1"));
    gripper.reply("VERBOSE=1").await;
    assert!(again.await.unwrap().unwrap());
}

/// The client's own `GRIPSTATE?`, written no sooner than `after` from now (the 10 s doubt of a
/// call without timeout, issue 29 M), answered: no motion.
async fn asked_after(gripper: &mut Gripper, after: Duration) {
    let asked = tokio::time::Instant::now();
    assert_eq!(gripper.line().await.as_deref(), Some("GRIPSTATE?"));
    assert!(asked.elapsed() >= after, "{:?}", asked.elapsed());
    gripper.reply("GRIPSTATE=0").await;
}

/// Issue 29 M: a call without timeout whose reply arrives damaged (here `damaged`) ends: the
/// client probes with a query, and once a reply written after the damaged line arrives, the
/// call fails `MalformedReply` and its name is free for the next call.
async fn damaged_reply_of_a_call_without_timeout(damaged: &str) {
    let (forever, mut gripper, call) = verbose_without_timeout().await;
    gripper.reply(damaged).await;
    assert_eq!(gripper.line().await.as_deref(), Some("GRIPSTATE?"));
    gripper.reply("GRIPSTATE=0").await;
    ends_malformed("the call", call).await;
    verbose_is_free_again(forever, &mut gripper).await;
}

#[tokio::test]
async fn call_without_timeout_ends_when_its_reply_is_err_without_a_name() {
    damaged_reply_of_a_call_without_timeout("ERR 2").await;
}

#[tokio::test]
async fn call_without_timeout_ends_when_its_reply_is_malformed() {
    damaged_reply_of_a_call_without_timeout("VERBOSE 0").await;
}

#[tokio::test]
async fn call_without_timeout_ends_when_its_reply_names_another_command() {
    damaged_reply_of_a_call_without_timeout("VERBOSF=0").await;
}

/// Issue 29 M: a call without timeout whose request the gripper never answered (its LF
/// damaged on the way, the gripper holds a fragment and writes nothing:
/// `wsg-text:0xfa9c7f60b0e57de1`) waited for ever and held its name. A reply due at once that
/// stays away 10 s is doubted: the client probes, and the probe's answer, which comes after
/// any reply due before it (replies come in order), ends the call `MalformedReply` and frees
/// the name.
#[tokio::test(start_paused = true)]
async fn call_without_timeout_ends_when_its_request_was_never_answered() {
    let (forever, mut gripper, call) = verbose_without_timeout().await;
    // Nothing answers it; the client asks after 10 s.
    asked_after(&mut gripper, Duration::from_secs(10)).await;
    ends_malformed("the call", call).await;
    verbose_is_free_again(forever, &mut gripper).await;
}

/// Issue 29 M for motions: a motion without timeout whose `FIN` arrived damaged (here
/// `FIN HOMX`) held its call and its name for ever: it had no give-up time, so it was never
/// checked (`wsg-text:0x6616913488a6a29b`, its `ERR` lost). 10 s after its `ACK` the client
/// asks `GRIPSTATE?`; the gripper reports no motion, so the unreadable line was its end: the
/// call fails `MalformedReply` and `HOME` is free again.
#[tokio::test(start_paused = true)]
async fn motion_without_timeout_ends_when_its_fin_was_damaged() {
    let (client, mut gripper) = pair(ClientConfig::default()).await;
    let forever = client.with_timeout(Duration::MAX);
    let call = tokio::spawn({
        let forever = forever.clone();
        async move { forever.home(gripper::wsg::HomingDirection::Default).await }
    });
    assert_eq!(gripper.line().await.as_deref(), Some("HOME()"));
    gripper.reply("ACK HOME").await;
    gripper.reply("FIN HOMX").await;
    asked_after(&mut gripper, Duration::from_secs(9)).await;
    ends_malformed("the HOME", call).await;
    let again =
        tokio::spawn(async move { forever.home(gripper::wsg::HomingDirection::Default).await });
    assert_eq!(gripper.line().await.as_deref(), Some("HOME()"));
    gripper.reply("ACK HOME").await;
    gripper.reply("FIN HOME").await;
    again.await.unwrap().unwrap();
}

/// Issue 29 M for motions: a motion without timeout that nothing answered (its request never
/// read by the gripper, so no line came in its place) is doubted after 10 s; the probe's answer
/// shows its first reply lost, and once the gripper reports no motion it ends, without any
/// damaged line read (`wsg-text:0x66c3c8e7252d7f83`, where it was asked every 10 s for ever).
#[tokio::test(start_paused = true)]
async fn motion_without_timeout_that_nothing_answered_ends_when_reported_over() {
    let (client, mut gripper) = pair(ClientConfig::default()).await;
    let forever = client.with_timeout(Duration::MAX);
    let call =
        tokio::spawn(async move { forever.home(gripper::wsg::HomingDirection::Default).await });
    assert_eq!(gripper.line().await.as_deref(), Some("HOME()"));
    // The probe of its missing first reply, then the check of the motion.
    asked_after(&mut gripper, Duration::from_secs(10)).await;
    asked_after(&mut gripper, Duration::from_secs(10)).await;
    ends_malformed("the HOME", call).await;
}

/// A client (`give_up_after` 200 ms) whose `MOVE(10)` with a 100 ms timeout was acknowledged
/// (then answered `after_ack`) and timed out; returned once, past its timeout +
/// `give_up_after`, the client asked `GRIPSTATE?` (issue 29 L).
async fn overdue_move(after_ack: &[&str]) -> (Client, Gripper) {
    let config = ClientConfig {
        give_up_after: Duration::from_millis(200),
        ..ClientConfig::default()
    };
    let (client, mut gripper) = pair(config).await;
    let slow = client.with_timeout(Duration::from_millis(100));
    let (moved, line) = tokio::join!(slow.move_to(10.0, None), async {
        let line = gripper.line().await.unwrap();
        gripper.reply("ACK MOVE").await;
        for reply in after_ack {
            gripper.reply(reply).await;
        }
        line
    });
    assert!(line.starts_with("MOVE(10"), "{line}");
    assert!(
        matches!(moved, Err(gripper::wsg::text::Error::Timeout { .. })),
        "{moved:?}"
    );
    let line = line_within(&mut gripper, Duration::from_secs(5), "GRIPSTATE?").await;
    assert_eq!(line, "GRIPSTATE?");
    (client, gripper)
}

/// The connection is up and `MOVE` free after an overdue `MOVE` ended: a `MOVE(20)` is written
/// within `within` and served.
async fn move_is_free_again(client: &Client, gripper: &mut Gripper, within: Duration) {
    let again = tokio::spawn({
        let client = client.clone();
        async move { client.move_to(20.0, None).await }
    });
    let line = line_within(gripper, within, "MOVE(20)").await;
    assert!(line.starts_with("MOVE(20"), "{line}");
    gripper.reply("ACK MOVE").await;
    gripper.reply("FIN MOVE").await;
    again.await.unwrap().unwrap();
}

/// The gripper answers the client's `GRIPSTATE?` check of an overdue `MOVE`: no motion
/// (`GRIPSTATE=0`). The `MOVE` ends and the connection stays: `MOVE` is free again.
async fn reported_over_the_motion_ends(client: &Client, gripper: &mut Gripper) {
    gripper.reply("GRIPSTATE=0").await;
    move_is_free_again(client, gripper, Duration::from_secs(5)).await;
}

/// Issue 29 L: an acknowledged motion whose `FIN` comes later than its timeout +
/// `give_up_after` is checked with `GRIPSTATE?`, not given up on time alone: while the gripper
/// reports it running, the connection stays, and its late `FIN` is consumed when it comes.
#[tokio::test]
async fn a_slow_acknowledged_motion_is_checked_not_given_up() {
    let (client, mut gripper) = overdue_move(&[]).await;
    // The motion still runs (6: positioning).
    gripper.reply("GRIPSTATE=6").await;
    // Asked again later, still running; then the FIN comes.
    let line = line_within(&mut gripper, Duration::from_secs(5), "GRIPSTATE?").await;
    assert_eq!(line, "GRIPSTATE?");
    gripper.reply("GRIPSTATE=6").await;
    gripper.reply("FIN MOVE").await;
    // The connection is up and MOVE is free (the line within `Gripper::line`'s bound).
    move_is_free_again(&client, &mut gripper, LIMIT).await;
}

/// Issue 29 L: a motion the gripper reports over whose `FIN` still does not come gets the
/// connection given up (for cause: a later `FIN` could no longer be paired). With no `FIN`
/// before the report and nothing unreadable since the `ACK`, the first report goes against the
/// order the gripper answers in (it may be a damaged value): the client asks once more, and
/// the second report counts.
#[tokio::test]
async fn a_motion_reported_over_without_its_fin_gives_the_connection_up() {
    let (client, mut gripper) = overdue_move(&[]).await;
    gripper.reply("GRIPSTATE=0").await;
    let again = line_within(&mut gripper, Duration::from_secs(5), "GRIPSTATE?").await;
    assert_eq!(again, "GRIPSTATE?");
    gripper.reply("GRIPSTATE=0").await;
    assert_eq!(lines_until_closed(&mut gripper).await, Vec::<String>::new());
    let after = client.position_mm().await;
    assert!(
        matches!(after, Err(gripper::wsg::text::Error::ConnectionLost { .. })),
        "{after:?}"
    );
}

/// Issue 29 M for motions, found through L's check: an acknowledged motion whose `FIN` arrived
/// damaged ends once the gripper reports it over, and its name is free; the connection stays.
#[tokio::test]
async fn a_motion_whose_fin_was_damaged_ends_when_reported_over() {
    let (client, mut gripper) = overdue_move(&["FIN MOVX"]).await;
    reported_over_the_motion_ends(&client, &mut gripper).await;
}

/// The hang of issue 29 M's residual (`wsg-text:0x3bac8274f6da31e9`): `close()` without
/// timeout whose `ACK BYE` arrives damaged (`@CK BYE`). Nothing is written after `BYE()`, so
/// no later reply could tell; the damaged line came where `ACK BYE` was due: `close()` fails
/// `MalformedReply` and the connection is closed (a later call fails `Closed`).
#[tokio::test]
async fn close_without_timeout_ends_when_ack_bye_is_damaged() {
    let (client, mut gripper) = pair(ClientConfig::default()).await;
    let forever = client.with_timeout(Duration::MAX);
    let close = tokio::spawn(async move { forever.close().await });
    assert_eq!(gripper.line().await.as_deref(), Some("BYE()"));
    gripper.reply("@CK BYE").await;
    ends_malformed("close()", close).await;
    closed_with_nothing_more_written(&client, &mut gripper).await;
}

/// The bound above is not eager: with a query written before `BYE()` still unanswered, its
/// reply and `ACK BYE` are both due, so one damaged line may have been the query's and
/// `ACK BYE` may still come: `close()` waits for it (then the query fails `Closed`, as every
/// call still on the wire when the session ends).
#[tokio::test]
async fn close_without_timeout_waits_for_every_reply_due_before_it() {
    let (client, mut gripper) = pair(ClientConfig::default()).await;
    let forever = client.with_timeout(Duration::MAX);
    let query = tokio::spawn({
        let forever = forever.clone();
        async move { forever.position_mm().await }
    });
    assert_eq!(gripper.line().await.as_deref(), Some("POS?"));
    let close = tokio::spawn(async move { forever.close().await });
    assert_eq!(gripper.line().await.as_deref(), Some("BYE()"));
    gripper.reply("P0S=1").await;
    // Still open: the next line is the gripper's to read.
    gripper.reply("ACK BYE").await;
    let closed = tokio::time::timeout(LIMIT, close).await.expect("close()");
    assert!(matches!(closed, Ok(Ok(()))), "{closed:?}");
    let failed = query.await.unwrap();
    assert!(
        matches!(failed, Err(gripper::wsg::text::Error::Closed)),
        "{failed:?}"
    );
    assert_eq!(lines_until_closed(&mut gripper).await, Vec::<String>::new());
}

/// `close()` without timeout given up by its caller (its future dropped) before `ACK BYE`:
/// nobody waits for the reply and nothing more is written, so the connection is closed then,
/// not held open for ever (the explorer's bound on a `close()` without timeout drops it so).
#[tokio::test]
async fn close_without_timeout_given_up_closes_the_connection() {
    let (client, mut gripper) = pair(ClientConfig::default()).await;
    let forever = client.with_timeout(Duration::MAX);
    let close = tokio::spawn(async move { forever.close().await });
    assert_eq!(gripper.line().await.as_deref(), Some("BYE()"));
    close.abort();
    let _ = close.await;
    closed_with_nothing_more_written(&client, &mut gripper).await;
}

/// Polls `future` once (it must not be ready yet): a call made then is in the client's channel.
async fn poll_once<F: std::future::Future + Unpin>(future: &mut F)
where
    F::Output: std::fmt::Debug,
{
    let polled = std::future::poll_fn(|cx| {
        std::task::Poll::Ready(std::future::Future::poll(
            std::pin::Pin::new(&mut *future),
            cx,
        ))
    })
    .await;
    assert!(polled.is_pending(), "{polled:?}");
}

/// Issue 29, rule 7 (`wsg-text:0xe5281323574dafa8`): a program's query made before the client
/// wrote its own probe of that query (here M's `GRIPSTATE?` after a damaged reply), and read
/// by the task only after it, takes the probe's answer: the gripper read that very line after
/// the call was made. Before, the call waited for the probe's answer, then wrote its line again
/// and could time out although the answer had come in time.
#[tokio::test]
async fn a_query_made_before_the_clients_own_probe_takes_its_answer() {
    let config = ClientConfig {
        queue_len: 2,
        query_timeout: Duration::from_secs(30),
        ..ClientConfig::default()
    };
    let (client, mut gripper) = pair(config).await;
    let first = tokio::spawn({
        let client = client.clone();
        async move { client.set_verbose(false).await }
    });
    assert_eq!(gripper.line().await.as_deref(), Some("VERBOSE=0"));
    // VERBOSE is busy: this one waits in the task (one of the two it holds, queue_len 2)...
    let second = tokio::spawn({
        let client = client.clone();
        async move { client.set_verbose(true).await }
    });
    // ...read before this one (one channel, in order), which shows it.
    let temp = tokio::spawn({
        let client = client.clone();
        async move { client.temperature_c().await }
    });
    assert_eq!(gripper.line().await.as_deref(), Some("TEMP?"));
    gripper.reply("TEMP=20").await;
    assert_eq!(temp.await.unwrap().unwrap(), 20.0);
    // A third VERBOSE call fills the task's waiting calls, and the query, made after it, stays
    // in the channel until one of them leaves.
    let mut third = Box::pin(client.set_verbose(false));
    poll_once(&mut third).await;
    let mut query = Box::pin(client.grip_state());
    poll_once(&mut query).await;
    // VERBOSE=0's reply damaged: the client probes with GRIPSTATE? (issue 29 M).
    gripper.reply("VERBOSX=0").await;
    assert_eq!(gripper.line().await.as_deref(), Some("GRIPSTATE?"));
    gripper.reply("GRIPSTATE=4").await;
    assert!(first.await.unwrap().is_err());
    // VERBOSE is free: the waiting call goes out; the query is answered by the probe's answer,
    // not written again.
    assert_eq!(gripper.line().await.as_deref(), Some("VERBOSE=1"));
    let state = tokio::time::timeout(LIMIT, query).await.expect("the query");
    assert_eq!(state.unwrap(), gripper::wsg::GripState::Holding);
    gripper.reply("VERBOSE=1").await;
    assert!(second.await.unwrap().unwrap());
    assert_eq!(gripper.line().await.as_deref(), Some("VERBOSE=0"));
    gripper.reply("VERBOSE=0").await;
    assert!(!third.await.unwrap());
    let pos = tokio::spawn({
        let client = client.clone();
        async move { client.position_mm().await }
    });
    assert_eq!(gripper.line().await.as_deref(), Some("POS?"));
    gripper.reply("POS=10").await;
    assert_eq!(pos.await.unwrap().unwrap(), 10.0);
}

/// A client (`give_up_after` 200 ms) with `MOVE(10)` (100 ms timeout) and `TEMP?` on the wire,
/// its gripper's side, and the `MOVE` call.
async fn move_and_query() -> (
    Client,
    Gripper,
    tokio::task::JoinHandle<gripper::wsg::text::Result<()>>,
    tokio::task::JoinHandle<gripper::wsg::text::Result<f64>>,
) {
    let config = ClientConfig {
        give_up_after: Duration::from_millis(200),
        ..ClientConfig::default()
    };
    let (client, mut gripper) = pair(config).await;
    let motion = tokio::spawn({
        let slow = client.with_timeout(Duration::from_millis(100));
        async move { slow.move_to(10.0, None).await }
    });
    let line = gripper.line().await.unwrap();
    assert!(line.starts_with("MOVE(10"), "{line}");
    let temp = tokio::spawn({
        let client = client.clone();
        async move { client.temperature_c().await }
    });
    assert_eq!(gripper.line().await.as_deref(), Some("TEMP?"));
    (client, gripper, motion, temp)
}

/// The rest of the tests below: the overdue `MOVE` is checked with `GRIPSTATE?`, ends once
/// the gripper reports no motion, and the connection stays: `MOVE` is free again.
async fn overdue_motion_ends_and_the_connection_stays(client: &Client, gripper: &mut Gripper) {
    let line = line_within(gripper, Duration::from_secs(5), "GRIPSTATE?").await;
    assert_eq!(line, "GRIPSTATE?");
    reported_over_the_motion_ends(client, gripper).await;
}

/// The rest of the tests below whose `MOVE(10)` timed out: its call fails `Timeout`, and then
/// the motion ends as [`overdue_motion_ends_and_the_connection_stays`] checks.
async fn the_move_timed_out_and_ends(
    client: &Client,
    gripper: &mut Gripper,
    motion: tokio::task::JoinHandle<gripper::wsg::text::Result<()>>,
) {
    let moved = motion.await.unwrap();
    assert!(
        matches!(moved, Err(gripper::wsg::text::Error::Timeout { .. })),
        "{moved:?}"
    );
    overdue_motion_ends_and_the_connection_stays(client, gripper).await;
}

/// The rest of the tests below where one damaged line held `TEMP?`'s reply and the `MOVE`'s
/// `FIN`: `TEMP?` fails `MalformedReply`, and the `MOVE` times out and then ends (above).
async fn the_query_fails_malformed_and_the_move_ends(
    client: &Client,
    gripper: &mut Gripper,
    motion: tokio::task::JoinHandle<gripper::wsg::text::Result<()>>,
    temp: tokio::task::JoinHandle<gripper::wsg::text::Result<f64>>,
) {
    let temp = temp.await.unwrap();
    assert!(
        matches!(temp, Err(gripper::wsg::text::Error::MalformedReply { .. })),
        "{temp:?}"
    );
    the_move_timed_out_and_ends(client, gripper, motion).await;
}

/// Issue 29 L (`wsg-text:0xaa891d063fc824a5` and its two siblings): two replies run together by
/// a damaged LF (0x0A read as 0x08) are one line that is neither. It was taken for the first
/// reply (`TEMP=20…`) and swallowed `FIN MOVE` unseen: the acknowledged `MOVE`, reported over
/// without its `FIN` and no damaged line counted, got the connection given up. Now the line
/// counts as damaged: `TEMP?` fails once a later reply shows its reply lost, and the `MOVE`
/// ends when the gripper reports it over.
#[tokio::test]
async fn two_replies_run_together_by_a_damaged_lf_count_as_damaged() {
    let (client, mut gripper, motion, temp) = move_and_query().await;
    gripper.reply("ACK MOVE").await;
    gripper.reply("TEMP=20\u{8}FIN MOVE").await;
    // Issue 29 M's probe, written after the damaged line.
    assert_eq!(gripper.line().await.as_deref(), Some("GRIPSTATE?"));
    gripper.reply("GRIPSTATE=6").await;
    the_query_fails_malformed_and_the_move_ends(&client, &mut gripper, motion, temp).await;
}

/// The same, when the character the LF became leaves a line that still parses as the query's
/// reply: `TEMP=20JFIN MOVE` (0x0A read as 0x4A) is `TEMP`'s value `20JFIN MOVE`, paired with
/// `TEMP?`, and `FIN MOVE` was swallowed in it (`wsg-text:0x837af21cd1f4f6c7`, `GRIPSTATE=6JFIN
/// MOVE`). Every value the client asks for is a number, so a value that is none counts as a
/// damaged line: the caller gets `MalformedReply`, and the `MOVE`, reported over when checked,
/// ends instead of the connection being given up.
#[tokio::test]
async fn a_value_that_is_no_number_counts_as_a_damaged_line() {
    let (client, mut gripper, motion, temp) = move_and_query().await;
    gripper.reply("ACK MOVE").await;
    gripper.reply("TEMP=20JFIN MOVE").await;
    the_query_fails_malformed_and_the_move_ends(&client, &mut gripper, motion, temp).await;
}

/// The same with a push: `@POS=12.5JERR MOVE 19` (the push's LF read as 0x4A) is a push whose
/// value `12.5JERR MOVE 19` is no number, and `ERR MOVE 19` was swallowed in it
/// (`wsg-text:0xaead2f1fc4928e38`, `@POS=104.7JERR HOME 19`). It was dropped as a push not
/// understood, not counted as damaged: the acknowledged motion, reported over when checked,
/// waited for a `FIN` that never came and the connection was given up. Every pushed value is a
/// number (shared note §3.10), so one that is none counts as a damaged line: the motion ends
/// when reported over and the connection stays.
#[tokio::test]
async fn a_push_whose_value_is_no_number_counts_as_a_damaged_line() {
    let (client, mut gripper) = overdue_move(&["@POS=12.5JERR MOVE 19"]).await;
    reported_over_the_motion_ends(&client, &mut gripper).await;
}

/// Issue 29 L with M: a motion whose first reply (`ACK` or `ERR`) arrived damaged, shown lost
/// by a later reply (the probe's), is taken as acknowledged: once overdue it is checked with
/// `GRIPSTATE?` and ends when the gripper reports no motion. Before, it stayed unacknowledged
/// and its give-up time gave the connection up.
#[tokio::test]
async fn a_motion_whose_first_reply_was_damaged_is_checked_not_given_up() {
    let (client, mut gripper, motion, temp) = move_and_query().await;
    gripper.reply("ERR MOVF 4").await;
    gripper.reply("TEMP=20").await;
    assert_eq!(temp.await.unwrap().unwrap(), 20.0);
    assert_eq!(gripper.line().await.as_deref(), Some("GRIPSTATE?"));
    gripper.reply("GRIPSTATE=0").await;
    the_move_timed_out_and_ends(&client, &mut gripper, motion).await;
}

/// An overdue acknowledged motion on a client whose `query_timeout` is `Duration::MAX`: its
/// `GRIPSTATE?` check is the client's own query, bounded all the same. Here that check's
/// request arrives damaged (answered `ERR GRIPSTATM 14`) and fails once a later reply shows it
/// (issue 29 M); the motion is checked again, and ends when reported over. Before, the
/// recheck was due at `query_timeout` + …, never: the motion held its name for good
/// (`wsg-text:0xfa9c7f60b0e57de1`). On a paused clock, over an in-memory stream.
#[tokio::test(start_paused = true)]
async fn an_overdue_motion_is_checked_again_without_a_query_timeout() {
    use tokio::io::AsyncBufReadExt as _;
    let config = ClientConfig {
        query_timeout: Duration::MAX,
        give_up_after: Duration::from_millis(200),
        ..ClientConfig::default()
    };
    let (near, far) = tokio::io::duplex(4096);
    let client = Client::from_io(near, config);
    let (read, mut write) = tokio::io::split(far);
    let mut lines = tokio::io::BufReader::new(read).lines();
    let mut reply = async |line: &str| {
        write
            .write_all(format!("{line}\n").as_bytes())
            .await
            .unwrap()
    };
    let motion = tokio::spawn({
        let slow = client.with_timeout(Duration::from_millis(100));
        async move { slow.move_to(10.0, None).await }
    });
    let line = lines.next_line().await.unwrap().unwrap();
    assert!(line.starts_with("MOVE(10"), "{line}");
    reply("ACK MOVE").await;
    assert!(matches!(
        motion.await.unwrap(),
        Err(gripper::wsg::text::Error::Timeout { .. })
    ));
    assert_eq!(
        lines.next_line().await.unwrap().as_deref(),
        Some("GRIPSTATE?")
    );
    reply("ERR GRIPSTATM 14").await;
    // M's probe after the damaged line; its answer shows the check's reply lost.
    assert_eq!(lines.next_line().await.unwrap().as_deref(), Some("POS?"));
    reply("POS=50").await;
    let again = tokio::time::timeout(Duration::from_secs(60), lines.next_line())
        .await
        .expect("the motion was never checked again");
    assert_eq!(again.unwrap().as_deref(), Some("GRIPSTATE?"));
    reply("GRIPSTATE=0").await;
    // Reported over with a damaged line after its ACK: the motion ended, MOVE is free.
    let next = tokio::spawn({
        let client = client.with_timeout(Duration::from_secs(5));
        async move { client.move_to(20.0, None).await }
    });
    let line = lines.next_line().await.unwrap().unwrap();
    assert!(line.starts_with("MOVE(20"), "{line}");
    reply("ACK MOVE").await;
    reply("FIN MOVE").await;
    next.await.unwrap().unwrap();
}

/// Issue 29 M for `close()`: a `BYE()` without timeout that nothing answers (its request
/// damaged on the way, so the gripper read no line, `wsg-text:0x7af44aab63b7c9f1`) waited for
/// ever: nothing may be written after `BYE()`, so no probe could draw an answer. It waits 10 s,
/// then fails `Timeout` with that bound, and the connection is closed (a later call: `Closed`).
#[tokio::test(start_paused = true)]
async fn close_without_timeout_that_nothing_answers_ends_after_ten_seconds() {
    let (client, mut gripper) = pair(ClientConfig::default()).await;
    let forever = client.with_timeout(Duration::MAX);
    let start = tokio::time::Instant::now();
    let close = tokio::spawn(async move { forever.close().await });
    assert_eq!(gripper.line().await.as_deref(), Some("BYE()"));
    let ended = close.await.unwrap();
    assert!(
        matches!(
            ended,
            Err(gripper::wsg::text::Error::Timeout { timeout, .. }) if timeout == Duration::from_secs(10)
        ),
        "{ended:?}"
    );
    assert_eq!(start.elapsed(), Duration::from_secs(10));
    assert_eq!(lines_until_closed(&mut gripper).await, Vec::<String>::new());
    let after = client.position_mm().await;
    assert!(
        matches!(after, Err(gripper::wsg::text::Error::Closed)),
        "{after:?}"
    );
}

/// `wsg-text:0x4a805d181f1854b8` (issue 29 M): every name a probe could use (`GRIPSTATE?`,
/// `POS?`, `SPEED?`) was on the wire unanswered (one line run into the next by a damaged LF,
/// one swallowed by it), and `give_up_after` was `Duration::MAX`: no probe could be written,
/// nothing settled them, and a `MOVE` without timeout waited for its name for ever. A fourth
/// name, `FORCE?` (answered at once in every state, shared note), draws the reply that shows
/// theirs lost, and their names are free again.
#[tokio::test(start_paused = true)]
async fn a_probe_goes_out_when_the_other_probe_names_wait_unanswered() {
    let config = ClientConfig {
        give_up_after: Duration::MAX,
        ..ClientConfig::default()
    };
    let (client, mut gripper) = pair(config).await;
    let short = client.with_timeout(Duration::from_millis(100));
    let (state, pos, speed) = tokio::join!(
        short.grip_state(),
        short.position_mm(),
        short.speed_mm_per_s(),
    );
    for (what, result) in [
        ("GRIPSTATE?", state.map(|_| ())),
        ("POS?", pos.map(|_| ())),
        ("SPEED?", speed.map(|_| ())),
    ] {
        assert!(
            matches!(result, Err(gripper::wsg::text::Error::Timeout { .. })),
            "{what}: {result:?}"
        );
    }
    let mut written = Vec::new();
    for _ in 0..3 {
        written.push(gripper.line().await.unwrap());
    }
    written.sort();
    assert_eq!(written, ["GRIPSTATE?", "POS?", "SPEED?"]);
    // Nothing answered: after the doubt time the client asks, on the one name left.
    assert_eq!(gripper.line().await.as_deref(), Some("FORCE?"));
    gripper.reply("FORCE=0.0").await;
    let pos = tokio::spawn({
        let client = client.clone();
        async move { client.position_mm().await }
    });
    assert_eq!(gripper.line().await.as_deref(), Some("POS?"));
    gripper.reply("POS=12.0").await;
    assert_eq!(pos.await.unwrap().unwrap(), 12.0);
}
