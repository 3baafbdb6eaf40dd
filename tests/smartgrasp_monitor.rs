//! The SmartGrasp simulator's monitor page over real loopback sockets: the scene at
//! `/monitor/latest_result`, 404 elsewhere, an oversized request refused, a silent client not
//! holding up the others, 503 once the simulator is gone.
#![cfg(feature = "sim")]

use std::time::Duration;

use gripper::smartgrasp::sim::{SimConfig, SimServer, MAX_REQUEST_BYTES, MONITOR_PATH};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

/// Bounds every wait: only turns a hang into a failure.
const PATIENCE: Duration = Duration::from_secs(30);

/// Sends `request` and reads the whole answer (the server closes after one).
async fn exchange(addr: std::net::SocketAddr, request: &[u8]) -> String {
    tokio::time::timeout(PATIENCE, async {
        let mut stream = TcpStream::connect(addr).await.expect("connect");
        stream.write_all(request).await.expect("send");
        let mut answer = Vec::new();
        // A reset after the answer (an oversized request left unread) still leaves the answer.
        let _ = stream.read_to_end(&mut answer).await;
        String::from_utf8(answer).expect("UTF-8 answer")
    })
    .await
    .expect("the monitor answers")
}

#[tokio::test]
async fn the_monitor_serves_the_scene_and_refuses_the_rest() {
    let server = SimServer::bind("127.0.0.1:0", SimConfig::default())
        .await
        .expect("bind");
    let monitor = server.serve_monitor("127.0.0.1:0").await.expect("bind");
    let addr = monitor.local_addr();

    // A client that connects and says nothing does not hold up the others.
    let _silent = TcpStream::connect(addr).await.expect("connect");

    let get = format!("GET {MONITOR_PATH} HTTP/1.1\r\nHost: sim\r\n\r\n");
    let answer = exchange(addr, get.as_bytes()).await;
    let (head, body) = answer.split_once("\r\n\r\n").expect("head and body");
    assert!(head.starts_with("HTTP/1.1 200 OK"), "{head}");
    assert!(head.contains("Content-Type: image/svg+xml"), "{head}");
    assert!(
        head.contains(&format!("Content-Length: {}", body.len())),
        "{head}"
    );
    assert_eq!(body.matches(r#"<g class="part""#).count(), 3);

    // The picture follows the scene.
    server.with_state(|s| s.projects_mut()[0].scene.truncate(1));
    let answer = exchange(addr, get.as_bytes()).await;
    assert_eq!(answer.matches(r#"<g class="part""#).count(), 1);

    let answer = exchange(addr, b"GET /index.html HTTP/1.1\r\n\r\n").await;
    assert!(answer.starts_with("HTTP/1.1 404 Not Found"), "{answer}");

    let mut huge = format!("GET {MONITOR_PATH} HTTP/1.1\r\nX-Pad: ").into_bytes();
    huge.resize(MAX_REQUEST_BYTES + 100, b'a');
    let answer = exchange(addr, &huge).await;
    assert!(answer.starts_with("HTTP/1.1 431"), "{answer}");

    // The simulator's tasks let go of its state once the runtime has dropped them: until then
    // the picture is still served, after that 503.
    drop(server);
    let gone = tokio::time::timeout(PATIENCE, async {
        loop {
            let answer = exchange(addr, get.as_bytes()).await;
            if !answer.starts_with("HTTP/1.1 200") {
                return answer;
            }
            tokio::task::yield_now().await;
        }
    })
    .await
    .expect("the monitor notices the simulator is gone");
    assert!(gone.starts_with("HTTP/1.1 503"), "{gone}");
}
