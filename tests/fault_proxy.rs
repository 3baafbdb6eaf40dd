//! The fault proxy on real loopback sockets: each fault observably happens, faults change while
//! traffic flows, and the proxy lets go of everything when dropped.
//!
//! Most tests hold both ends of one proxied connection (the client socket and the server's
//! accepted socket), so they see exactly which bytes crossed. They wait for the proxy's counters
//! instead of sleeping, and every read is bounded by a timeout.
#![cfg(feature = "sim")]

use std::future::Future;
use std::io::ErrorKind;
use std::net::SocketAddr;
use std::time::Duration;

use gripper::fault::{At, Direction, Fault, FaultProxy, FrameLen, Framing, ProxyConfig};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

/// Upper bound for anything that should happen promptly; only reached when a test fails.
const LIMIT: Duration = Duration::from_secs(10);
/// A pause or delay that a test ends by changing the faults, never by waiting it out.
const LONG: Duration = Duration::from_secs(3600);

async fn within<F: Future>(what: &str, future: F) -> F::Output {
    tokio::time::timeout(LIMIT, future)
        .await
        .unwrap_or_else(|_| panic!("timed out: {what}"))
}

/// A proxy, and both ends of one connection through it: the client's socket and the socket the
/// upstream server accepted.
async fn link(config: ProxyConfig) -> (FaultProxy, TcpStream, TcpStream) {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let proxy = FaultProxy::start_with(listener.local_addr().unwrap(), config)
        .await
        .unwrap();
    let client = TcpStream::connect(proxy.local_addr()).await.unwrap();
    let (server, _) = within("upstream accept", listener.accept()).await.unwrap();
    (proxy, client, server)
}

fn lines() -> ProxyConfig {
    ProxyConfig::new().framing(Framing::Delimited(b'\n'))
}

async fn read_exactly(stream: &mut TcpStream, n: usize) -> Vec<u8> {
    let mut buf = vec![0; n];
    within("read", stream.read_exact(&mut buf)).await.unwrap();
    buf
}

async fn read_to_end(stream: &mut TcpStream) -> Vec<u8> {
    let mut buf = Vec::new();
    within("read to end", stream.read_to_end(&mut buf))
        .await
        .unwrap();
    buf
}

/// Asserts that no byte is waiting on `stream`, with a real non-blocking `peek` (tokio's own
/// readiness cache could answer "nothing" for bytes that have just arrived).
fn assert_nothing_arrived(stream: TcpStream) -> TcpStream {
    let std = stream.into_std().unwrap();
    let mut buf = [0u8; 64];
    match std.peek(&mut buf) {
        Err(e) if e.kind() == ErrorKind::WouldBlock => {}
        other => panic!(
            "expected nothing to have arrived, got {other:?} ({:?})",
            &buf[..]
        ),
    }
    TcpStream::from_std(std).unwrap()
}

/// An echo server on a free port.
async fn echo_server() -> SocketAddr {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    tokio::spawn(async move {
        while let Ok((mut socket, _)) = listener.accept().await {
            tokio::spawn(async move {
                let (mut read, mut write) = socket.split();
                let _ = tokio::io::copy(&mut read, &mut write).await;
            });
        }
    });
    addr
}

#[tokio::test]
async fn forwards_both_ways_untouched_without_faults() {
    let (proxy, mut client, mut server) = link(ProxyConfig::new()).await;
    let request: Vec<u8> = (0..200_000u32).map(|i| (i * 7 % 251) as u8).collect();
    let (sent, received) = tokio::join!(
        client.write_all(&request),
        read_exactly(&mut server, request.len())
    );
    sent.unwrap();
    assert_eq!(received, request);

    server.write_all(b"reply").await.unwrap();
    assert_eq!(read_exactly(&mut client, 5).await, b"reply");

    let stats = within(
        "counters",
        proxy.wait_for_stats(|s| s.server_to_client.bytes_written == 5),
    )
    .await;
    assert_eq!(stats.connections_accepted, 1);
    assert_eq!(stats.connections_open, 1);
    assert_eq!(stats.client_to_server.bytes_read, request.len() as u64);
    assert_eq!(stats.client_to_server.bytes_written, request.len() as u64);
    assert_eq!(stats.server_to_client.bytes_written, 5);
    assert_eq!(stats.client_to_server.faults_fired, 0);
}

