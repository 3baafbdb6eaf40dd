//! `--sim wsg|griplink|smartgrasp`: the crate's simulator of the device, in process and in real
//! time, on a loopback port of its own.

use std::sync::Arc;
use std::time::Duration;

use gripper::griplink::sim as gl;
use gripper::wsg::sim::{Model, SimConfig, SimServer, SimSnapshot};
use tokio::sync::watch;

use crate::params::{DeviceKind, Params};
use crate::periodic;

/// How often the simulator's state is looked at for its log.
const LOG_PERIOD: Duration = Duration::from_millis(10);

/// A running simulator; it stops when dropped.
pub enum Sim {
    /// A WSG (50 by default).
    Wsg(Arc<SimServer>),
    /// A GRIPLINK-ET4.
    Griplink(Arc<gl::SimServer>),
    /// A Grasping-Kit server.
    SmartGrasp(gripper::smartgrasp::sim::SimServer),
}

/// Starts the simulator of `kind` and points the parameters at it.
pub async fn start(
    kind: DeviceKind,
    wsg_model: Option<Model>,
    params: &mut Params,
    shutdown: watch::Receiver<bool>,
) -> Result<Sim, String> {
    match kind {
        DeviceKind::Wsg => {
            // A WSG (50 unless `--sim wsg:MODEL` says which, so that its stroke is its
            // description's) with a 40 mm part (±2 mm) between its fingers, which stops a
            // closing move (E_AXIS_BLOCKED), moving in real time; over its text interface (GCL)
            // with `transport: text`, else over the binary protocol on TCP.
            let text = params.transport == "text";
            let model = wsg_model.unwrap_or(Model::Wsg50);
            let mut config = SimConfig::new(model)
                .with_part(40.0, 2.0)
                .with_time_scale(1.0)
                .with_blocking_part();
            if text {
                config = config.text();
            }
            let server = SimServer::bind("127.0.0.1:0", config)
                .await
                .map_err(|e| format!("WSG simulator: {e}"))?;
            let addr = server
                .local_addr()
                .ok_or("the WSG simulator has no address")?;
            tracing::info!(
                "WSG simulator ({model:?}, a 40 mm part between the fingers, real time) on {addr}"
            );
            if !text {
                params.transport = "tcp".into();
            }
            params.address = addr.to_string();
            let server = Arc::new(server);
            tokio::spawn(log_wsg(server.clone(), shutdown));
            Ok(Sim::Wsg(server))
        }
        DeviceKind::Griplink => {
            // A GRIPLINK-ET4 (an IEG 55-020 on port 0, here with a 10 mm part; a CRG 200-085
            // on port 2), moving in real time.
            let mut config = gl::SimConfig::et4();
            let ieg = gl::SimDevice::ieg_55_020().with_part(10.0);
            config = config.device(0, Some(ieg));
            let server = gl::SimServer::bind("127.0.0.1:0", config)
                .await
                .map_err(|e| format!("GRIPLINK simulator: {e}"))?;
            let addr = server.local_addr();
            tracing::info!(
                "GRIPLINK simulator (ET4: IEG 55-020 with a 10 mm part on port 0, CRG 200-085 \
                 on port 2, real time) on {addr}"
            );
            params.address = addr.to_string();
            let server = Arc::new(server);
            tokio::spawn(log_griplink(server.clone(), params.griplink_port, shutdown));
            Ok(Sim::Griplink(server))
        }
        DeviceKind::SmartGrasp => {
            // An operational V4 server with the demo bin (three parts). A real Grasping-Kit's
            // GRASP_FEEDBACK changes nothing (SCHUNK's examples); here an OK takes the part out of
            // the bin, as `gripctl sim smartgrasp` does, so a picking loop ends.
            let config = gripper::smartgrasp::sim::SimConfig {
                feedback_removes_objects: true,
                ..Default::default()
            };
            let server = gripper::smartgrasp::sim::SimServer::bind("127.0.0.1:0", config)
                .await
                .map_err(|e| format!("Grasping-Kit simulator: {e}"))?;
            let addr = server.local_addr();
            tracing::info!("Grasping-Kit simulator (V4, the demo bin of three parts) on {addr}");
            params.address = addr.to_string();
            Ok(Sim::SmartGrasp(server))
        }
    }
}

/// The simulator's log: each change of its grip state or system state flags (a stop shows as
/// AXIS_STOPPED, manual Anhang B), with the width.
async fn log_wsg(server: Arc<SimServer>, shutdown: watch::Receiver<bool>) {
    let mut last: Option<SimSnapshot> = None;
    periodic::every(LOG_PERIOD, shutdown, move || {
        let now = server.snapshot();
        let changed = last
            .as_ref()
            .is_none_or(|l| l.grip_state != now.grip_state || l.system_state != now.system_state);
        if changed {
            tracing::info!(
                target: "simulator",
                "WSG simulator: grip state {:?}, {:?}, width {:.2} mm",
                now.grip_state,
                now.system_state,
                now.width_mm
            );
        }
        last = Some(now);
        std::future::ready(())
    })
    .await;
}

/// The GRIPLINK simulator's log: each change of the port's device state (a cancel's DISABLE
/// shows as `Disabled`).
async fn log_griplink(
    server: Arc<gl::SimServer>,
    port: gripper::griplink::command::PortNumber,
    shutdown: watch::Receiver<bool>,
) {
    let mut last = None;
    periodic::every(LOG_PERIOD, shutdown, move || {
        let now = server.device_state(port);
        if now != last {
            tracing::info!(target: "simulator", "GRIPLINK simulator: port {port}: {now:?}");
            last = now;
        }
        std::future::ready(())
    })
    .await;
}
