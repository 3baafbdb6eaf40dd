//! Picks a part with a WSG gripper: connect, read system info and limits, home, pre-position,
//! grasp, watch width / force / grip state while holding, release, disconnect gracefully.
//!
//! ```text
//! cargo run --example wsg_pick                          # against an in-process simulator
//! cargo run --example wsg_pick -- --addr 192.168.1.20:1000
//! cargo run --example wsg_pick -- --udp 192.168.1.20:1000
//! cargo run --example wsg_pick -- --serial /dev/ttyUSB0 [--baud 115200] [--shared]
//!     [--shared]     open the port without an exclusive lock (the simulator's --pty needs it)
//!     [--width MM]   nominal part width (default 40)
//! cargo run --example wsg_pick -- --text [--addr 192.168.1.20:1000]
//!     the text interface (GCL) instead: an in-process text simulator, or a gripper set to
//!     "Use text based interface"
//! ```

use std::net::SocketAddr;
use std::process::ExitCode;
use std::time::Duration;

use futures_util::StreamExt;
use gripper::wsg::sim::{Model, SimConfig, SimServer};
use gripper::wsg::{Client, GripState, HomingDirection, SystemState, UpdateOptions};

enum Target {
    Simulator,
    Tcp(String),
    Udp(SocketAddr),
    Serial {
        path: String,
        baud: u32,
        exclusive: bool,
    },
}

struct Args {
    target: Target,
    width_mm: f32,
    text: bool,
}

fn parse() -> Result<Args, String> {
    let mut target = Target::Simulator;
    let mut baud = gripper::wsg::transport::DEFAULT_BAUD_RATE;
    let mut width_mm = 40.0;
    let mut exclusive = true;
    let mut text = false;
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().ok_or_else(|| format!("{name} needs a value"));
        match a.as_str() {
            "--addr" => {
                let mut addr = value("--addr")?;
                if !addr.contains(':') {
                    // The WSG's default TCP port.
                    addr = format!("{addr}:{}", gripper::wsg::DEFAULT_PORT);
                }
                target = Target::Tcp(addr);
            }
            "--udp" => {
                let v = value("--udp")?;
                target = Target::Udp(v.parse().map_err(|e| format!("--udp {v}: {e}"))?);
            }
            "--serial" => target = Target::Serial { path: value("--serial")?, baud: 0, exclusive: true },
            "--shared" => exclusive = false,
            "--text" => text = true,
            "--baud" => baud = value("--baud")?.parse().map_err(|e| format!("--baud: {e}"))?,
            "--width" => width_mm = value("--width")?.parse().map_err(|e| format!("--width: {e}"))?,
            "-h" | "--help" => {
                return Err("usage: wsg_pick [--addr HOST:PORT | --udp HOST:PORT | --serial PATH [--baud N] [--shared]] [--width MM] [--text]".into())
            }
            other => return Err(format!("unknown argument {other} (try --help)")),
        }
    }
    if let Target::Serial {
        baud: b,
        exclusive: x,
        ..
    } = &mut target
    {
        *b = baud;
        *x = exclusive;
    }
    if text && !matches!(target, Target::Simulator | Target::Tcp(_)) {
        return Err("--text works over TCP only".into());
    }
    Ok(Args {
        target,
        width_mm,
        text,
    })
}

async fn connect(target: Target) -> Result<(Client, Option<SimServer>), String> {
    let e = |e: gripper::wsg::Error| e.to_string();
    Ok(match target {
        Target::Simulator => {
            let sim = SimServer::bind(
                "127.0.0.1:0",
                SimConfig::new(Model::Wsg50).with_part(40.0, 2.0),
            )
            .await
            .map_err(|e| format!("cannot start the simulator: {e}"))?;
            let addr = sim.local_addr().ok_or("the simulator has no address")?;
            println!("started the simulator on {addr}");
            (Client::connect_tcp(addr).await.map_err(e)?, Some(sim))
        }
        Target::Tcp(addr) => (Client::connect_tcp(addr.as_str()).await.map_err(e)?, None),
        Target::Udp(addr) => (Client::builder().connect_udp(addr).await.map_err(e)?, None),
        Target::Serial {
            path,
            baud,
            exclusive,
        } => serial(&path, baud, exclusive).map(|c| (c, None))?,
    })
}

#[cfg(feature = "serial")]
fn serial(path: &str, baud: u32, exclusive: bool) -> Result<Client, String> {
    Client::builder()
        .serial_exclusive(exclusive)
        .open_serial(path, baud)
        .map_err(|e| format!("{path}: {e}"))
}

#[cfg(not(feature = "serial"))]
fn serial(_: &str, _: u32, _: bool) -> Result<Client, String> {
    Err("built without the `serial` feature".into())
}