#[tokio::test]
async fn half_close_is_forwarded_and_the_other_direction_keeps_flowing() {
    let (_proxy, mut client, mut server) = link(ProxyConfig::new()).await;
    client.write_all(b"last request").await.unwrap();
    client.shutdown().await.unwrap();
    assert_eq!(read_to_end(&mut server).await, b"last request");
    server.write_all(b"late reply").await.unwrap();
    server.shutdown().await.unwrap();
    assert_eq!(read_to_end(&mut client).await, b"late reply");
}

#[tokio::test]
async fn split_delivers_pieces_separately_until_the_faults_change() {
    let (proxy, mut client, mut server) = link(lines()).await;
    let faults = proxy.client_to_server();
    let split = faults.add(
        Fault::Split {
            piece_len: 4,
            pause: LONG,
        }
        .once(),
    );
    client.write_all(b"0123456789A\n").await.unwrap();

    // The first piece is written, then the proxy pauses: exactly 4 bytes are there.
    assert_eq!(read_exactly(&mut server, 4).await, b"0123");
    let stats = within(
        "first piece counted",
        faults.wait_for(|s| s.bytes_written == 4),
    )
    .await;
    assert_eq!(stats.writes, 1);
    let mut server = assert_nothing_arrived(server);

    // Changing the faults ends the pause: the other pieces follow, each its own write.
    faults.clear();
    assert_eq!(read_exactly(&mut server, 8).await, b"456789A\n");
    let stats = within(
        "all pieces counted",
        faults.wait_for(|s| s.bytes_written == 12),
    )
    .await;
    assert_eq!(stats.writes, 3, "12 bytes in pieces of 4");
    assert_eq!(split.fired(), 1);
}

#[tokio::test]
async fn merge_holds_frames_and_writes_them_together() {
    let (proxy, client, mut server) =
        link(ProxyConfig::new().framing(Framing::FixedLength(8))).await;
    let faults = proxy.server_to_client();
    let merge = faults.add(
        Fault::Merge {
            frames: 3,
            max_wait: LONG,
        }
        .once(),
    );
    server.write_all(b"frame-1;").await.unwrap();
    server.write_all(b"frame-2;").await.unwrap();
    within("two frames read", faults.wait_for(|s| s.frames == 2)).await;
    let mut client = assert_nothing_arrived(client);

    server.write_all(b"frame-3;").await.unwrap();
    assert_eq!(
        read_exactly(&mut client, 24).await,
        b"frame-1;frame-2;frame-3;"
    );
    let stats = within("group counted", faults.wait_for(|s| s.bytes_written == 24)).await;
    assert_eq!(stats.writes, 1, "three frames, one write");
    assert_eq!(merge.fired(), 1);

    // The rule was one-shot: the next frame goes on its own.
    server.write_all(b"frame-4;").await.unwrap();
    assert_eq!(read_exactly(&mut client, 8).await, b"frame-4;");
    let stats = within("frame counted", faults.wait_for(|s| s.bytes_written == 32)).await;
    assert_eq!(stats.writes, 2);
}

#[tokio::test]
async fn merge_group_that_never_fills_is_written_after_max_wait() {
    let (proxy, mut client, mut server) =
        link(ProxyConfig::new().framing(Framing::FixedLength(8))).await;
    let merge = proxy.server_to_client().add(
        Fault::Merge {
            frames: 5,
            max_wait: Duration::from_millis(20),
        }
        .once(),
    );
    server.write_all(b"lonely-1").await.unwrap();
    assert_eq!(read_exactly(&mut client, 8).await, b"lonely-1");
    assert_eq!(merge.fired(), 1);
}

