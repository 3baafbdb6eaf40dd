//! SmartGrasp client findings of issue 21, section 2, over loopback against the simulator or a
//! scripted server: a call's own timeout bounds its give-up, no legitimate answer is dropped as
//! a "repeat", a V3 GET_GRASP response may declare another pose format, and calls queued across
//! a reconnect speak the version that reconnect negotiated.
//!
//! Real clock (a paused one would fire the client's timeouts while the runtime waits on the
//! sockets); every wait is bounded by [`LIMIT`], which only a failing test reaches.
#![cfg(feature = "sim")]

use std::future::Future;
use std::time::Duration;

use gripper::reconnect::ReconnectPolicy;
use gripper::smartgrasp::sim::{Fault, SimConfig, SimServer};
use gripper::smartgrasp::{Client, ClientConfig, RobotSystem, ServerState};

/// Only reached when something hangs (a bug).
const LIMIT: Duration = Duration::from_secs(10);

async fn within<F: Future>(what: &str, future: F) -> F::Output {
    tokio::time::timeout(LIMIT, future)
        .await
        .unwrap_or_else(|_| panic!("hung: {what}"))
}

// ---- 2.1: a call's own timeout bounds its give-up --------------------------------------------

/// A handle with a longer timeout (`with_timeout`) for a slow request: the connection is not
/// given up at the configured timeout plus `give_up_after`, but at the call's own timeout plus
/// `give_up_after`, as GRIPLINK does; with reconnect on, the session is not re-opened under it.
#[tokio::test]
async fn a_longer_call_timeout_is_not_cut_short_by_the_configured_one() {
    for reconnect in [None, Some(ReconnectPolicy::default())] {
        let server = SimServer::bind("127.0.0.1:0", SimConfig::default())
            .await
            .unwrap();
        let config = ClientConfig {
            robot_system: Some(RobotSystem::Ur),
            query_timeout: Duration::from_millis(50),
            detection_timeout: Duration::from_millis(50),
            give_up_after: Duration::from_millis(50),
            reconnect,
            ..ClientConfig::default()
        };
        let client = within("connect", Client::connect(server.local_addr(), config))
            .await
            .unwrap();
        // Three times the configured timeout plus give_up_after.
        server.inject(Fault::DelayReply(Duration::from_millis(300)));
        let slow = client.with_timeout(Duration::from_secs(5));
        let state = within("slow call", slow.get_state()).await;
        assert_eq!(state.unwrap(), ServerState::Operational, "{reconnect:?}");
        assert_eq!(
            server.registered_clients(),
            [RobotSystem::Ur],
            "{reconnect:?}: the session was opened again"
        );
        assert_eq!(
            within("next", client.get_state()).await.unwrap(),
            ServerState::Operational
        );
    }
}
