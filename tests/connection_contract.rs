//! The reconnect contract, run against every client (the WSG binary client, the WSG text client,
//! GRIPLINK, SmartGrasp): they share one connection supervisor (`src/supervisor.rs`), and this
//! suite holds each of them to what it promises, the same way. The reconnect contract:
//!
//! - a cut connection is reported (`Lost`), reconnected (`Connected`) and restored
//!   (`Restored { attempts: 1 }`), and calls work again on the new connection;
//! - without a policy a loss closes the client for good: the event stream ends after `Lost`, and
//!   every later call fails with the protocol's `ConnectionLost`;
//! - a policy that gives up (one `Reconnecting` per attempt, then `GaveUp { attempts: 2 }`)
//!   closes the client like one without.
//!
//! And the cancel contract:
//!
//! - calls dropped at any await point (`select!`, `timeout`) never disturb another caller's
//!   calls, and the connection stays healthy: no loss, no reconnect, the next call is served;
//! - dropping every handle closes the connection;
//! - `close()` while a call waits ends both, and every later call fails with `Closed`; whether
//!   the waiting call still gets the reply it asked for is the protocol's (SmartGrasp fails it at
//!   once, the others answer it before their own close request);
//! - `close()` during a long reconnect backoff returns promptly with `Ok` (there is no
//!   connection to say goodbye on), the client is closed, and every later call fails with
//!   `Closed`.
//!
//! Each protocol's own suites check what it restores (tests/*_reconnect.rs) and what a dropped
//! call of its own means on the device, with replies that name their request so one handed to
//! the wrong caller is caught (tests/*_cancel.rs).
#![cfg(feature = "sim")]

mod common;

use std::future::Future;
use std::net::SocketAddr;
use std::task::Poll;
use std::time::Duration;

use common::{cut_and_restored, events_until, policy, within};
use futures_util::StreamExt as _;
use gripper::fault::{FaultProxy, Framing, ProxyConfig};
use gripper::reconnect::{ConnectionEvent, ConnectionEvents, ReconnectPolicy};

/// How a call ended, in the terms of the contract.
#[derive(Debug, PartialEq, Eq)]
enum Outcome {
    Ok,
    ConnectionLost,
    Closed,
    Other(String),
}

/// One protocol's client, as the contract sees it.
trait Contracted: Sized {
    /// The simulator (kept alive by the test).
    type Sim;
    /// How the fault proxy cuts the protocol's byte stream into frames.
    fn framing() -> Framing;
    /// A simulator on a loopback port.
    async fn sim() -> (Self::Sim, SocketAddr);
    /// A client connected to `addr` with `policy`.
    async fn connect(addr: SocketAddr, policy: Option<ReconnectPolicy>) -> Self;
    /// A query the device answers at once.
    async fn query(&self) -> Outcome;
    fn events(&self) -> ConnectionEvents;
    /// `close()`, as the contract sees its end.
    async fn close(&self) -> Outcome;
    /// Whether the client is closed for good.
    fn is_closed(&self) -> bool;
    /// Whether `close()` fails the calls waiting for a reply at once (SmartGrasp: no message
    /// ends a session, the socket is simply closed, manual 3.3), rather than letting the
    /// replies already asked for arrive first (the WSG's disconnect announcement and the
    /// `BYE()` of GRIPLINK and the text client wait for their own reply, behind the others).
    const CLOSE_FAILS_WAITING_CALLS: bool;
}

/// A simulator, a proxy to pull the cable with, and a client through it.
async fn proxied<C: Contracted>(
    policy: Option<ReconnectPolicy>,
) -> (C::Sim, FaultProxy, C, ConnectionEvents) {
    let (sim, addr) = C::sim().await;
    let proxy = FaultProxy::start_with(addr, ProxyConfig::new().framing(C::framing()))
        .await
        .unwrap();
    let client = within("connect", C::connect(proxy.local_addr(), policy)).await;
    let events = client.events();
    (sim, proxy, client, events)
}

async fn a_cut_is_reported_reconnected_and_restored<C: Contracted>() {
    let (_sim, proxy, client, mut events) = proxied::<C>(Some(policy(None))).await;
    assert_eq!(within("query", client.query()).await, Outcome::Ok);
    cut_and_restored(&proxy, &mut events).await;
    assert_eq!(within("query", client.query()).await, Outcome::Ok);
    assert_eq!(proxy.stats().connections_accepted, 2);
}