#[tokio::test]
async fn corrupt_flips_one_byte_of_the_next_frame_only() {
    let (proxy, mut client, mut server) = link(lines()).await;
    let corrupt = proxy.client_to_server().add(
        Fault::Corrupt {
            at: At::Start(1),
            xor: 0x20,
        }
        .once(),
    );
    client.write_all(b"abc\nabc\n").await.unwrap();
    assert_eq!(read_exactly(&mut server, 8).await, b"aBc\nabc\n");
    assert_eq!(corrupt.fired(), 1);
    assert!(!corrupt.is_active());
}

#[tokio::test]
async fn drop_every_third_frame() {
    let (proxy, mut client, mut server) =
        link(ProxyConfig::new().framing(Framing::FixedLength(3))).await;
    let dropping = proxy.client_to_server().add(Fault::Drop.every(3));
    for i in 1..=9 {
        client
            .write_all(format!("f{i:02}").as_bytes())
            .await
            .unwrap();
    }
    assert_eq!(read_exactly(&mut server, 18).await, b"f01f02f04f05f07f08");
    // Frame 9 was dropped too: frame 10 arrives next.
    dropping.remove();
    client.write_all(b"f10").await.unwrap();
    assert_eq!(read_exactly(&mut server, 3).await, b"f10");
    assert_eq!(dropping.fired(), 3);
    assert_eq!(proxy.stats().client_to_server.frames, 10);
}

#[tokio::test]
async fn drop_bytes_removes_a_range_inside_a_frame() {
    let (proxy, mut client, mut server) = link(lines()).await;
    proxy.client_to_server().add(
        Fault::DropBytes {
            at: At::Start(2),
            len: 3,
        }
        .once(),
    );
    client.write_all(b"0123456789\nok\n").await.unwrap();
    assert_eq!(read_exactly(&mut server, 11).await, b"0156789\nok\n");
}

#[tokio::test]
async fn duplicate_the_second_reply() {
    let (proxy, mut client, mut server) = link(lines()).await;
    let duplicate = proxy.server_to_client().add(Fault::Duplicate.nth(2));
    server.write_all(b"A\nB\nC\n").await.unwrap();
    assert_eq!(read_exactly(&mut client, 8).await, b"A\nB\nB\nC\n");
    assert_eq!(duplicate.fired(), 1);
}

#[tokio::test]
async fn stall_holds_bytes_without_closing_and_release_lets_them_through() {
    let (proxy, mut client, server) = link(lines()).await;
    let faults = proxy.client_to_server();
    faults.stall();
    client.write_all(b"hello\n").await.unwrap();
    let stats = within("held at the stall", faults.wait_for(|s| s.held_bytes == 6)).await;
    assert!(stats.stalled);
    assert_eq!(stats.bytes_written, 0);
    let mut server = assert_nothing_arrived(server);

    // Exactly two bytes through, then held again.
    faults.release_bytes(2);
    assert_eq!(read_exactly(&mut server, 2).await, b"he");
    within("two written", faults.wait_for(|s| s.held_bytes == 4)).await;
    let mut server = assert_nothing_arrived(server);

    faults.release();
    assert!(!faults.is_stalled());
    assert_eq!(read_exactly(&mut server, 4).await, b"llo\n");
    // The connection survived the stall: traffic still flows both ways.
    server.write_all(b"ack\n").await.unwrap();
    assert_eq!(read_exactly(&mut client, 4).await, b"ack\n");
    assert_eq!(proxy.stats().connections_cut, 0);
}

