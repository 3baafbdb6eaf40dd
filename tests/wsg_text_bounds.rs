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