async fn pick(gripper: &Client, width_mm: f32) -> Result<(), Box<dyn std::error::Error>> {
    let info = gripper.system_info().await?;
    println!(
        "gripper: {:?}, hardware rev {}, firmware {}, serial {}",
        info.device_type, info.hardware_revision, info.firmware, info.serial_number
    );
    let limits = gripper.system_limits().await?;
    println!(
        "limits: stroke {} mm, speed {}..{} mm/s, force {}..{} N",
        limits.stroke_mm,
        limits.min_speed_mm_per_s,
        limits.max_speed_mm_per_s,
        limits.min_force_n,
        limits.nominal_force_n
    );
    if gripper
        .system_state()
        .await?
        .contains(SystemState::FAST_STOP)
    {
        // Never acknowledged blindly: a FAST STOP has a cause (an earlier program closed TCP
        // without announcing it, a fault, an emergency) someone has to look at.
        return Err(
            "the gripper is in FAST STOP: find the cause, then acknowledge it (command 0x24)"
                .into(),
        );
    }
    println!("homing");
    gripper.home(HomingDirection::Default).await?;
    let open_mm = (width_mm + 20.0).min(limits.stroke_mm);
    let speed = 50.0_f32.clamp(limits.min_speed_mm_per_s, limits.max_speed_mm_per_s);
    println!("pre-positioning to {open_mm} mm");
    gripper.pre_position(open_mm, speed).await?;
    println!("grasping a {width_mm} mm part");
    match gripper.grasp(width_mm, speed).await {
        Err(e) if e.status() == Some(gripper::wsg::Status::CmdFailed) => {
            return Err(format!("no part found at {width_mm} mm (E_CMD_FAILED)").into());
        }
        other => other?,
    }

    let every = UpdateOptions::periodic(Duration::from_millis(50));
    let mut state = gripper.subscribe_grip_state(every).await?;
    let mut width = gripper.subscribe_width_mm(every).await?;
    let mut force = gripper.subscribe_force_n(every).await?;
    for _ in 0..3 {
        let (Some(s), Some(w), Some(f)) =
            (state.next().await, width.next().await, force.next().await)
        else {
            break;
        };
        println!("holding: grip state {s:?}, width {w:.2} mm, force {f:.1} N");
        if s != GripState::Holding {
            println!("warning: the part is no longer held");
        }
    }
    drop((state, width, force));

    println!("releasing to {open_mm} mm");
    gripper.release(open_mm, speed).await?;
    println!("grip state: {:?}", gripper.grip_state().await?);
    Ok(())
}

/// The same pick over the text interface (GCL): `FSACK()` first as every public driver does
/// (answered `ACK FSACK` with nothing pending), then HOME, MOVE, GRIP, watch with `AUTOSEND`,
/// RELEASE (by a pull-back distance: GCL's release is relative) and `BYE()`.
async fn pick_text(target: Target, width_mm: f32) -> Result<(), Box<dyn std::error::Error>> {
    use gripper::wsg::text::{self, Quantity};
    let (addr, _sim) = match target {
        Target::Tcp(addr) => (addr, None),
        _ => {
            let config = SimConfig::new(Model::Wsg50).with_part(40.0, 2.0).text();
            let sim = SimServer::bind("127.0.0.1:0", config).await?;
            let addr = sim.local_addr().ok_or("the simulator has no address")?;
            println!("started the text simulator on {addr}");
            (addr.to_string(), Some(sim))
        }
    };
    let gripper = text::Client::connect(addr.as_str()).await?;
    let result = async {
        gripper.ack_fast_stop().await?;
        println!("homing");
        gripper.home(HomingDirection::Default).await?;
        let open_mm = f64::from(width_mm) + 20.0;
        println!("moving to {open_mm} mm");
        gripper.move_to(open_mm, Some(50.0)).await?;
        println!("gripping a {width_mm} mm part");
        gripper
            .grip_part(40.0, f64::from(width_mm), Some(50.0))
            .await?;
        let mut positions = gripper.autosend(Quantity::Position, 50, false).await?;
        for _ in 0..3 {
            let Some(push) = positions.next().await else {
                break;
            };
            println!(
                "holding: width {:.1} mm, grip state {:?}",
                push.value,
                gripper.grip_state().await?
            );
        }
        gripper.stop_autosend(Quantity::Position).await?;
        println!("releasing by 20 mm");
        gripper.release(Some(20.0), Some(50.0)).await?;
        println!("grip state: {:?}", gripper.grip_state().await?);
        Ok::<_, text::Error>(())
    }
    .await;
    let closed = gripper.close().await;
    result?;
    closed?;
    Ok(())
}

#[tokio::main]
async fn main() -> ExitCode {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("wsg_pick: {e}");
            return ExitCode::from(2);
        }
    };
    if args.text {
        return match pick_text(args.target, args.width_mm).await {
            Ok(()) => {
                println!("done: disconnected gracefully (BYE)");
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("wsg_pick: {e}");
                ExitCode::FAILURE
            }
        };
    }
    let (gripper, _sim) = match connect(args.target).await {
        Ok(c) => c,
        Err(e) => {
            eprintln!("wsg_pick: cannot connect: {e}");
            return ExitCode::FAILURE;
        }
    };
    let result = pick(&gripper, args.width_mm).await;
    let closed = gripper.close().await;
    match (result, closed) {
        (Ok(()), Ok(())) => {
            println!("done: disconnected gracefully");
            ExitCode::SUCCESS
        }
        (Err(e), _) => {
            eprintln!("wsg_pick: {e}");
            ExitCode::FAILURE
        }
        (Ok(()), Err(e)) => {
            eprintln!("wsg_pick: closing: {e}");
            ExitCode::FAILURE
        }
    }
}