async fn without_a_policy_a_loss_closes_for_good<C: Contracted>() {
    let (_sim, proxy, client, mut events) = proxied::<C>(None).await;
    assert_eq!(within("query", client.query()).await, Outcome::Ok);
    proxy.cut_connections();
    let got = events_until(&mut events, |e| matches!(e, ConnectionEvent::Lost { .. })).await;
    assert_eq!(got.len(), 1, "{got:?}");
    assert_eq!(within("the stream's end", events.next()).await, None);
    assert!(client.is_closed());
    for _ in 0..3 {
        assert_eq!(
            within("query", client.query()).await,
            Outcome::ConnectionLost
        );
    }
    assert_eq!(proxy.stats().connections_accepted, 1);
}

async fn a_policy_that_gives_up_closes_with_the_loss<C: Contracted>() {
    let (_sim, proxy, client, mut events) = proxied::<C>(Some(policy(Some(2)))).await;
    assert_eq!(within("query", client.query()).await, Outcome::Ok);
    // Nothing to reconnect to: the proxy the client connects through is gone.
    within("the proxy's shutdown", proxy.shutdown()).await;
    let got = events_until(&mut events, |e| matches!(e, ConnectionEvent::GaveUp { .. })).await;
    let attempts: Vec<u32> = got
        .iter()
        .filter_map(|e| match e {
            ConnectionEvent::Reconnecting { attempt, .. } => Some(*attempt),
            _ => None,
        })
        .collect();
    assert_eq!(attempts, [1, 2], "{got:?}");
    assert!(!got.contains(&ConnectionEvent::Connected), "{got:?}");
    assert_eq!(got.last(), Some(&ConnectionEvent::GaveUp { attempts: 2 }));
    assert_eq!(within("the stream's end", events.next()).await, None);
    assert!(client.is_closed());
    assert_eq!(
        within("query", client.query()).await,
        Outcome::ConnectionLost
    );
}

/// Polls `call` at most `polls` times, then drops it (a caller's `select!` or `timeout` taking
/// the other branch at one of the call's await points). Whether it completed first.
async fn poll_then_drop<F: Future>(call: F, polls: usize) -> bool {
    let mut call = std::pin::pin!(call);
    for _ in 0..polls {
        let ready = std::future::poll_fn(|cx| Poll::Ready(call.as_mut().poll(cx).is_ready())).await;
        if ready {
            return true;
        }
        tokio::task::yield_now().await;
    }
    false
}

/// The cancel contract: calls dropped at every await point, while another caller keeps calling,
/// never disturb the other caller, leave the connection healthy (no loss, no reconnect), and the
/// next call of the same kind is served.
async fn a_dropped_call_leaves_the_connection_healthy<C: Contracted>() {
    // Without a policy a loss would close the client: every later call would fail.
    let (_sim, proxy, client, _events) = proxied::<C>(None).await;
    let sent_before = proxy.stats().client_to_server.frames;
    let steady = async {
        for _ in 0..40 {
            assert_eq!(within("steady query", client.query()).await, Outcome::Ok);
        }
    };
    let dropper = async {
        for polls in 0..40 {
            poll_then_drop(client.query(), polls % 12).await;
            // Also dropped by a timer, as `tokio::time::timeout` does.
            let _ = tokio::time::timeout(Duration::from_micros(polls as u64 * 50), client.query())
                .await;
        }
    };
    within("the calls", async { tokio::join!(steady, dropper) }).await;
    assert_eq!(within("query", client.query()).await, Outcome::Ok);
    // Some dropped calls were on the wire when dropped (more requests than the 41 kept calls):
    // their replies came to a connection whose callers had moved on.
    let sent = proxy.stats().client_to_server.frames - sent_before;
    assert!(
        sent > 41,
        "no dropped call reached the wire ({sent} requests)"
    );
    assert!(!client.is_closed());
    assert_eq!(proxy.stats().connections_accepted, 1);
    assert_eq!(proxy.stats().connections_cut, 0);
}

/// Dropping every handle (the events stream included) closes the connection.
async fn dropping_every_handle_closes_the_connection<C: Contracted>() {
    let (_sim, proxy, client, events) = proxied::<C>(None).await;
    assert_eq!(within("query", client.query()).await, Outcome::Ok);
    assert_eq!(proxy.stats().connections_open, 1);
    drop(events);
    drop(client);
    within(
        "the connection's close",
        proxy.wait_for_stats(|s| s.connections_open == 0),
    )
    .await;
}

