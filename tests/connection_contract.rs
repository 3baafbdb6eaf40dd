//! The reconnect contract, run against every client (the WSG binary client, the WSG text client,
//! GRIPLINK, SmartGrasp): they share one connection supervisor (`src/supervisor.rs`), and this
//! suite holds each of them to what it promises, the same way:
//!
//! - a cut connection is reported (`Lost`), reconnected (`Connected`) and restored
//!   (`Restored { attempts: 1 }`), and calls work again on the new connection;
//! - without a policy a loss closes the client for good: the event stream ends after `Lost`, and
//!   every later call fails with the protocol's `ConnectionLost`;
//! - a policy that gives up (`GaveUp { attempts: 2 }`) closes the client like one without.
//!
//! Each protocol's own suite (tests/*_reconnect.rs) checks what it restores.
#![cfg(feature = "sim")]

use std::future::Future;
use std::net::SocketAddr;
use std::time::Duration;

use futures_util::StreamExt as _;
use gripper::fault::{FaultProxy, Framing, ProxyConfig};
use gripper::reconnect::{ConnectionEvent, ConnectionEvents, ReconnectPolicy};

/// Upper bound for anything that should happen promptly; only reached when a test fails.
const LIMIT: Duration = Duration::from_secs(20);

async fn within<F: Future>(what: &str, future: F) -> F::Output {
    tokio::time::timeout(LIMIT, future)
        .await
        .unwrap_or_else(|_| panic!("hung: {what}"))
}

fn policy(max_attempts: Option<u32>) -> ReconnectPolicy {
    ReconnectPolicy {
        initial_delay: Duration::from_millis(5),
        max_delay: Duration::from_millis(20),
        factor: 2.0,
        max_attempts,
    }
}

/// How a call ended, in the terms of the contract.
#[derive(Debug, PartialEq, Eq)]
enum Outcome {
    Ok,
    ConnectionLost,
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

/// The next events, up to and including the first that `last` accepts.
async fn events_until(
    events: &mut ConnectionEvents,
    last: impl Fn(&ConnectionEvent) -> bool,
) -> Vec<ConnectionEvent> {
    let mut got = Vec::new();
    while let Some(event) = within("event", events.next()).await {
        let done = last(&event);
        got.push(event);
        if done {
            return got;
        }
    }
    panic!("the event stream ended after {got:?}");
}

async fn a_cut_is_reported_reconnected_and_restored<C: Contracted>() {
    let (_sim, proxy, client, mut events) = proxied::<C>(Some(policy(None))).await;
    assert_eq!(within("query", client.query()).await, Outcome::Ok);
    proxy.cut_connections();
    let got = events_until(&mut events, |e| {
        matches!(e, ConnectionEvent::Restored { .. })
    })
    .await;
    assert!(
        matches!(got.first(), Some(ConnectionEvent::Lost { .. })),
        "{got:?}"
    );
    assert!(got.contains(&ConnectionEvent::Connected), "{got:?}");
    assert_eq!(got.last(), Some(&ConnectionEvent::Restored { attempts: 1 }));
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
    assert_eq!(got.last(), Some(&ConnectionEvent::GaveUp { attempts: 2 }));
    assert_eq!(within("the stream's end", events.next()).await, None);
    assert_eq!(
        within("query", client.query()).await,
        Outcome::ConnectionLost
    );
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
                Err(Error::ConnectionLost { .. }) => Outcome::ConnectionLost,
                Err(other) => Outcome::Other(format!("{other:?}")),
            }
        }

        fn events(&self) -> ConnectionEvents {
            self.connection_events()
        }
    }

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
                Err(Error::ConnectionLost { .. }) => Outcome::ConnectionLost,
                Err(other) => Outcome::Other(format!("{other:?}")),
            }
        }

        fn events(&self) -> ConnectionEvents {
            self.connection_events()
        }
    }

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
                Err(Error::ConnectionLost { .. }) => Outcome::ConnectionLost,
                Err(other) => Outcome::Other(format!("{other:?}")),
            }
        }

        fn events(&self) -> ConnectionEvents {
            self.connection_events()
        }
    }

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
                Err(Error::ConnectionLost { .. }) => Outcome::ConnectionLost,
                Err(other) => Outcome::Other(format!("{other:?}")),
            }
        }

        fn events(&self) -> ConnectionEvents {
            self.connection_events()
        }
    }

    contract!(Client);
}
