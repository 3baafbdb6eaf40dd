//! Helpers shared by the integration tests (`mod common;` in each file that uses them).

/// xorshift64: a small seeded generator, so randomised tests are reproducible without a
/// dependency. Seed with a non-zero value (zero stays zero).
#[allow(dead_code)] // only the cancel tests use it
pub struct Rng(pub u64);

#[allow(dead_code)]
impl Rng {
    /// The next draw in `0..n` (`0` when `n` is 0).
    pub fn below(&mut self, n: u64) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0 % n.max(1)
    }
}

/// Homes the gripper, speeds the simulator up, starts a pre-position to 20 mm at 50 mm/s on a
/// clone of `client`, and returns the move's task once the device reports MOVING (a move in
/// flight for the cancel and reconnect tests to interrupt).
#[cfg(feature = "sim")]
#[allow(dead_code)] // only the WSG tests use it
pub async fn wsg_start_moving(
    sim: &gripper::wsg::sim::SimServer,
    client: &gripper::wsg::Client,
) -> tokio::task::JoinHandle<gripper::wsg::Result<()>> {
    use gripper::wsg::{HomingDirection, SystemState};

    client.home(HomingDirection::Default).await.unwrap();
    sim.set_time_scale(1000.0);
    let mover = {
        let c = client.clone();
        tokio::spawn(async move { c.pre_position(20.0, 50.0).await })
    };
    while !client
        .system_state()
        .await
        .unwrap()
        .contains(SystemState::MOVING)
    {}
    mover
}

/// Waits until `cond` holds on the GRIPLINK simulator, polling every millisecond; panics with
/// `what` if it does not within `limit`.
#[cfg(feature = "sim")]
#[allow(dead_code)] // only the GRIPLINK tests use it
pub async fn griplink_until(
    server: &gripper::griplink::sim::SimServer,
    limit: std::time::Duration,
    what: &str,
    cond: impl Fn(&gripper::griplink::sim::SimServer) -> bool,
) {
    tokio::time::timeout(limit, async {
        while !cond(server) {
            tokio::time::sleep(std::time::Duration::from_millis(1)).await;
        }
    })
    .await
    .expect(what);
}

/// A raw SmartGrasp peer over loopback serving any number of connections: `respond(connection,
/// i, request)` gives the bytes to write for the i-th request of a connection (`None`: stay
/// silent).
#[cfg(feature = "sim")]
#[allow(dead_code)] // only the SmartGrasp tests use it
pub async fn smartgrasp_peer(
    respond: impl Fn(usize, usize, gripper::smartgrasp::frame::RequestFrame) -> Option<Vec<u8>>
        + Send
        + Sync
        + 'static,
) -> std::net::SocketAddr {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let respond = std::sync::Arc::new(respond);
    tokio::spawn(async move {
        let mut connection = 0;
        while let Ok((mut stream, _)) = listener.accept().await {
            let respond = std::sync::Arc::clone(&respond);
            let n = connection;
            connection += 1;
            tokio::spawn(async move {
                let mut buf = [0u8; gripper::smartgrasp::frame::FRAME_LEN];
                let mut i = 0;
                while stream.read_exact(&mut buf).await.is_ok() {
                    let out = respond(n, i, gripper::smartgrasp::frame::RequestFrame::decode(&buf));
                    i += 1;
                    if let Some(out) = out {
                        if stream.write_all(&out).await.is_err() {
                            break;
                        }
                    }
                }
            });
        }
    });
    addr
}

/// Upper bound for anything that should happen promptly; only reached when a test fails.
#[allow(dead_code)] // only some tests use it
pub const LIMIT: std::time::Duration = std::time::Duration::from_secs(20);

/// Bounds a call that must end by itself well before [`LIMIT`]: a hang fails the test (naming
/// `what`) instead of blocking the suite.
#[allow(dead_code)] // only some tests use it
pub async fn within<F: std::future::Future>(what: &str, call: F) -> F::Output {
    tokio::time::timeout(LIMIT, call)
        .await
        .unwrap_or_else(|_| panic!("hung: {what} (no end within {LIMIT:?})"))
}

/// A reconnect policy quick enough for a test: 5 ms, doubling up to 20 ms, for at most
/// `max_attempts` attempts (`None`: until it reconnects).
#[allow(dead_code)] // only the reconnect tests use it
pub fn policy(max_attempts: Option<u32>) -> gripper::reconnect::ReconnectPolicy {
    gripper::reconnect::ReconnectPolicy {
        initial_delay: std::time::Duration::from_millis(5),
        max_delay: std::time::Duration::from_millis(20),
        factor: 2.0,
        max_attempts,
    }
}

/// The next connection event (`None`: the stream ended), within [`LIMIT`].
#[allow(dead_code)] // only the reconnect tests use it
pub async fn next_event(
    events: &mut gripper::reconnect::ConnectionEvents,
) -> Option<gripper::reconnect::ConnectionEvent> {
    use futures_util::StreamExt as _;
    within("the next connection event", events.next()).await
}

