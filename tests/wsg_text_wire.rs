//! The GCL client on a hostile wire: a scripted fake gripper that answers out of order, sends
//! lines for nobody, malformed, over-long and cut-off lines; the real text simulator behind the
//! fault proxy (split, merged, duplicated, dropped and corrupted lines, a pulled cable); and a
//! property test of the reply parser. The rule in every case: the right answer or a typed
//! error, never another command's answer, never a hang past the call's timeout.
#![cfg(feature = "sim")]

use std::future::Future;
use std::time::Duration;

use gripper::fault::{Fault, FaultProxy, Framing, ProxyConfig};
use gripper::wsg::sim::{Model, SimConfig, SimServer};
use gripper::wsg::text::line::{parse_reply, ReplyLine};
use gripper::wsg::text::{Client, ClientConfig, Error};
use gripper::wsg::{HomingDirection, Status};
use proptest::prelude::*;
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::tcp::OwnedWriteHalf;
use tokio::net::TcpListener;

const LIMIT: Duration = Duration::from_secs(20);

async fn within<F: Future>(what: &str, future: F) -> F::Output {
    tokio::time::timeout(LIMIT, future)
        .await
        .unwrap_or_else(|_| panic!("hung: {what}"))
}

/// A fake gripper: the test reads the client's lines and writes whatever it likes.
struct Fake {
    lines: tokio::io::Lines<BufReader<tokio::net::tcp::OwnedReadHalf>>,
    write: OwnedWriteHalf,
}

impl Fake {
    async fn pair(config: ClientConfig) -> (Client, Fake) {
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let (client, accepted) =
            tokio::join!(Client::connect_with(addr, config), listener.accept());
        let (read, write) = accepted.unwrap().0.into_split();
        let fake = Fake {
            lines: BufReader::new(read).lines(),
            write,
        };
        (client.unwrap(), fake)
    }

    async fn read(&mut self) -> String {
        within("a command line", self.lines.next_line())
            .await
            .unwrap()
            .expect("the client closed")
    }

    async fn say(&mut self, bytes: &str) {
        self.write.write_all(bytes.as_bytes()).await.unwrap();
    }
}

/// Runs `call` on a clone of `g` in a task of its own.
fn spawn<T, F>(g: &Client, call: impl FnOnce(Client) -> F) -> tokio::task::JoinHandle<T>
where
    F: Future<Output = T> + Send + 'static,
    T: Send + 'static,
{
    tokio::spawn(call(g.clone()))
}

#[tokio::test]
async fn replies_are_paired_by_name_whatever_their_order() {
    let (g, mut fake) = Fake::pair(ClientConfig::default()).await;
    let mover = spawn(&g, |g| async move { g.move_to(20.0, Some(50.0)).await });
    assert_eq!(fake.read().await, "MOVE(20,50)");
    fake.say("ACK MOVE\n").await;
    let pos = spawn(&g, |g| async move { g.position_mm().await });
    assert_eq!(fake.read().await, "POS?");
    // Lines for nobody, a push nobody asked for, and lines that are not GCL come first.
    fake.say(
        "FIN HOME\nERR 4\n@POS=3.0\nhello\nACK\nERR GRIP 18\nSPEED=1.0\n\r\n\
         POS=12.5\n",
    )
    .await;
    assert_eq!(within("POS?", pos).await.unwrap().unwrap(), 12.5);
    assert!(!mover.is_finished(), "MOVE ended by another command's line");
    // Lower-case names are the same command.
    fake.say("fin move\n").await;
    within("MOVE", mover).await.unwrap().unwrap();
}

/// A motion's `FIN` comes after its `ACK`: a `FIN GRIP` before this GRIP's `ACK`, with nothing
/// unreadable between, is an earlier GRIP's (the explorer's `wsg-text:0xa1fd31cdef49e64e`:
/// after a damaged `GRIPSTATE?` answered `ERR GRIP 15` was taken by a GRIP, GRIP's replies ran
/// one behind, and an old `FIN GRIP` reported a GRIP done that the gripper had only read). The
/// call ends with its own reply.
#[tokio::test]
async fn a_fin_before_its_motions_ack_is_not_its_end() {
    let (g, mut fake) = Fake::pair(ClientConfig::default()).await;
    let grip = spawn(&g, |g| async move { g.grip(Some(20.0)).await });
    assert_eq!(fake.read().await, "GRIP(20)");
    fake.say(
        "FIN GRIP
ACK GRIP
ERR GRIP 19 E_CMD_ABORTED
",
    )
    .await;
    let end = within("GRIP", grip).await.unwrap();
    assert!(
        matches!(&end, Err(Error::Device { line, .. }) if line.starts_with("ERR GRIP 19")),
        "{end:?}"
    );
}