#[tokio::test]
async fn stall_rule_holds_from_the_chosen_frame_on() {
    let (proxy, mut client, mut server) = link(lines()).await;
    let faults = proxy.server_to_client();
    let stall = faults.add(Fault::Stall.nth(2));
    server.write_all(b"one\ntwo\nthree\n").await.unwrap();
    assert_eq!(read_exactly(&mut client, 4).await, b"one\n");
    within(
        "stalled",
        faults.wait_for(|s| s.stalled && s.held_bytes == 4),
    )
    .await;
    assert_eq!(stall.wait_fired(1).await, 1);
    let mut client = assert_nothing_arrived(client);
    faults.release();
    assert_eq!(read_exactly(&mut client, 10).await, b"two\nthree\n");
}

#[tokio::test]
async fn delay_holds_a_frame_until_the_rule_is_removed() {
    let (proxy, client, mut server) = link(lines()).await;
    let faults = proxy.server_to_client();
    let delay = faults.add(Fault::Delay(LONG).always());
    server.write_all(b"late\n").await.unwrap();
    within("delay applied", delay.wait_fired(1)).await;
    let mut client = assert_nothing_arrived(client);
    delay.remove();
    assert_eq!(read_exactly(&mut client, 5).await, b"late\n");
    // Removed: the next frame is not delayed.
    server.write_all(b"now\n").await.unwrap();
    assert_eq!(read_exactly(&mut client, 4).await, b"now\n");
    assert_eq!(delay.fired(), 1);
}

#[tokio::test]
async fn cut_mid_frame_delivers_the_first_bytes_then_closes_both_sides() {
    let (proxy, mut client, mut server) = link(lines()).await;
    let cut = proxy
        .server_to_client()
        .add(Fault::Cut { after_bytes: 3 }.nth(2));
    server.write_all(b"whole\nABCDEFG\n").await.unwrap();
    assert_eq!(read_to_end(&mut client).await, b"whole\nABC");
    // The server's side is closed too (EOF, or a reset if its bytes were still unread).
    let mut rest = Vec::new();
    let _ = within("server sees the cut", server.read_to_end(&mut rest)).await;
    assert!(rest.is_empty());
    assert_eq!(cut.fired(), 1);
    let stats = within("counted", proxy.wait_for_stats(|s| s.connections_open == 0)).await;
    assert_eq!(stats.connections_cut, 1);
}

#[tokio::test]
async fn cut_connections_closes_now_and_new_connections_work() {
    let proxy = FaultProxy::start(echo_server().await).await.unwrap();
    let mut first = TcpStream::connect(proxy.local_addr()).await.unwrap();
    first.write_all(b"ping").await.unwrap();
    assert_eq!(read_exactly(&mut first, 4).await, b"ping");

    proxy.cut_connections();
    assert_eq!(read_to_end(&mut first).await, b"");
    within(
        "cut counted",
        proxy.wait_for_stats(|s| s.connections_cut == 1),
    )
    .await;

    let mut second = TcpStream::connect(proxy.local_addr()).await.unwrap();
    second.write_all(b"pong").await.unwrap();
    assert_eq!(read_exactly(&mut second, 4).await, b"pong");
    assert_eq!(proxy.stats().connections_accepted, 2);
}

#[tokio::test]
async fn faults_change_at_run_time_in_both_directions() {
    let (proxy, mut client, mut server) = link(lines()).await;
    let requests = proxy.client_to_server();
    let replies = proxy.server_to_client();

    let dropping = requests.add(Fault::Drop.always());
    client.write_all(b"lost\n").await.unwrap();
    within("dropped", dropping.wait_fired(1)).await;
    dropping.remove();
    assert!(!dropping.is_active());
    let duplicate = replies.add(Fault::Duplicate.always());
    client.write_all(b"kept\n").await.unwrap();
    assert_eq!(read_exactly(&mut server, 5).await, b"kept\n");
    server.write_all(b"twice\n").await.unwrap();
    assert_eq!(read_exactly(&mut client, 12).await, b"twice\ntwice\n");

    replies.clear();
    assert!(!duplicate.is_active());
    server.write_all(b"once\n").await.unwrap();
    client.write_all(b"end\n").await.unwrap();
    assert_eq!(read_exactly(&mut server, 4).await, b"end\n");
    assert_eq!(read_exactly(&mut client, 5).await, b"once\n");
    let client = assert_nothing_arrived(client);
    drop(client);
    assert_eq!(
        proxy
            .stats()
            .direction(Direction::ClientToServer)
            .faults_fired,
        1
    );
    assert_eq!(
        proxy
            .stats()
            .direction(Direction::ServerToClient)
            .faults_fired,
        1
    );
}