/// The connection events up to the first `Restored`, each within [`LIMIT`] (a restore that
/// hangs fails the test); how many attempts it took.
#[allow(dead_code)] // only the reconnect tests use it
pub async fn restored_after(events: &mut gripper::reconnect::ConnectionEvents) -> u32 {
    use gripper::reconnect::ConnectionEvent;
    let got = events_until(events, |e| matches!(e, ConnectionEvent::Restored { .. })).await;
    match got.last() {
        Some(ConnectionEvent::Restored { attempts }) => *attempts,
        other => panic!("not restored: {other:?}"),
    }
}

/// The next connection events, up to and including the first that `last` accepts; panics if
/// the stream ends first.
#[allow(dead_code)] // only the reconnect tests use it
pub async fn events_until(
    events: &mut gripper::reconnect::ConnectionEvents,
    last: impl Fn(&gripper::reconnect::ConnectionEvent) -> bool,
) -> Vec<gripper::reconnect::ConnectionEvent> {
    let mut got = Vec::new();
    while let Some(event) = next_event(events).await {
        let done = last(&event);
        got.push(event);
        if done {
            return got;
        }
    }
    panic!("the event stream ended after {got:?}");
}

/// Pulls the cable (`proxy.cut_connections()`) and reads `events` until the client has restored
/// the connection, holding it to the reconnect contract's first promise on the way: `Lost`
/// first, then a `Connected`, and `Restored { attempts: 1 }` last. The contract suite and each
/// protocol's own reconnect suite start from this same checked reconnect before looking at what
/// their protocol restores.
#[cfg(feature = "sim")]
#[allow(dead_code)] // only the reconnect tests use it
pub async fn cut_and_restored(
    proxy: &gripper::fault::FaultProxy,
    events: &mut gripper::reconnect::ConnectionEvents,
) {
    use gripper::reconnect::ConnectionEvent;
    proxy.cut_connections();
    let got = events_until(events, |e| matches!(e, ConnectionEvent::Restored { .. })).await;
    assert!(
        matches!(got.first(), Some(ConnectionEvent::Lost { .. })),
        "{got:?}"
    );
    assert!(got.contains(&ConnectionEvent::Connected), "{got:?}");
    assert_eq!(got.last(), Some(&ConnectionEvent::Restored { attempts: 1 }));
}

/// A raw WSG "gripper" on loopback TCP serving one connection: it reads the client's request
/// frames and answers them one after the other, in order, as the device's command interpreter
/// does. `answer(request)` gives what to write for a request; the next request is read only
/// once that is written, so an answer that takes its time stalls the ones behind it, as a slow
/// device does. Ends when the client closes the connection or a write fails.
#[allow(dead_code)] // only the raw-socket WSG tests use it
pub async fn wsg_tcp_device<F>(
    mut answer: impl FnMut(gripper::wsg::frame::Frame) -> F + Send + 'static,
) -> std::net::SocketAddr
where
    F: std::future::Future<Output = Vec<u8>> + Send + 'static,
{
    use futures_util::StreamExt;
    use tokio::io::AsyncWriteExt;
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    tokio::spawn(async move {
        let (socket, _) = listener.accept().await.unwrap();
        let (read, mut write) = socket.into_split();
        let mut requests = tokio_util::codec::FramedRead::new(read, gripper::wsg::WsgCodec::new());
        while let Some(Ok(request)) = requests.next().await {
            let bytes = answer(request).await;
            if write.write_all(&bytes).await.is_err() {
                return;
            }
        }
    });
    addr
}

/// The WSG simulator with `config` and a client of it subscribed to the width every 10 ms, with
/// a subscription buffer of 4 updates: small, so a test soon sees what a full buffer does to
/// updates not read (missed and counted) and, reading more items than it holds, that new
/// updates arrive.
#[cfg(feature = "sim")]
#[allow(dead_code)] // only the WSG subscription tests use it
pub async fn wsg_width_subscription(
    config: gripper::wsg::sim::SimConfig,
) -> (
    gripper::wsg::sim::SimServer,
    gripper::wsg::Client,
    gripper::wsg::Subscription<f32>,
) {
    let sim = gripper::wsg::sim::SimServer::bind("127.0.0.1:0", config)
        .await
        .unwrap();
    let client = gripper::wsg::Client::builder()
        .subscription_buffer(4)
        .connect_tcp(sim.local_addr().unwrap())
        .await
        .unwrap();
    let widths = client
        .subscribe_width_mm(gripper::wsg::UpdateOptions::periodic(
            std::time::Duration::from_millis(10),
        ))
        .await
        .unwrap();
    (sim, client, widths)
}

/// The WSG simulator with `config` and a fault proxy before it that cuts the byte stream into
/// WSG frames (`wsg::frame::frame_len`), so that a fault can target one frame; the client under
/// test connects to the proxy.
#[cfg(feature = "sim")]
#[allow(dead_code)] // only the WSG tests through the fault proxy use it
pub async fn wsg_sim_behind_proxy(
    config: gripper::wsg::sim::SimConfig,
) -> (gripper::wsg::sim::SimServer, gripper::fault::FaultProxy) {
    use gripper::fault::{FaultProxy, Framing, ProxyConfig};
    let sim = gripper::wsg::sim::SimServer::bind("127.0.0.1:0", config)
        .await
        .unwrap();
    let proxy = FaultProxy::start_with(
        sim.local_addr().unwrap(),
        ProxyConfig::new().framing(Framing::Custom(gripper::wsg::frame::frame_len)),
    )
    .await
    .unwrap();
    (sim, proxy)
}
