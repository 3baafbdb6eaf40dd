//! The fault proxy (`gripper::fault`) driven end to end over loopback with arbitrary bytes.
//!
//! Its framer and fault plan are crate-private; the public way in is [`FaultProxy`] with a
//! [`Framing`] (including [`Framing::Custom`] functions that answer whatever they like) and
//! [`Rule`]s. Each input starts a proxy in front of an echo server, sends a stream through it in
//! chunks the input chooses (each chunk is read by the proxy before the next is written, so the
//! framer sees the same pushes every run), half-closes, and reads everything that comes back: the
//! bytes cross the proxy twice, once through each direction's framer. Framings: bytes,
//! delimited, fixed length, the WSG framing (`wsg::frame::frame_len`), a hostile custom one.
//!
//! Input: `[framing, param, max_frame_len, rules, (kind, arg, when) x rules, split input..]`
//! (the split input as in [`split_input`]).
//!
//! Checked, besides "no panic" (in the proxy's tasks too: a panicking connection task would cut
//! the echo short, which the checks see):
//! - no hang: the whole exchange ends within 10 s, whatever the framing and faults (no stalls
//!   are used, and delays and merge waits are zero: timing is not what this target explores);
//! - no rule, or only splits, merges and zero delays: every byte comes back exactly once, in
//!   order, whatever the framing and frame bound;
//! - corruption alone keeps the length; drops and cuts give a subsequence of what was sent;
//!   duplicates a supersequence; the upstream is always reached.
#![no_main]

use std::net::SocketAddr;
use std::sync::OnceLock;
use std::time::Duration;

use gripper::fault::{At, Fault, FaultProxy, FrameLen, Framing, ProxyConfig, Rule, When};
use gripper_fuzz::split_input;
use libfuzzer_sys::fuzz_target;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::runtime::Runtime;

/// One runtime and one echo server for the whole run.
fn setup() -> &'static (Runtime, SocketAddr) {
    static SETUP: OnceLock<(Runtime, SocketAddr)> = OnceLock::new();
    SETUP.get_or_init(|| {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        let addr = rt.block_on(async {
            let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
            let addr = listener.local_addr().unwrap();
            tokio::spawn(async move {
                while let Ok((mut socket, _)) = listener.accept().await {
                    // Without it, Nagle's algorithm and delayed ACKs add 40 ms to some runs.
                    let _ = socket.set_nodelay(true);
                    tokio::spawn(async move {
                        let (mut read, mut write) = socket.split();
                        let _ = tokio::io::copy(&mut read, &mut write).await;
                        let _ = write.shutdown().await;
                    });
                }
            });
            addr
        });
        (rt, addr)
    })
}

/// A framing function that says whatever the bytes make it say: zero, huge and overflowing
/// lengths, garbage longer than the buffer, "need more" forever.
fn hostile_frame_len(buf: &[u8]) -> FrameLen {
    let arg = buf.get(1).copied().map_or(0, usize::from);
    match buf[0] % 8 {
        0 => FrameLen::Complete(arg),
        1 => FrameLen::Garbage(arg),
        2 => FrameLen::NeedMore,
        3 => FrameLen::Complete(usize::MAX - arg),
        4 => FrameLen::Garbage(usize::MAX - arg),
        5 if buf.len() > arg => FrameLen::Complete(buf.len()),
        5 => FrameLen::NeedMore,
        6 => FrameLen::Complete(buf.len() + arg),
        _ => FrameLen::Garbage(buf.len()),
    }
}

fn framing(selector: u8, param: u8) -> Framing {
    match selector % 5 {
        0 => Framing::Bytes,
        1 => Framing::Delimited(param),
        2 => Framing::FixedLength(usize::from(param)),
        3 => Framing::Custom(gripper::wsg::frame::frame_len),
        _ => Framing::Custom(hostile_frame_len),
    }
}

/// What the rules allow the echo to look like.
#[derive(Debug, Default)]
struct Effects {
    changes_bytes: bool,
    removes: bool,
    adds: bool,
}