/// An LF flipped to `*` runs `ACK HOME` into the free text of GRIP's `ERR` line. Taken for
/// GRIP's `ERR`, the line swallowed HOME's `ACK` unseen, and HOME's `FIN` then came with no
/// `ACK` before it (the explorer's `wsg-text:0xea94665dbf03df00`). Such a line is one that could
/// not be read: HOME's `FIN` after it ends HOME.
#[tokio::test]
async fn an_ack_run_into_an_err_line_is_damage_not_swallowed() {
    let (g, mut fake) = Fake::pair(ClientConfig::default()).await;
    let grip = spawn(&g, |g| async move { g.grip(Some(20.0)).await });
    assert_eq!(fake.read().await, "GRIP(20)");
    fake.say("ACK GRIP\n").await;
    let home = spawn(
        &g,
        |g| async move { g.home(HomingDirection::Default).await },
    );
    assert_eq!(fake.read().await, "HOME()");
    fake.say("ERR GRIP 19*ACK HOME\nFIN HOME\n").await;
    within("HOME", home).await.unwrap().unwrap();
    assert!(
        !grip.is_finished(),
        "GRIP ended by a line that could not be read"
    );
}

/// The same with the swallowed reply's keyword damaged too (`JQCK HOME`: two flipped bits in
/// one line, `wsg-text:0x485486c387f4d074`): HOME's `FIN` was refused as another motion's, and
/// the healthy connection was given up when HOME was overdue.
#[tokio::test]
async fn an_ack_with_a_damaged_keyword_run_into_an_err_line_is_damage_too() {
    let (g, mut fake) = Fake::pair(ClientConfig::default()).await;
    let mover = spawn(&g, |g| async move { g.move_to(22.5, None).await });
    assert_eq!(fake.read().await, "MOVE(22.5)");
    let home = spawn(
        &g,
        |g| async move { g.home(HomingDirection::Default).await },
    );
    assert_eq!(fake.read().await, "HOME()");
    fake.say("ERR MOVE 3 E_NOT_INITIALIZEDJQCK HOME\nFIN HOME\n")
        .await;
    within("HOME", home).await.unwrap().unwrap();
    assert!(
        !mover.is_finished(),
        "MOVE ended by a line that could not be read"
    );
}

/// A request damaged on the way is answered under whatever name the damage left: a flipped bit
/// made `GRIPSTATE?` into `GRIP\x13TATE?`, answered `ERR GRIP 15`, and the program's `GRIP(…)`
/// on the wire then took it while its own `ACK GRIP` followed (the explorer's
/// `wsg-text:0xba0682223c8b01a8`). The gripper answers in order, so the `ACK GRIP` after it
/// shows the line was the query's: the query fails, GRIP ends with its own `FIN`. When the line
/// is GRIP's own, a reply to a line written after GRIP (the client's probe) says so, and that
/// the query written before GRIP lost its reply.
#[tokio::test]
async fn a_parse_error_answering_a_damaged_line_is_not_the_next_commands() {
    let (g, mut fake) = Fake::pair(ClientConfig::default()).await;
    let state = spawn(&g, |g| async move { g.grip_state().await });
    assert_eq!(fake.read().await, "GRIPSTATE?");
    let grip = spawn(&g, |g| async move { g.grip(Some(20.0)).await });
    assert_eq!(fake.read().await, "GRIP(20)");
    fake.say("ERR GRIP 15\nACK GRIP\nFIN GRIP\n").await;
    // Held, and nothing written after GRIP waits for a reply: a probe draws one.
    assert_eq!(fake.read().await, "POS?", "a probe");
    fake.say("POS=1.0\n").await;
    within("GRIP", grip).await.unwrap().unwrap();
    let state = within("GRIPSTATE?", state).await.unwrap();
    assert!(
        matches!(&state, Err(Error::MalformedReply { line, .. }) if line == "ERR GRIP 15"),
        "{state:?}"
    );

    // GRIP's own: the probe's answer settles it for GRIP.
    // (POS?'s reply is lost.)
    let pos = spawn(&g, |g| async move { g.position_mm().await });
    assert_eq!(fake.read().await, "POS?");
    let grip = spawn(&g, |g| async move { g.grip(Some(20.0)).await });
    assert_eq!(fake.read().await, "GRIP(20)");
    fake.say("ERR GRIP 15\n").await;
    assert_eq!(fake.read().await, "GRIPSTATE?", "a probe");
    fake.say("GRIPSTATE=0\n").await;
    let end = within("GRIP", grip).await.unwrap();
    assert!(
        matches!(
            &end,
            Err(Error::Device {
                status: Some(Status::CmdFormatError),
                ..
            })
        ),
        "{end:?}"
    );
    // In order, POS?'s reply came before GRIP's: the probe's answer shows it lost.
    let pos = within("POS?", pos).await.unwrap();
    assert!(matches!(pos, Err(Error::MalformedReply { .. })), "{pos:?}");
}