/// `close()` while a call waits for its reply: the protocol decides whether the reply asked for
/// still arrives ([`Contracted::CLOSE_FAILS_WAITING_CALLS`]); either way the call ends, `close()`
/// returns, and every later call fails with `Closed`.
async fn close_while_a_call_waits<C: Contracted>() {
    let (_sim, proxy, client, _events) = proxied::<C>(None).await;
    assert_eq!(within("query", client.query()).await, Outcome::Ok);
    let replies = proxy.server_to_client();
    replies.stall();
    let requests = proxy.client_to_server();
    let sent = requests.stats().frames;
    let mut waiting = std::pin::pin!(client.query());
    tokio::select! {
        biased;
        outcome = waiting.as_mut() => panic!("answered through a stalled wire: {outcome:?}"),
        _ = requests.wait_for(|s| s.frames > sent) => {}
    }
    if C::CLOSE_FAILS_WAITING_CALLS {
        assert_eq!(within("close", client.close()).await, Outcome::Ok);
        assert_eq!(within("the waiting call", waiting).await, Outcome::Closed);
        replies.release();
    } else {
        let release = async {
            tokio::task::yield_now().await;
            replies.release();
        };
        let (answered, closed, ()) = within("close", async {
            tokio::join!(waiting, client.close(), release)
        })
        .await;
        assert_eq!(answered, Outcome::Ok);
        assert_eq!(closed, Outcome::Ok);
    }
    assert!(client.is_closed());
    assert_eq!(within("query", client.query()).await, Outcome::Closed);
}

/// What a user needs of `close()` while the client waits out a long reconnect backoff: it
/// returns promptly (not after the backoff) with `Ok`, and the client is closed (`Closed`, not
/// the loss: the program ended it).
async fn close_during_a_backoff_returns_promptly<C: Contracted>() {
    let hour = Duration::from_secs(3600);
    let long = ReconnectPolicy {
        initial_delay: hour,
        max_delay: hour,
        factor: 1.0,
        max_attempts: None,
    };
    let (_sim, proxy, client, mut events) = proxied::<C>(Some(long)).await;
    assert_eq!(within("query", client.query()).await, Outcome::Ok);
    within("the proxy's shutdown", proxy.shutdown()).await;
    events_until(&mut events, |e| {
        matches!(e, ConnectionEvent::Reconnecting { .. })
    })
    .await;
    let closed = tokio::time::timeout(Duration::from_secs(5), client.close())
        .await
        .expect("close() waited out the backoff");
    assert_eq!(closed, Outcome::Ok);
    assert!(client.is_closed());
    assert_eq!(within("query", client.query()).await, Outcome::Closed);
}

/// The contract's tests for one protocol.
macro_rules! contract {
    ($client:ty) => {
        #[tokio::test]
        async fn a_cut_is_reported_reconnected_and_restored() {
            super::a_cut_is_reported_reconnected_and_restored::<$client>().await;
        }

        #[tokio::test]
        async fn without_a_policy_a_loss_closes_for_good() {
            super::without_a_policy_a_loss_closes_for_good::<$client>().await;
        }

        #[tokio::test]
        async fn a_policy_that_gives_up_closes_with_the_loss() {
            super::a_policy_that_gives_up_closes_with_the_loss::<$client>().await;
        }

        #[tokio::test]
        async fn a_dropped_call_leaves_the_connection_healthy() {
            super::a_dropped_call_leaves_the_connection_healthy::<$client>().await;
        }

        #[tokio::test]
        async fn dropping_every_handle_closes_the_connection() {
            super::dropping_every_handle_closes_the_connection::<$client>().await;
        }

        #[tokio::test]
        async fn close_while_a_call_waits() {
            super::close_while_a_call_waits::<$client>().await;
        }

        #[tokio::test]
        async fn close_during_a_backoff_returns_promptly() {
            super::close_during_a_backoff_returns_promptly::<$client>().await;
        }
    };
}

/// The handle's methods every client spells the same way (`connection_events`, `close`,
/// `is_closed`), inside a `Contracted` impl.
macro_rules! handle {
    (close_fails_waiting_calls = $cut:literal) => {
        fn events(&self) -> ConnectionEvents {
            self.connection_events()
        }

        async fn close(&self) -> Outcome {
            match Client::close(self).await {
                Ok(()) => Outcome::Ok,
                Err(error) => outcome(error),
            }
        }

        fn is_closed(&self) -> bool {
            Client::is_closed(self)
        }

        const CLOSE_FAILS_WAITING_CALLS: bool = $cut;
    };
}

/// `outcome(error)`: how a call of the protocol's `Error` ended, in the terms of the contract
/// (each protocol's enum has the same variants for the connection's end).
macro_rules! outcome {
    () => {
        fn outcome(error: Error) -> Outcome {
            match error {
                Error::ConnectionLost { .. } => Outcome::ConnectionLost,
                Error::Closed => Outcome::Closed,
                other => Outcome::Other(format!("{other:?}")),
            }
        }
    };
}

