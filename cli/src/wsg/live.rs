//! Commands that keep talking: `watch` (auto-updates) and `loop` (echo test).

use std::future::poll_fn;
use std::pin::Pin;
use std::time::{Duration, Instant};

use futures_core::Stream;
use gripper::wsg::{Client, GripState, Subscription, UpdateOptions};
use serde_json::json;

use super::classify;
use super::show::{grip_json, grip_name, num, to_hex};
use crate::error::{CliError, Kind};
use crate::output::Out;

/// The latest of each streamed value.
pub(super) struct Sample {
    pub(super) width_mm: f32,
    pub(super) speed_mm_per_s: f32,
    pub(super) force_n: f32,
    pub(super) grip: GripState,
}

/// The four auto-update streams of `watch` and of a trace, and the first sample they gave.
pub(super) struct Streams {
    pub(super) width: Subscription<f32>,
    pub(super) speed: Subscription<f32>,
    pub(super) force: Subscription<f32>,
    pub(super) grip: Subscription<GripState>,
    /// The state when the streams started.
    pub(super) first: Sample,
}

impl Streams {
    /// Subscribes to width, speed, force and grip state (manual 3.4.1 with 0x41, 0x43-0x45).
    pub(super) async fn subscribe(
        client: &Client,
        options: UpdateOptions,
    ) -> Result<Streams, CliError> {
        let mut width = client.subscribe_width_mm(options).await.map_err(classify)?;
        let mut speed = client
            .subscribe_speed_mm_per_s(options)
            .await
            .map_err(classify)?;
        let mut force = client.subscribe_force_n(options).await.map_err(classify)?;
        let mut grip = client
            .subscribe_grip_state(options)
            .await
            .map_err(classify)?;
        // Each stream's first item answers the subscription: a complete first sample.
        let first = Sample {
            width_mm: next(&mut width).await?,
            speed_mm_per_s: next(&mut speed).await?,
            force_n: next(&mut force).await?,
            grip: next(&mut grip).await?,
        };
        Ok(Streams {
            width,
            speed,
            force,
            grip,
            first,
        })
    }
}

pub(super) async fn watch(
    client: &Client,
    count: Option<u64>,
    period: Duration,
    out: Out,
) -> Result<(), CliError> {
    let Streams {
        mut width,
        mut speed,
        mut force,
        mut grip,
        first: mut sample,
    } = Streams::subscribe(client, UpdateOptions::periodic(period)).await?;
    let start = Instant::now();
    let mut emitted = 0;
    loop {
        if count.is_some_and(|n| emitted >= n) {
            return Ok(());
        }
        emit_sample(&sample, start.elapsed(), out)?;
        emitted += 1;
        if count.is_some_and(|n| emitted >= n) {
            return Ok(());
        }
        // One sample per width update (all four share the period); the others refresh between.
        loop {
            tokio::select! {
                w = next(&mut width) => { sample.width_mm = w?; break; }
                s = next(&mut speed) => sample.speed_mm_per_s = s?,
                f = next(&mut force) => sample.force_n = f?,
                g = next(&mut grip) => sample.grip = g?,
            }
        }
    }
}

pub(super) async fn next<T>(stream: &mut Subscription<T>) -> Result<T, CliError> {
    poll_fn(|cx| Pin::new(&mut *stream).poll_next(cx))
        .await
        .ok_or_else(|| {
            CliError::new(
                Kind::Connection,
                "the auto-update stream ended: connection lost",
            )
        })
}

pub(super) fn emit_sample(s: &Sample, elapsed: Duration, out: Out) -> Result<(), CliError> {
    out.emit(
        format!(
            "{:8.3} s  width {:7.2} mm  speed {:7.2} mm/s  force {:6.1} N  {}",
            elapsed.as_secs_f64(),
            s.width_mm,
            s.speed_mm_per_s,
            s.force_n,
            grip_name(s.grip)
        ),
        json!({
            "elapsed_s": elapsed.as_secs_f64(),
            "width_mm": num(s.width_mm),
            "speed_mm_per_s": num(s.speed_mm_per_s),
            "force_n": num(s.force_n),
            "grip_state": grip_json(s.grip),
        }),
    )
}

pub(super) async fn loop_test(
    client: &Client,
    size: u16,
    repeat: u32,
    out: Out,
) -> Result<(), CliError> {
    let start = Instant::now();
    for round in 0..repeat {
        // A different pattern each round, so a stale echo of an earlier round cannot pass.
        let data: Vec<u8> = (0..size)
            .map(|i| (u32::from(i) + round * 7) as u8)
            .collect();
        let echo = client.loop_back(data.clone()).await.map_err(classify)?;
        if echo[..] != data[..] {
            return Err(CliError::new(
                Kind::Malformed,
                format!(
                    "loop round {}: sent {} bytes, the echo differs ({} bytes: [{}])",
                    round + 1,
                    data.len(),
                    echo.len(),
                    to_hex(&echo)
                ),
            ));
        }
    }
    let elapsed = start.elapsed();
    let per_round_ms = elapsed.as_secs_f64() * 1000.0 / f64::from(repeat);
    out.emit(
        format!("loop test passed: {repeat} × {size} bytes echoed, {per_round_ms:.2} ms per round"),
        json!({ "rounds": repeat, "size": size, "ms_per_round": per_round_ms }),
    )
}