/// `wsg-text:0x939e47e5d1d27846`: GRIP's own `ERR GRIP 15` held behind POS?, then a line that
/// could not be read (the probe's own reply, damaged). It may have been GRIP's `ACK` (the
/// `ERR` then POS?'s), so GRIP is in doubt and the client asks whether it runs: idle, with no
/// `FIN` before (asked twice), GRIP never ran and the `ERR` was its own. Before, GRIP was taken
/// as acknowledged and its call timed out with its refusal in hand; grasping, GRIP's `FIN` ends
/// it.
#[tokio::test]
async fn a_held_parse_error_in_doubt_is_settled_by_asking_whether_the_motion_runs() {
    for moving in [false, true] {
        let (g, mut fake) = Fake::pair(ClientConfig::default()).await;
        let pos = spawn(&g, |g| async move { g.position_mm().await });
        assert_eq!(fake.read().await, "POS?");
        let grip = spawn(&g, |g| async move { g.grip(Some(79.5)).await });
        assert_eq!(fake.read().await, "GRIP(79.5)");
        fake.say("ERR GRIP 15\n").await;
        assert_eq!(fake.read().await, "GRIPSTATE?", "a probe");
        fake.say("GRI\x10STATE=6\n").await;
        let probe = fake.read().await;
        let answer = format!("{}=1.0\n", probe.trim_end_matches('?'));
        fake.say(&answer).await;
        // POS?'s reply came before GRIP's either way: lost.
        let pos = within("POS?", pos).await.unwrap();
        assert!(matches!(pos, Err(Error::MalformedReply { .. })), "{pos:?}");
        assert_eq!(
            fake.read().await,
            "GRIPSTATE?",
            "{moving}: is GRIP running?"
        );
        if moving {
            fake.say("GRIPSTATE=1\n").await;
            fake.say("FIN GRIP\n").await;
            within("GRIP", grip).await.unwrap().unwrap();
        } else {
            // Twice: one flipped bit turns a moving state into an idle one.
            fake.say("GRIPSTATE=0\n").await;
            assert_eq!(fake.read().await, "GRIPSTATE?", "asked again");
            fake.say("GRIPSTATE=0\n").await;
            let end = within("GRIP", grip).await.unwrap();
            assert!(
                matches!(
                    &end,
                    Err(Error::Device {
                        status: Some(Status::CmdFormatError),
                        line,
                        ..
                    }) if line == "ERR GRIP 15"
                ),
                "{end:?}"
            );
        }
    }
}

#[tokio::test]
async fn one_command_of_each_name_on_the_wire() {
    let (g, mut fake) = Fake::pair(ClientConfig::default()).await;
    let a = spawn(&g, |g| async move { g.position_mm().await });
    assert_eq!(fake.read().await, "POS?");
    let b = spawn(&g, |g| async move { g.position_mm().await });
    let speed = spawn(&g, |g| async move { g.speed_mm_per_s().await });
    // The second POS? waits; SPEED? goes out at once.
    assert_eq!(fake.read().await, "SPEED?");
    fake.say("SPEED=2.0\nPOS=1.0\n").await;
    assert_eq!(fake.read().await, "POS?");
    fake.say("POS=2.0\n").await;
    assert_eq!(within("a", a).await.unwrap().unwrap(), 1.0);
    assert_eq!(within("b", b).await.unwrap().unwrap(), 2.0);
    assert_eq!(within("speed", speed).await.unwrap().unwrap(), 2.0);
}

