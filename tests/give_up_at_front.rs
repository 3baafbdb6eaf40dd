//! Issue 29 F and H: a request answered in order whose call waited behind a long one (a blocking
//! HOME, a long `with_timeout` call) has its give-up clock started when it reaches the front
//! (`src/give_up.rs`, shared by GRIPLINK and SmartGrasp). Before, its give-up time had already
//! passed when the long call was answered, and unless its own reply came in the same read, the
//! healthy connection was declared lost.
//!
//! The peer is a scripted controller over loopback: it holds the first reply for the length of a
//! motion and then takes a moment for the next one, as a real controller does (GRIPLINK); the
//! SmartGrasp simulator delays its responses on request.

use std::future::Future;
use std::time::Duration;

use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpListener;

/// Upper bound for anything that should happen promptly; only reached when a test fails.
const LIMIT: Duration = Duration::from_secs(20);

async fn within<F: Future>(what: &str, future: F) -> F::Output {
    tokio::time::timeout(LIMIT, future)
        .await
        .unwrap_or_else(|_| panic!("hung: {what}"))
}

/// Polls `future` once: its output if it is ready, `None` if it waits.
async fn poll_once<F: Future + Unpin>(mut future: F) -> Option<F::Output> {
    std::future::poll_fn(|cx| {
        std::task::Poll::Ready(match std::pin::Pin::new(&mut future).poll(cx) {
            std::task::Poll::Ready(out) => Some(out),
            std::task::Poll::Pending => None,
        })
    })
    .await
}

mod griplink {
    use super::*;
    use gripper::griplink::{Client, ClientConfig, Error};

    /// The HOME blocks the controller this long (manual 3.4.3: HOME answers when homing is done).
    const HOMING: Duration = Duration::from_millis(600);
    /// The controller's moment for the next reply.
    const MOMENT: Duration = Duration::from_millis(150);

    #[tokio::test]
    async fn a_query_behind_a_long_home_does_not_lose_the_healthy_connection() {
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let controller = tokio::spawn(async move {
            let (stream, _) = listener.accept().await.unwrap();
            let (read, mut write) = stream.into_split();
            let mut lines = BufReader::new(read).lines();
            assert_eq!(lines.next_line().await.unwrap().unwrap(), "HOME(0)");
            assert_eq!(lines.next_line().await.unwrap().unwrap(), "ID?");
            tokio::time::sleep(HOMING).await;
            write.write_all(b"ACK\n").await.unwrap();
            tokio::time::sleep(MOMENT).await;
            write.write_all(b"ID=\"GRIPLINK-ET4\"\n").await.unwrap();
            // Then every ID? at once, until BYE().
            while let Ok(Some(line)) = lines.next_line().await {
                if line == "BYE()" {
                    write.write_all(b"ACK\n").await.unwrap();
                    break;
                }
                assert_eq!(line, "ID?");
                write.write_all(b"ID=\"GRIPLINK-ET4\"\n").await.unwrap();
            }
        });
        let config = ClientConfig {
            pipeline_depth: 2,
            query_timeout: Duration::from_millis(100),
            motion_timeout: Duration::from_secs(5),
            // Shorter than the HOME: the query's give-up time counted from its call passes
            // before the HOME is answered.
            give_up_after: Duration::from_millis(300),
            ..ClientConfig::default()
        };
        let client = within("connect", Client::connect_with(addr, config))
            .await
            .unwrap();
        let port = client.port(0);
        let mut home = std::pin::pin!(port.home());
        // Polled once, HOME is written (a call polls the connection inline, and the line goes
        // out at once); its reply is awaited below.
        let first = poll_once(home.as_mut()).await;
        assert!(first.is_none(), "{first:?}");
        // The query goes out behind it, and its caller gives up while HOME holds the
        // controller: a Timeout, as documented for a call behind a blocking command.
        let query = within("the query behind HOME", client.id()).await;
        assert!(matches!(query, Err(Error::Timeout { .. })), "{query:?}");
        within("HOME", home).await.unwrap();
        // The connection is healthy: the query's late reply is consumed, and the next call
        // (with time for the controller's moment) gets its own.
        let patient = client.with_timeout(Duration::from_secs(2));
        assert_eq!(within("ID?", patient.id()).await.unwrap(), "GRIPLINK-ET4");
        assert!(!client.is_closed());
        within("close", client.close()).await.unwrap();
        within("the controller", controller).await.unwrap();
    }
}

#[cfg(feature = "sim")]
mod smartgrasp {
    use super::*;
    use gripper::smartgrasp::sim::{Fault, SimConfig, SimServer};
    use gripper::smartgrasp::{Client, ClientConfig, Error, ServerState};

    #[tokio::test]
    async fn a_short_call_behind_a_long_with_timeout_call_does_not_lose_the_healthy_connection() {
        let config = SimConfig {
            max_version: 3,
            ..SimConfig::default()
        };
        let server = SimServer::bind("127.0.0.1:0", config).await.unwrap();
        let config = ClientConfig {
            query_timeout: Duration::from_millis(100),
            // Shorter than the long call: the short call's give-up time counted from its call
            // passes before the long call is answered.
            give_up_after: Duration::from_millis(300),
            ..ClientConfig::default()
        };
        let client = within("connect", Client::connect(server.local_addr(), config))
            .await
            .unwrap();
        // The long call's response comes after 600 ms (a long detection), and the next one a
        // moment (150 ms) after it: responses stay in order.
        server.inject(Fault::DelayReply(Duration::from_millis(600)));
        server.inject(Fault::DelayReply(Duration::from_millis(150)));
        let patient = client.with_timeout(Duration::from_secs(5));
        let mut long = std::pin::pin!(patient.get_state());
        // Polled once, the long call's request is written (a call polls the connection
        // inline); its response is awaited below.
        let first = poll_once(long.as_mut()).await;
        assert!(first.is_none(), "{first:?}");
        // The short call goes out behind it, and its caller gives up while the long one runs.
        let short = within("the short call", client.get_protocol_version()).await;
        assert!(matches!(short, Err(Error::Timeout { .. })), "{short:?}");
        assert_eq!(
            within("the long call", long).await.unwrap(),
            ServerState::Operational
        );
        // The connection is healthy: the short call's late response is consumed, and the next
        // call (with time for the server's moment) gets its own.
        assert_eq!(
            within("GET_STATE", patient.get_state()).await.unwrap(),
            ServerState::Operational
        );
        assert!(!client.is_closed());
    }
}
