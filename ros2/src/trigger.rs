//! `std_srvs/srv/Trigger` services (`~/home`, `~/stop`, `~/acknowledge`): each its own task,
//! so a stop is never queued behind a homing that runs.

use std::sync::Arc;

use futures::future::BoxFuture;
use ros2_client::Node;
use tokio::sync::watch;

use crate::msgs::{trigger_type, TriggerRequest, TriggerResponse};
use crate::params::Params;
use crate::{ros, rpc};

/// What a service does: `Ok(message)` or `Err(why)`.
pub type Handler = Arc<dyn Fn() -> BoxFuture<'static, Result<String, String>> + Send + Sync>;

/// Creates `~/name` and serves it until `shutdown` turns true.
pub fn spawn(
    node: &mut Node,
    params: &Params,
    name: &str,
    handler: Handler,
    mut shutdown: watch::Receiver<bool>,
) -> Result<(), String> {
    let server = rpc::Service::<TriggerRequest, TriggerResponse>::create(
        node,
        params,
        &ros::private_name(params, name)?,
        &trigger_type(),
    )?;
    let name = name.to_owned();
    tokio::spawn(async move {
        loop {
            let request = tokio::select! {
                r = server.receive() => r,
                _ = shutdown.wait_for(|s| *s) => return,
            };
            tracing::info!("~/{name} called");
            let response = match handler().await {
                Ok(message) => TriggerResponse {
                    success: true,
                    message,
                },
                Err(message) => {
                    tracing::warn!("~/{name} failed: {message}");
                    TriggerResponse {
                        success: false,
                        message,
                    }
                }
            };
            if let Err(e) = server.respond(request.server, request.id, response) {
                tracing::warn!("{e}");
            }
        }
    });
    Ok(())
}