/// WSG frame length from the header (PROTOCOLS.md §1: `AA AA AA id len:u16 LE payload crc:u16`).
fn wsg_frame_len(buf: &[u8]) -> FrameLen {
    if !buf.iter().take(3).all(|&b| b == 0xAA) {
        return FrameLen::Garbage(1);
    }
    match buf {
        [_, _, _, _, lo, hi, ..] => {
            FrameLen::Complete(8 + usize::from(u16::from_le_bytes([*lo, *hi])))
        }
        _ => FrameLen::NeedMore,
    }
}

#[tokio::test]
async fn custom_framing_corrupts_a_checksum_and_passes_garbage_untouched() {
    let (proxy, mut client, mut server) =
        link(ProxyConfig::new().framing(Framing::Custom(wsg_frame_len))).await;
    let corrupt = proxy.server_to_client().add(
        Fault::Corrupt {
            at: At::End(0),
            xor: 0x01,
        }
        .nth(2),
    );
    let frame = [0xAA, 0xAA, 0xAA, 0x40, 0x02, 0x00, 0x00, 0x00, 0x12, 0x34];
    let mut stream = b"noise".to_vec();
    stream.extend_from_slice(&frame);
    stream.extend_from_slice(&frame);
    server.write_all(&stream).await.unwrap();

    let mut expected = stream.clone();
    let last = expected.len() - 1;
    expected[last] ^= 0x01;
    assert_eq!(read_exactly(&mut client, expected.len()).await, expected);
    assert_eq!(corrupt.fired(), 1);
    let stats = proxy.stats().server_to_client;
    assert_eq!(stats.frames, 2);
    assert_eq!(stats.passthrough_bytes, 5);
}

#[tokio::test]
async fn frames_over_the_bound_pass_through_unbuffered() {
    let (proxy, mut client, mut server) = link(lines().max_frame_len(16)).await;
    let corrupt = proxy.client_to_server().add(
        Fault::Corrupt {
            at: At::Start(0),
            xor: 0x20,
        }
        .always(),
    );
    let long_line = [b'x'; 100];
    client.write_all(&long_line).await.unwrap();
    // Forwarded before its end arrived: the proxy did not wait to buffer the whole line.
    assert_eq!(read_exactly(&mut server, 100).await, long_line);
    client.write_all(b"x\nshort\n").await.unwrap();
    assert_eq!(read_exactly(&mut server, 8).await, b"x\nShort\n");
    assert_eq!(corrupt.fired(), 1, "only the short line is a frame");
    assert_eq!(proxy.stats().client_to_server.passthrough_bytes, 102);
}

#[tokio::test]
async fn random_faults_are_reproducible_for_a_seed() {
    async fn survivors(seed: u64) -> Vec<u8> {
        let (proxy, mut client, mut server) = link(
            ProxyConfig::new()
                .framing(Framing::FixedLength(1))
                .seed(seed),
        )
        .await;
        let faults = proxy.client_to_server();
        let dropping = faults.add(Fault::Drop.randomly(2));
        let sent: Vec<u8> = (0..64).collect();
        client.write_all(&sent).await.unwrap();
        let stats = within(
            "all decided",
            faults.wait_for(|s| s.frames == 64 && s.held_bytes == 0),
        )
        .await;
        assert_eq!(stats.bytes_written, 64 - dropping.fired());
        read_exactly(&mut server, stats.bytes_written as usize).await
    }
    let first = survivors(7).await;
    assert_eq!(first, survivors(7).await);
    assert!(
        !first.is_empty() && first.len() < 64,
        "{} of 64 survived",
        first.len()
    );
    assert_ne!(first, survivors(8).await);
}

