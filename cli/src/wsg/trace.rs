//! `--plot FILE.svg` of `home`, `move`, `grasp` and `release`: width, speed and force from
//! auto-updates (manual 3.4.1, 0x43/0x44/0x45 every 10 ms, the fastest period the protocol allows),
//! from the command's start to its final reply, drawn over time; grip state changes (0x41) are
//! marked.

use std::future::Future;
use std::path::Path;
use std::time::{Duration, Instant};

use gripper::wsg::{Client, Error, UpdateOptions};

use super::live::{emit_sample, next, Streams};
use super::show::grip_name;
use super::{classify, optional};
use crate::error::CliError;
use crate::output::Out;
use crate::plot::{Panel, Trace};

/// The auto-update period of a trace: the manual's minimum (3.4.1: 10 ms).
const TRACE_PERIOD: Duration = Duration::from_millis(10);

/// What a motion command asks for, for the plot's title and reference lines.
#[derive(Debug, Clone)]
pub(super) struct Motion {
    /// The command as the user wrote it, e.g. `grasp 20.0 mm at 20.0 mm/s`.
    pub(super) what: String,
    /// The width the command moves to, mm (none for homing).
    pub(super) target_mm: Option<f32>,
}

/// Runs `command` (the motion, not yet polled) while recording a trace, and writes the trace to
/// `path` whatever the outcome: a failed grasp is exactly the curve an engineer wants to see.
pub(super) async fn traced(
    client: &Client,
    path: &Path,
    motion: Motion,
    command: impl Future<Output = gripper::wsg::Result<()>>,
    out: Out,
) -> Result<(), CliError> {
    // The force limit of grasps (0x33); a gripper without it just gets no reference line.
    let force_limit_n = optional(client.grasping_force_n().await)?;
    // The first sample is the state before the motion.
    let Streams {
        mut width,
        mut speed,
        mut force,
        mut grip,
        first: mut sample,
    } = Streams::subscribe(client, UpdateOptions::periodic(TRACE_PERIOD)).await?;
    let mut width_panel = Panel::new("width", "mm");
    let mut speed_panel = Panel::new("speed", "mm/s");
    let mut force_panel = Panel::new("force", "N");
    let mut events = Vec::new();
    width_panel.push(0.0, sample.width_mm.into());
    speed_panel.push(0.0, sample.speed_mm_per_s.into());
    force_panel.push(0.0, sample.force_n.into());

    let start = Instant::now();
    if out.is_json() {
        // As `watch`: the first sample is the state the command starts from.
        emit_sample(&sample, Duration::ZERO, out)?;
    }
    tokio::pin!(command);
    // A stream that ends (the connection broke) stops being sampled; the command's own reply
    // then says what happened.
    let mut streaming = true;
    // A sample that cannot be printed (a closed pipe) is reported once the motion has ended:
    // returning at once would leave the fingers moving unwatched.
    let mut output_error = None;
    let result = loop {
        let t = || start.elapsed().as_secs_f64();
        tokio::select! {
            // The final reply first: samples after it are not part of the command.
            biased;
            r = &mut command => break r,
            w = next(&mut width), if streaming => match w {
                Ok(w) => {
                    sample.width_mm = w;
                    width_panel.push(t(), w.into());
                    if out.is_json() && output_error.is_none() {
                        output_error = emit_sample(&sample, start.elapsed(), out).err();
                    }
                }
                Err(_) => streaming = false,
            },
            s = next(&mut speed), if streaming => match s {
                Ok(s) => {
                    sample.speed_mm_per_s = s;
                    speed_panel.push(t(), s.into());
                }
                Err(_) => streaming = false,
            },
            f = next(&mut force), if streaming => match f {
                Ok(f) => {
                    sample.force_n = f;
                    force_panel.push(t(), f.into());
                }
                Err(_) => streaming = false,
            },
            g = next(&mut grip), if streaming => match g {
                Ok(g) => {
                    if g != sample.grip {
                        events.push((t(), grip_name(g)));
                    }
                    sample.grip = g;
                }
                Err(_) => streaming = false,
            },
        }
    };
    // Unsubscribe before anything else is asked (dropping turns the updates off).
    drop((width, speed, force, grip));
    // Where the command left the fingers: a grasp's force and grip state change with its final
    // reply, before the next update could report them. Best effort: the trace is drawn anyway.
    let (w, s, f, g) = tokio::join!(
        client.width_mm(),
        client.speed_mm_per_s(),
        client.force_n(),
        client.grip_state()
    );
    let end_s = start.elapsed().as_secs_f64();
    for (panel, value) in [
        (&mut width_panel, w),
        (&mut speed_panel, s),
        (&mut force_panel, f),
    ] {
        match value {
            Ok(v) => panel.push(end_s, v.into()),
            Err(_) => panel.hold_until(end_s),
        }
    }
    let final_grip = g.ok();
    if let Some(g) = final_grip.filter(|&g| g != sample.grip) {
        events.push((end_s, grip_name(g)));
    }
    if let Some(target) = motion.target_mm {
        width_panel.reference(format!("target {target:.1} mm"), target.into());
    }
    if let Some(limit) = force_limit_n {
        force_panel.reference(format!("force limit {limit:.1} N"), limit.into());
    }
    let status = match &result {
        Ok(()) => match final_grip {
            Some(grip) => format!("E_SUCCESS, grip state {}", grip_name(grip)),
            None => "E_SUCCESS".to_owned(),
        },
        Err(Error::Device { status, .. }) => status.symbol().to_owned(),
        Err(e) => e.to_string(),
    };
    if let Some(e) = output_error {
        return Err(e);
    }
    let samples = width_panel.samples.len();
    Trace {
        title: format!("wsg {}: {status}", motion.what),
        panels: vec![width_panel, speed_panel, force_panel],
        events,
    }
    .write(path)?;
    if !out.is_json() {
        // In JSON mode the samples themselves were the output; the text reader gets a pointer.
        out.emit(
            format!(
                "trace: {samples} width samples written to {}",
                path.display()
            ),
            serde_json::Value::Null,
        )?;
    }
    result.map_err(classify)
}
