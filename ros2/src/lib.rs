//! `gripper-ros2`: a Weiss WSG gripper, a GRIPLINK port or the SCHUNK 2D Grasping-Kit as a
//! ROS 2 node, in pure Rust over ros2-client (no ROS installation needed), optionally with the
//! `gripper` crate's simulator of the device in process (`--sim`).
//!
//! The binary is `src/main.rs`; this library holds the node so that the tests can run it in
//! process. The README's "ROS 2" section has the commands, a launch file and the parameter
//! table.

pub mod action;
pub mod diagnostics;
pub mod griplink_node;
pub mod gripper_node;
pub mod joint_map;
pub mod joint_states;
pub mod kit_node;
pub mod link;
pub mod logging;
pub mod msgs;
pub mod param_services;
pub mod params;
pub mod periodic;
pub mod qos;
pub mod ros;
pub mod rpc;
pub mod sim;
pub mod telemetry;
pub mod trigger;
pub mod wsg_node;
pub mod wsg_text_node;

use std::future::Future;
use std::time::Duration;

use tokio::sync::watch;

use crate::params::{Cli, DeviceKind};

/// How long the node waits at shutdown for a running goal to be stopped and the device's link
/// to close.
pub const SHUTDOWN_GRACE: Duration = Duration::from_secs(3);

/// The device link to close at shutdown.
enum Link {
    Wsg(gripper::wsg::Client),
    WsgText(gripper::wsg::text::Client),
    Griplink(gripper::griplink::Client),
    SmartGrasp(gripper::smartgrasp::Client),
}

/// Runs the node `cli` describes until `stop` completes, then shuts it down cleanly: a running
/// goal is stopped, the device's link closed (WSG: the disconnect announced).
pub async fn run(cli: Cli, stop: impl Future<Output = ()>) -> Result<(), String> {
    let (shutdown_tx, shutdown) = watch::channel(false);
    let mut params = cli.params;
    let _sim = match cli.sim {
        Some(kind) => Some(sim::start(kind, cli.sim_model, &mut params, shutdown.clone()).await?),
        None => None,
    };
    let context = ros::context(&params)?;
    let mut node = ros::node(&context, &params, cli.rosout_logs)?;
    logging::attach(&node, &params);
    let live = params::Live::new(&params);
    param_services::spawn(&context, &mut node, &params, &live, &shutdown)?;
    let link = match params.device {
        DeviceKind::Wsg if params.transport == "text" => {
            let client = wsg_text_node::connect(&params).await?;
            wsg_text_node::start(&mut node, &params, client.clone(), &live, &shutdown).await?;
            Link::WsgText(client)
        }
        DeviceKind::Wsg => {
            let client = wsg_node::connect(&params).await?;
            wsg_node::start(&mut node, &params, client.clone(), &live, &shutdown).await?;
            Link::Wsg(client)
        }
        DeviceKind::Griplink => {
            let client = griplink_node::connect(&params).await?;
            griplink_node::start(&mut node, &params, client.clone(), &live, &shutdown).await?;
            Link::Griplink(client)
        }
        DeviceKind::SmartGrasp => {
            let client = kit_node::connect(&params).await?;
            kit_node::start(&mut node, &params, client.clone(), &shutdown)?;
            Link::SmartGrasp(client)
        }
    };
    let mapping = match params.service_mapping {
        Some(m) => format!("{m:?} service mapping"),
        None => "each peer's service mapping".to_owned(),
    };
    tracing::info!(
        "ready: node {} on ROS domain {}, {mapping}",
        params.fully_qualified_name(),
        params.domain_id,
    );
    stop.await;
    tracing::info!("shutting down");
    let _ = shutdown_tx.send(true);
    drop(shutdown);
    // Every task holds a receiver until it has finished (a running goal stops first).
    if tokio::time::timeout(SHUTDOWN_GRACE, shutdown_tx.closed())
        .await
        .is_err()
    {
        tracing::warn!("some tasks did not finish within {SHUTDOWN_GRACE:?}");
    }
    let closed = match &link {
        // Announces the disconnect first (0x07), so the WSG does not go into FAST STOP.
        Link::Wsg(client) => tokio::time::timeout(SHUTDOWN_GRACE, client.close())
            .await
            .map_err(|_| "closing the WSG link timed out".to_owned())
            .and_then(|r| r.map_err(|e| format!("closing the WSG link: {e}"))),
        // BYE(): announces the disconnect, so the WSG does not go into FAST STOP (GCL manual,
        // chapter 2).
        Link::WsgText(client) => tokio::time::timeout(SHUTDOWN_GRACE, client.close())
            .await
            .map_err(|_| "closing the WSG text link timed out".to_owned())
            .and_then(|r| r.map_err(|e| format!("closing the WSG text link: {e}"))),
        // BYE(): ends the session (manual 3.3.1).
        Link::Griplink(client) => tokio::time::timeout(SHUTDOWN_GRACE, client.close())
            .await
            .map_err(|_| "closing the GRIPLINK session timed out".to_owned())
            .and_then(|r| r.map_err(|e| format!("closing the GRIPLINK session: {e}"))),
        Link::SmartGrasp(client) => tokio::time::timeout(SHUTDOWN_GRACE, client.close())
            .await
            .map_err(|_| "closing the Grasping-Kit session timed out".to_owned())
            .and_then(|r| r.map_err(|e| format!("closing the Grasping-Kit session: {e}"))),
    };
    if let Err(e) = &closed {
        tracing::warn!("{e}");
    }
    // Dropping the last handle of a DDS participant joins RustDDS's event-loop thread: done on
    // a blocking thread, bounded, so that it never stalls the runtime's workers.
    let teardown = tokio::task::spawn_blocking(move || drop((node, context)));
    if tokio::time::timeout(SHUTDOWN_GRACE, teardown)
        .await
        .is_err()
    {
        tracing::warn!("the DDS participant did not stop within {SHUTDOWN_GRACE:?}");
    }
    Ok(())
}