#[tokio::test]
async fn dropping_the_proxy_closes_the_listener_and_every_connection() {
    let (proxy, mut client, mut server) = link(lines()).await;
    let addr = proxy.local_addr();
    // Leave bytes held at a stall, so there is work in flight to abandon.
    let faults = proxy.client_to_server();
    faults.stall();
    client.write_all(b"held\n").await.unwrap();
    within("held", faults.wait_for(|s| s.held_bytes == 5)).await;
    drop(proxy);

    assert_eq!(read_to_end(&mut client).await, b"");
    assert_eq!(read_to_end(&mut server).await, b"");
    // The listener goes with it (the accept task may be cancelled just after the connections).
    within("listener closed", async {
        while TcpStream::connect(addr).await.is_ok() {
            tokio::task::yield_now().await;
        }
    })
    .await;
    // A handle that outlived the proxy sees the abandoned bytes released from the count.
    within("held bytes freed", faults.wait_for(|s| s.held_bytes == 0)).await;
}

#[tokio::test]
async fn shutdown_waits_until_everything_is_closed() {
    let (proxy, mut client, mut server) = link(lines()).await;
    let faults = proxy.server_to_client();
    faults.add(Fault::Delay(LONG).always());
    server.write_all(b"never\n").await.unwrap();
    within("delaying", faults.wait_for(|s| s.faults_fired == 1)).await;
    within("shutdown", proxy.shutdown()).await;
    assert_eq!(read_to_end(&mut client).await, b"");
    let mut rest = Vec::new();
    let _ = within("server closed", server.read_to_end(&mut rest)).await;
    assert!(rest.is_empty());
}

#[tokio::test]
async fn unreachable_upstream_closes_the_client() {
    // A port that was free a moment ago and has nothing listening now.
    let upstream = {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        listener.local_addr().unwrap()
    };
    let proxy = FaultProxy::start(upstream).await.unwrap();
    let mut client = TcpStream::connect(proxy.local_addr()).await.unwrap();
    let mut rest = Vec::new();
    let _ = within("client closed", client.read_to_end(&mut rest)).await;
    assert!(rest.is_empty());
    let stats = within(
        "failure counted",
        proxy.wait_for_stats(|s| s.upstream_connect_failures == 1 && s.connections_open == 0),
    )
    .await;
    assert_eq!(stats.connections_accepted, 1);
}

#[tokio::test]
async fn a_stalled_direction_stops_reading_instead_of_buffering() {
    let (proxy, mut client, mut server) = link(ProxyConfig::new().max_frame_len(1024)).await;
    let faults = proxy.client_to_server();
    faults.stall();
    // Far more than the kernel's socket buffers on both sides can take.
    let data: Vec<u8> = (0..32 * 1024 * 1024u32).map(|i| (i % 253) as u8).collect();
    let expected = data.clone();
    let writer = tokio::spawn(async move {
        client.write_all(&data).await.unwrap();
        client
    });
    let stats = within("held", faults.wait_for(|s| s.held_bytes > 0)).await;
    // One read, held at the stall, and nothing read behind it.
    assert!(
        stats.bytes_read <= 1024,
        "read {} bytes while stalled",
        stats.bytes_read
    );
    assert_eq!(stats.bytes_read, stats.held_bytes);
    assert!(!writer.is_finished());

    faults.release();
    assert!(read_exactly(&mut server, expected.len()).await == expected);
    let _client = within("writer done", writer).await.unwrap();
}
