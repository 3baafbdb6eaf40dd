//! Following a device link through the crate's connection events: lost, restored (counted),
//! given up. Shared by the WSG and GRIPLINK nodes.

use std::future::Future;

use futures::StreamExt;
use gripper::reconnect::{ConnectionEvent, ConnectionEvents};

use crate::telemetry::Shared;

/// Follows `events` into the telemetry until they end; after each restored link, runs
/// `restored` (e.g. the FAST STOP check). Nothing here moves the fingers: no homing, no goal
/// resumed.
pub async fn follow<F, Fut>(
    mut events: ConnectionEvents,
    device: &str,
    telemetry: Shared,
    restored: F,
) where
    F: Fn() -> Fut,
    Fut: Future<Output = ()>,
{
    while let Some(event) = events.next().await {
        match event {
            ConnectionEvent::Lost { reason } => {
                tracing::warn!("{device} link lost: {reason}");
                let mut t = telemetry.lock();
                t.connected = false;
                t.last_error = Some(format!("link lost: {reason}"));
            }
            ConnectionEvent::Restored { attempts } => {
                tracing::info!("{device} link restored after {attempts} attempt(s)");
                {
                    let mut t = telemetry.lock();
                    t.connected = true;
                    t.reconnects += 1;
                }
                restored().await;
            }
            ConnectionEvent::GaveUp { attempts } => {
                tracing::error!("{device}: gave up reconnecting after {attempts} attempt(s)");
                let mut t = telemetry.lock();
                t.connected = false;
                t.last_error = Some(format!("gave up reconnecting after {attempts} attempt(s)"));
            }
            _ => {}
        }
    }
}
