//! A pick with a GRIPLINK controller: identify it, find the devices on its ports, home the
//! gripper, write a grip recipe, grip while printing the finger position, release, BYE.
//!
//! ```text
//! cargo run --example griplink_pick                       # against an in-process simulator
//! cargo run --example griplink_pick -- --addr 192.168.1.40:10001
//! ```
//! Exits 0 when the part was gripped and released, 1 with a one-line message otherwise.

use std::process::ExitCode;
use std::time::Duration;

use futures_util::StreamExt as _;
use gripper::griplink::client::{GripOutcome, ReleaseOutcome, WaitBy};
use gripper::griplink::command::{GripConfigF, MAX_PORT};
use gripper::griplink::sim::{SimConfig, SimDevice, SimServer};
use gripper::griplink::{Client, Status};

/// The recipe index this example writes and uses.
const RECIPE: u32 = 0;

fn parse_args() -> Result<Option<String>, String> {
    let mut addr = None;
    let mut it = std::env::args().skip(1);
    while let Some(arg) = it.next() {
        match arg.as_str() {
            "--addr" => addr = Some(it.next().ok_or("--addr needs HOST:PORT")?),
            other => {
                return Err(format!(
                    "unknown argument {other:?} (usage: griplink_pick [--addr HOST:PORT])"
                ))
            }
        }
    }
    Ok(addr)
}

async fn pick(client: &Client) -> Result<(), Box<dyn std::error::Error>> {
    println!(
        "controller: {} ({}), firmware {}",
        client.id().await?,
        client.protocol().await?,
        client.version().await?
    );
    client.protocol_assert("GRIPLINK", 2).await?;
    println!("protocol GRIPLINK >= 2 asserted");

    // Walk the ports until the controller says the index is out of range.
    let mut gripper = None;
    for number in 0..=MAX_PORT {
        let port = client.port(number);
        match port.vendor_id().await {
            Ok(None) => println!("port {number}: empty"),
            Ok(Some(vid)) => {
                let (pid, name) = (port.product_id().await?, port.name().await?);
                println!("port {number}: {name} (vendor {vid}, product {pid})");
                gripper.get_or_insert(port);
            }
            Err(e) if e.status() == Some(Status::IndexOutOfBounds) => break,
            Err(e) => return Err(e.into()),
        }
    }
    let gripper = gripper.ok_or("no device found on any port")?;
    let number = gripper.number();

    println!("port {number}: homing");
    gripper.home().await?;
    let open_mm = gripper.position_mm().await?;
    println!("port {number}: homed, fingers at {open_mm} mm");

    let recipe = GripConfigF::gripper("pick", 1.0, open_mm, 50.0);
    let written = gripper.set_grip_config_f(RECIPE, &recipe).await?;
    println!("port {number}: recipe {RECIPE} = {written:?}");

    // Grip and wait for the outcome while a stream prints the finger position: both poll over
    // the same connection, their requests interleaved by the client.
    let mut positions = gripper.watch_value(0, Duration::from_millis(20));
    let grip = gripper.grip_and_wait(RECIPE, WaitBy::Polling(Duration::from_millis(10)));
    tokio::pin!(grip);
    let outcome = loop {
        tokio::select! {
            outcome = &mut grip => break outcome?,
            Some(Ok(mm)) = positions.next() => println!("port {number}: fingers at {mm} mm"),
        }
    };
    drop(positions);
    match outcome {
        GripOutcome::Holding => println!(
            "port {number}: holding the part at {} mm",
            gripper.position_mm().await?
        ),
        GripOutcome::NoPart => return Err("no part between the fingers".into()),
        GripOutcome::Fault => return Err("the gripper faulted while gripping".into()),
    }

    match gripper.release_and_wait(RECIPE, WaitBy::Transition).await? {
        ReleaseOutcome::Released => println!(
            "port {number}: released, fingers at {} mm",
            gripper.position_mm().await?
        ),
        ReleaseOutcome::Fault => return Err("the gripper faulted while releasing".into()),
    }
    client.close().await?;
    println!("BYE acknowledged");
    Ok(())
}

async fn run() -> Result<(), Box<dyn std::error::Error>> {
    let (client, _server) = match parse_args()? {
        Some(addr) => {
            println!("connecting to {addr}");
            (Client::connect(addr.as_str()).await?, None)
        }
        None => {
            // A simulated GRIPLINK-ET4 with a 12 mm part in the IEG 55-020 on port 0; motion at
            // a tenth of real time.
            let config = SimConfig::et4()
                .device(0, Some(SimDevice::ieg_55_020().with_part(12.0)))
                .time_scale(0.1);
            let server = SimServer::bind("127.0.0.1:0", config).await?;
            println!("simulated controller on {}", server.local_addr());
            (Client::connect(server.local_addr()).await?, Some(server))
        }
    };
    pick(&client).await
}

#[tokio::main]
async fn main() -> ExitCode {
    match run().await {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("griplink_pick: {e}");
            ExitCode::FAILURE
        }
    }
}