fn rule(kind: u8, arg: u8, w: u8, effects: &mut Effects) -> Rule {
    let at = match arg % 3 {
        0 => At::Start(usize::from(arg / 3)),
        1 => At::End(usize::from(arg / 3)),
        _ => At::Random,
    };
    let n = usize::from(arg);
    let fault = match kind % 8 {
        0 => Fault::Split {
            piece_len: n,
            pause: Duration::ZERO,
        },
        1 => Fault::Merge {
            frames: n % 8,
            max_wait: Duration::ZERO,
        },
        // Zero: a real delay on every one-byte frame would make runs too slow to fuzz.
        2 => Fault::Delay(Duration::ZERO),
        3 => {
            effects.changes_bytes = true;
            Fault::Corrupt { at, xor: arg }
        }
        4 => {
            effects.removes = true;
            Fault::Drop
        }
        5 => {
            effects.removes = true;
            Fault::DropBytes { at, len: n % 16 }
        }
        6 => {
            effects.adds = true;
            Fault::Duplicate
        }
        _ => {
            effects.removes = true;
            Fault::Cut {
                after_bytes: n % 32,
            }
        }
    };
    let when = match w % 4 {
        0 => When::Nth(u64::from(w / 4)),
        1 => When::Every(u64::from(w / 4)),
        2 => When::Randomly {
            one_in: u32::from(w / 4),
        },
        _ => When::Every(1),
    };
    let rule = Rule::new(fault, when);
    if w.is_multiple_of(5) {
        rule.times(u64::from(w % 3))
    } else {
        rule
    }
}

/// Whether `small` is a subsequence of `big`.
fn is_subsequence(small: &[u8], big: &[u8]) -> bool {
    let mut big = big.iter();
    small.iter().all(|b| big.any(|c| c == b))
}

fuzz_target!(|data: &[u8]| {
    let [sel, param, bound, nrules, rest @ ..] = data else {
        return;
    };
    let nrules = usize::from(nrules % 4);
    if rest.len() < 3 * nrules {
        return;
    }
    let (rule_bytes, rest) = rest.split_at(3 * nrules);
    let (chunks, stream) = split_input(rest);
    let max_frame_len = if *bound == 255 {
        64 * 1024
    } else {
        1 + 4 * usize::from(*bound)
    };
    let mut effects = Effects::default();
    let rules: Vec<Rule> = rule_bytes
        .chunks_exact(3)
        .map(|r| rule(r[0], r[1], r[2], &mut effects))
        .collect();

    let (rt, echo) = setup();
    let echoed = rt.block_on(async {
        let config = ProxyConfig::new()
            .framing(framing(*sel, *param))
            .max_frame_len(max_frame_len)
            .seed(u64::from(*param));
        let proxy = FaultProxy::start_with(*echo, config).await.unwrap();
        for rule in &rules {
            proxy.client_to_server().add(*rule);
        }
        let exchange = async {
            let client = TcpStream::connect(proxy.local_addr()).await.unwrap();
            // No TIME_WAIT: thousands of connections a second must not run out of ports.
            let _ = client.set_zero_linger();
            client.set_nodelay(true).unwrap();
            let (mut read, mut write) = client.into_split();
            let send = async {
                let mut sent = 0u64;
                for chunk in &chunks {
                    if write.write_all(chunk).await.is_err() {
                        return; // cut
                    }
                    sent += chunk.len() as u64;
                    // The proxy reads this chunk before the next is written (or the connection
                    // is gone): the framer sees the same pushes on every run.
                    let faults = proxy.client_to_server();
                    let done = faults.wait_for(|s| s.bytes_read >= sent);
                    let gone = proxy
                        .wait_for_stats(|s| s.connections_open == 0 && s.connections_accepted > 0);
                    tokio::select! {
                        _ = done => {}
                        _ = gone => return,
                    }
                }
                let _ = write.shutdown().await;
            };
            let receive = async {
                let mut echoed = Vec::new();
                // A reset after a cut ends the echo like an EOF.
                let _ = read.read_to_end(&mut echoed).await;
                echoed
            };
            let ((), echoed) = tokio::join!(send, receive);
            echoed
        };
        let echoed = tokio::time::timeout(Duration::from_secs(10), exchange)
            .await
            .unwrap_or_else(|_| {
                panic!("hang: framing {sel}/{param}, bound {max_frame_len}, rules {rules:?}")
            });
        let stats = proxy.stats();
        proxy.shutdown().await;
        (echoed, stats)
    });
    let (echoed, stats) = echoed;
    assert_eq!(stats.upstream_connect_failures, 0);

    let context = || format!("rules {rules:?}, bound {max_frame_len}, stats {stats:?}");
    match effects {
        Effects {
            changes_bytes: false,
            removes: false,
            adds: false,
        } => {
            assert!(echoed == stream, "not transparent: {}", context());
            assert_eq!(stats.client_to_server.bytes_read, stream.len() as u64);
            assert_eq!(stats.server_to_client.bytes_written, stream.len() as u64);
        }
        Effects {
            changes_bytes: true,
            removes: false,
            adds: false,
        } => assert_eq!(echoed.len(), stream.len(), "{}", context()),
        Effects {
            changes_bytes: false,
            removes: true,
            adds: false,
        } => assert!(is_subsequence(&echoed, stream), "{}", context()),
        Effects {
            changes_bytes: false,
            removes: false,
            adds: true,
        } => assert!(is_subsequence(stream, &echoed), "{}", context()),
        _ => {}
    }
});