#[tokio::test]
async fn wrong_forms_are_typed_errors() {
    let (g, mut fake) = Fake::pair(ClientConfig::default()).await;
    let call = spawn(&g, |g| async move { g.position_mm().await });
    fake.read().await;
    fake.say("ACK POS\n").await;
    let e = within("POS?", call).await.unwrap().unwrap_err();
    assert!(matches!(e, Error::UnexpectedReply { .. }), "{e}");

    let call = spawn(&g, |g| async move { g.position_mm().await });
    fake.read().await;
    fake.say("POS=nan\n").await;
    let e = within("POS?", call).await.unwrap().unwrap_err();
    assert!(matches!(e, Error::MalformedReply { .. }), "{e}");

    let call = spawn(&g, |g| async move { g.grip_state().await });
    fake.read().await;
    fake.say("GRIPSTATE=4.5\n").await;
    let e = within("GRIPSTATE?", call).await.unwrap().unwrap_err();
    assert!(matches!(e, Error::MalformedReply { .. }), "{e}");

    // An ERR whose code is not in the binary table keeps its number and its line.
    let call = spawn(
        &g,
        |g| async move { g.home(HomingDirection::Positive).await },
    );
    assert_eq!(fake.read().await, "HOME(1)");
    fake.say("ERR HOME 99 something\n").await;
    let e = within("HOME", call).await.unwrap().unwrap_err();
    assert_eq!(e.status(), Some(Status::Unknown(99)));
    assert!(matches!(&e, Error::Device { line, .. } if line == "ERR HOME 99 something"));

    // An over-long line is skipped, not taken for a reply.
    let call = spawn(&g, |g| async move { g.position_mm().await });
    fake.read().await;
    fake.say(&format!("POS={}\nPOS=7.0\n", "1".repeat(5000)))
        .await;
    assert_eq!(within("POS?", call).await.unwrap().unwrap(), 7.0);
}

#[tokio::test]
async fn a_reply_cut_off_by_the_close_is_no_reply() {
    let (g, mut fake) = Fake::pair(ClientConfig::default()).await;
    let call = spawn(&g, |g| async move { g.position_mm().await });
    fake.read().await;
    fake.say("POS=12").await;
    drop(fake);
    let e = within("POS?", call).await.unwrap().unwrap_err();
    assert!(matches!(e, Error::ConnectionLost { .. }), "{e}");
}

#[tokio::test]
async fn a_missing_reply_times_out_then_gives_up_the_connection() {
    let config = ClientConfig {
        query_timeout: Duration::from_millis(50),
        give_up_after: Duration::from_millis(100),
        ..ClientConfig::default()
    };
    let (g, mut fake) = Fake::pair(config).await;
    let e = g.position_mm().await.unwrap_err();
    assert!(matches!(e, Error::Timeout { .. }), "{e}");
    assert_eq!(fake.read().await, "POS?");
    // Another name still works meanwhile.
    let speed = spawn(&g, |g| async move { g.speed_mm_per_s().await });
    assert_eq!(fake.read().await, "SPEED?");
    fake.say("SPEED=0.0\n").await;
    assert_eq!(within("SPEED?", speed).await.unwrap().unwrap(), 0.0);
    // POS? stays busy until its reply: a later POS? is not sent, and when the reply is overdue
    // past `give_up_after` the connection is given up.
    let e = within("give up", g.with_timeout(LIMIT).position_mm())
        .await
        .unwrap_err();
    assert!(matches!(e, Error::ConnectionLost { .. }), "{e}");
    assert!(g.is_closed());
}

/// A text simulator behind a line-framed fault proxy.
async fn rig() -> (SimServer, FaultProxy, Client) {
    let config = SimConfig::new(Model::Wsg50).with_part(40.0, 2.0).text();
    let server = SimServer::bind("127.0.0.1:0", config).await.unwrap();
    let proxy = FaultProxy::start_with(
        server.local_addr().unwrap(),
        ProxyConfig::new().framing(Framing::Delimited(b'\n')),
    )
    .await
    .unwrap();
    let config = ClientConfig {
        query_timeout: Duration::from_millis(300),
        give_up_after: Duration::from_millis(200),
        ..ClientConfig::default()
    };
    let g = Client::connect_with(proxy.local_addr(), config)
        .await
        .unwrap();
    within("home", g.home(HomingDirection::Default))
        .await
        .unwrap();
    (server, proxy, g)
}

