//! `--plot FILE.svg` of `home`, `grip`, `release`, `flexgrip` and `flexrelease`: the finger
//! position (`VALUEF[p][0]?`, manual 3.5.2) and the device state (`DEVSTATE[p]?`, 3.5.1) polled
//! at a fixed rate from the command's start to its final reply, drawn over time with every state
//! change marked.
//!
//! The polls go over a second connection: a blocking motion holds its own connection until it is
//! done (manual 3.4.3 to 3.4.7), so polls queued behind it would see only its end. A controller
//! that refuses a second connection makes `--plot` fail with that error before the motion starts.

use std::future::Future;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use gripper::griplink::{Client, ClientConfig, DeviceState, Error, Port, PortNumber};

use serde_json::json;

use super::{classify, state_json};
use crate::error::CliError;
use crate::output::Out;
use crate::plot::{Panel, Trace};

/// How often the position and state are polled: two short queries per period on a loopback or
/// LAN connection, and a curve fine enough to see a bounce.
const POLL_PERIOD: Duration = Duration::from_millis(20);

/// The second connection that polls, and where the trace goes.
pub(super) struct Tracer {
    poller: Client,
    port: Port,
    port_number: PortNumber,
    path: PathBuf,
}

/// What a motion command asks for, for the plot's title and reference lines.
#[derive(Debug, Clone, Default)]
pub(super) struct Motion {
    /// The command as the user wrote it, e.g. `grip recipe 0`.
    pub(super) what: String,
    /// The position the command moves to (a recipe's limit, a flex command's position), mm.
    pub(super) target_mm: Option<f64>,
    /// The force limit, as the command gives it (`50 %` of a recipe, `20.0 N`).
    pub(super) force: Option<String>,
}

impl Tracer {
    /// Opens the polling connection to `addr`.
    pub(super) async fn connect(
        addr: &str,
        config: ClientConfig,
        port_number: PortNumber,
        path: &Path,
    ) -> Result<Tracer, CliError> {
        let poller = Client::connect_with(addr, config)
            .await
            .map_err(|e| classify(e).context("--plot: cannot open the polling connection"))?;
        let port = poller.port(port_number);
        Ok(Tracer {
            poller,
            port,
            port_number,
            path: path.to_owned(),
        })
    }

    /// Runs `command` (the motion, not yet polled) while polling, and writes the trace whatever
    /// the outcome: a grip that found no part is exactly the curve an engineer wants to see.
    pub(super) async fn traced<T>(
        &self,
        motion: Motion,
        command: impl Future<Output = gripper::griplink::Result<T>>,
        out: Out,
    ) -> Result<T, CliError> {
        let mut position = Panel::new("position", "mm");
        let mut events = Vec::new();
        let mut state = None;
        let mut ticker = tokio::time::interval(POLL_PERIOD);
        // A slow controller delays the next poll rather than bunching polls up.
        ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        let start = Instant::now();
        // Where the fingers start: `command` is not sent before it is first polled.
        let mut polling = self
            .poll(start, &mut position, &mut events, &mut state, out)
            .await
            .is_ok();
        // The next poll one period later, not at once.
        ticker.reset();
        tokio::pin!(command);
        // A failed poll (or a sample that cannot be printed) ends the polling, not the wait for
        // the motion's reply: that reply says what became of the motion.
        let result = loop {
            tokio::select! {
                // The final reply first: polls after it are not part of the command.
                biased;
                r = &mut command => break r,
                _ = ticker.tick(), if polling => {
                    polling = self
                        .poll(start, &mut position, &mut events, &mut state, out)
                        .await
                        .is_ok();
                }
            }
        };
        // One last poll: where the command left the fingers, and in which state (best effort:
        // the trace is drawn anyway).
        if polling {
            let _ = self
                .poll(start, &mut position, &mut events, &mut state, out)
                .await;
        }
        position.hold_until(start.elapsed().as_secs_f64());
        if let Some(target) = motion.target_mm {
            position.reference(format!("target {target:.1} mm"), target);
        }
        let status = match (&result, state) {
            (Ok(_), Some(state)) => state.to_string(),
            (Ok(_), None) => "done".to_owned(),
            (Err(Error::Device { status, .. }), _) => {
                status.identifier().unwrap_or("device error").to_owned()
            }
            (Err(e), _) => e.to_string(),
        };
        let force = motion
            .force
            .map(|f| format!(", force limit {f}"))
            .unwrap_or_default();
        let samples = position.samples.len();
        Trace {
            title: format!(
                "griplink port {} {}{force}: {status}",
                self.port_number, motion.what
            ),
            panels: vec![position],
            events,
        }
        .write(&self.path)?;
        if !out.is_json() {
            out.emit(
                format!(
                    "trace: {samples} position samples written to {}",
                    self.path.display()
                ),
                serde_json::Value::Null,
            )?;
        }
        result.map_err(classify)
    }

    /// One poll: the state (a change is an event) and the position; in JSON mode also printed,
    /// as `watch` prints its samples.
    async fn poll(
        &self,
        start: Instant,
        position: &mut Panel,
        events: &mut Vec<(f64, String)>,
        last_state: &mut Option<DeviceState>,
        out: Out,
    ) -> Result<(), CliError> {
        let state = self.port.state().await.map_err(classify)?;
        let position_mm = self.port.position_mm().await.map_err(classify)?;
        let t = start.elapsed().as_secs_f64();
        if *last_state != Some(state) {
            events.push((t, state.to_string()));
            *last_state = Some(state);
        }
        position.push(t, position_mm);
        if out.is_json() {
            out.emit(
                "",
                json!({ "elapsed_s": t, "position_mm": position_mm, "state": state_json(state) }),
            )?;
        }
        Ok(())
    }

    /// Ends the polling session with `BYE()` (manual 3.3.1).
    pub(super) async fn close(self) -> Result<(), CliError> {
        self.poller.close().await.map_err(classify)
    }
}
