//! `gripctl sim smartgrasp --http ADDR`: the simulator's scene picture over HTTP, at the path
//! where the kit serves its latest detection result.

use gripper::smartgrasp::sim::{MonitorServer, SimServer, MONITOR_PATH};
use serde_json::json;

use super::cannot_listen;
use crate::error::CliError;
use crate::output::Out;

/// Starts the monitor page and prints its URL (text: `monitor: http://…`, JSON: `{"monitor": …}`)
/// so that a script can read it after the `listening on` line.
pub(super) async fn serve(
    server: &SimServer,
    listen: &str,
    out: Out,
) -> Result<MonitorServer, CliError> {
    let monitor = server
        .serve_monitor(listen)
        .await
        .map_err(|e| cannot_listen(listen, &e))?;
    let url = format!("http://{}{MONITOR_PATH}", monitor.local_addr());
    out.emit(format!("monitor: {url}"), json!({ "monitor": url }))?;
    Ok(monitor)
}