#[tokio::test]
async fn split_merged_and_duplicated_lines_change_no_answer() {
    let (_server, proxy, g) = rig().await;
    let split = Fault::Split {
        piece_len: 1,
        pause: Duration::from_millis(1),
    };
    let rule = proxy.server_to_client().add(split.always());
    within("move", g.move_to(30.0, None)).await.unwrap();
    assert_eq!(within("pos", g.position_mm()).await.unwrap(), 30.0);
    rule.remove();
    let merge = Fault::Merge {
        frames: 2,
        max_wait: Duration::from_millis(50),
    };
    let rule = proxy.server_to_client().add(merge.always());
    let (a, b) = tokio::join!(g.position_mm(), g.grip_state());
    assert_eq!(a.unwrap(), 30.0);
    assert_eq!(b.unwrap(), gripper::wsg::GripState::Idle);
    rule.remove();
    // A duplicated FIN arrives when no MOVE is on the wire: dropped.
    proxy.server_to_client().add(Fault::Duplicate.always());
    within("move", g.move_to(40.0, None)).await.unwrap();
    within("move", g.move_to(50.0, None)).await.unwrap();
    assert_eq!(within("pos", g.position_mm()).await.unwrap(), 50.0);
}

#[tokio::test]
async fn a_corrupted_reply_is_a_malformed_reply_never_a_wrong_answer() {
    let (_server, proxy, g) = rig().await;
    // "POS=110.0" → "XOS=110.0": a reply for nobody.
    proxy.server_to_client().add(
        Fault::Corrupt {
            at: gripper::fault::At::Start(0),
            xor: b'P' ^ b'X',
        }
        .once(),
    );
    // Never a wrong answer: the damaged line is known to have been POS?'s reply once the
    // client's probe (GRIPSTATE?, written after it) is answered, and the call fails with it
    // (issue 29 M; before, the call timed out and the name stayed busy until the connection
    // was given up).
    let e = within("pos", g.position_mm()).await.unwrap_err();
    assert!(
        matches!(&e, Error::MalformedReply { line, .. } if line == "XOS=110.0"),
        "{e}"
    );
    // The name is free: the next POS? gets its own reply, on the same connection.
    let width = within("pos", g.position_mm()).await.unwrap();
    assert_eq!(width, 110.0);
}

#[tokio::test]
async fn a_cut_cable_fails_the_call() {
    let (_server, proxy, g) = rig().await;
    proxy
        .server_to_client()
        .add(Fault::Cut { after_bytes: 3 }.once());
    let e = within("pos", g.position_mm()).await.unwrap_err();
    assert!(matches!(e, Error::ConnectionLost { .. }), "{e}");
}

proptest! {
    #[test]
    fn the_reply_parser_never_panics(line in ".{0,300}") {
        let _ = parse_reply(&line);
    }

    #[test]
    fn replies_read_back_as_written(
        name in "[A-Z][A-Z0-9_]{0,12}",
        value in "[0-9]{1,6}\\.[0-9]",
        code in 0u16..1000,
    ) {
        let (ack, fin) = (format!("ACK {name}"), format!("FIN {name}\r"));
        let (set, push) = (format!("{name}={value}"), format!("@{name}={value}"));
        let err = format!("ERR {name} {code} E_X");
        prop_assert_eq!(parse_reply(&ack), Ok(ReplyLine::Ack(&name)));
        prop_assert_eq!(parse_reply(&fin), Ok(ReplyLine::Fin(&name)));
        prop_assert_eq!(parse_reply(&set), Ok(ReplyLine::Value { name: &name, value: &value }));
        prop_assert_eq!(parse_reply(&push), Ok(ReplyLine::Push { name: &name, value: &value }));
        prop_assert_eq!(
            parse_reply(&err),
            Ok(ReplyLine::Err { name: Some(&name), code: Some(code), text: "E_X" })
        );
    }
}

#[tokio::test]
async fn connecting_to_nothing_is_an_error() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    drop(listener);
    assert!(Client::connect(addr).await.is_err());
}
