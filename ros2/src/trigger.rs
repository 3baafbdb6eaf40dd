//! `std_srvs/srv/Trigger` services (`~/home`, `~/stop`, `~/acknowledge`): each its own task,
//! so a stop is never queued behind a homing that runs.

use std::sync::Arc;

use futures::future::BoxFuture;
use ros2_client::{Node, ServiceMapping};
use tokio::sync::watch;

use crate::msgs::{trigger_type, TriggerRequest, TriggerResponse};
use crate::params::Params;
use crate::{qos, ros};

/// The pause after a failed read of a request.
const ERROR_BACKOFF: std::time::Duration = std::time::Duration::from_millis(100);

/// What a service does: `Ok(message)` or `Err(why)`.
pub type Handler = Arc<dyn Fn() -> BoxFuture<'static, Result<String, String>> + Send + Sync>;

/// Creates `~/name` and serves it until `shutdown` turns true.
pub fn spawn(
    node: &mut Node,
    params: &Params,
    mapping: ServiceMapping,
    name: &str,
    handler: Handler,
    mut shutdown: watch::Receiver<bool>,
) -> Result<(), String> {
    let server = node
        .create_server::<TriggerRequest, TriggerResponse>(
            mapping,
            &ros::private_name(params, name)?,
            &trigger_type(),
            qos::services(),
            qos::services(),
        )
        .map_err(|e| format!("service ~/{name}: {e:?}"))?;
    let name = name.to_owned();
    tokio::spawn(async move {
        loop {
            let request = tokio::select! {
                r = server.async_receive_request() => r,
                _ = shutdown.wait_for(|s| *s) => return,
            };
            let id = match request {
                Ok((id, _)) => id,
                Err(e) => {
                    tracing::warn!("~/{name}: reading a request failed: {e:?}");
                    // A reader that keeps failing must not spin the runtime.
                    tokio::time::sleep(ERROR_BACKOFF).await;
                    continue;
                }
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
            if let Err(e) = server.send_response(id, response) {
                tracing::warn!("~/{name}: answering failed: {e:?}");
            }
        }
    });
    Ok(())
}