mod wsg {
    use super::*;
    use gripper::wsg::sim::{Model, SimConfig, SimServer};
    use gripper::wsg::{Client, Error};

    impl Contracted for Client {
        type Sim = SimServer;

        fn framing() -> Framing {
            Framing::Custom(gripper::wsg::frame::frame_len)
        }

        async fn sim() -> (SimServer, SocketAddr) {
            let sim = SimServer::bind("127.0.0.1:0", SimConfig::new(Model::Wsg50))
                .await
                .unwrap();
            let addr = sim.local_addr().unwrap();
            (sim, addr)
        }

        async fn connect(addr: SocketAddr, policy: Option<ReconnectPolicy>) -> Client {
            let builder = Client::builder();
            let builder = match policy {
                Some(policy) => builder.reconnect(policy),
                None => builder,
            };
            builder.connect_tcp(addr).await.unwrap()
        }

        async fn query(&self) -> Outcome {
            match self.width_mm().await {
                Ok(_) => Outcome::Ok,
                Err(error) => outcome(error),
            }
        }

        handle!(close_fails_waiting_calls = false);
    }

    outcome!();

    contract!(Client);
}

mod wsg_text {
    use super::*;
    use gripper::wsg::sim::{Model, SimConfig, SimServer};
    use gripper::wsg::text::{Client, ClientConfig, Error};

    impl Contracted for Client {
        type Sim = SimServer;

        fn framing() -> Framing {
            Framing::Delimited(b'\n')
        }

        async fn sim() -> (SimServer, SocketAddr) {
            let sim = SimServer::bind("127.0.0.1:0", SimConfig::new(Model::Wsg50).text())
                .await
                .unwrap();
            let addr = sim.local_addr().unwrap();
            (sim, addr)
        }

        async fn connect(addr: SocketAddr, reconnect: Option<ReconnectPolicy>) -> Client {
            let config = ClientConfig {
                reconnect,
                ..ClientConfig::default()
            };
            Client::connect_with(addr, config).await.unwrap()
        }

        async fn query(&self) -> Outcome {
            match self.position_mm().await {
                Ok(_) => Outcome::Ok,
                Err(error) => outcome(error),
            }
        }

        handle!(close_fails_waiting_calls = false);
    }

    outcome!();

    contract!(Client);
}

mod griplink {
    use super::*;
    use gripper::griplink::sim::{SimConfig, SimServer};
    use gripper::griplink::{Client, ClientConfig, Error};

    impl Contracted for Client {
        type Sim = SimServer;

        fn framing() -> Framing {
            Framing::Delimited(b'\n')
        }

        async fn sim() -> (SimServer, SocketAddr) {
            let sim = SimServer::bind("127.0.0.1:0", SimConfig::et4().time_scale(0.0))
                .await
                .unwrap();
            let addr = sim.local_addr();
            (sim, addr)
        }

        async fn connect(addr: SocketAddr, reconnect: Option<ReconnectPolicy>) -> Client {
            let config = ClientConfig {
                reconnect,
                ..ClientConfig::default()
            };
            Client::connect_with(addr, config).await.unwrap()
        }

        async fn query(&self) -> Outcome {
            match self.id().await {
                Ok(_) => Outcome::Ok,
                Err(error) => outcome(error),
            }
        }

        handle!(close_fails_waiting_calls = false);
    }

    outcome!();

    contract!(Client);
}

mod smartgrasp {
    use super::*;
    use gripper::smartgrasp::codec;
    use gripper::smartgrasp::sim::{SimConfig, SimServer};
    use gripper::smartgrasp::{Client, ClientConfig, Error, RobotSystem};

    impl Contracted for Client {
        type Sim = SimServer;

        fn framing() -> Framing {
            Framing::Custom(codec::proxy_frame_len)
        }

        async fn sim() -> (SimServer, SocketAddr) {
            let config = SimConfig {
                max_version: 3,
                ..SimConfig::default()
            };
            let sim = SimServer::bind("127.0.0.1:0", config).await.unwrap();
            let addr = sim.local_addr();
            (sim, addr)
        }

        async fn connect(addr: SocketAddr, reconnect: Option<ReconnectPolicy>) -> Client {
            let config = ClientConfig {
                robot_system: Some(RobotSystem::Kuka),
                reconnect,
                ..ClientConfig::default()
            };
            Client::connect(addr, config).await.unwrap()
        }

        async fn query(&self) -> Outcome {
            match self.get_state().await {
                Ok(_) => Outcome::Ok,
                Err(error) => outcome(error),
            }
        }

        handle!(close_fails_waiting_calls = true);
    }

    outcome!();

    contract!(Client);
}
