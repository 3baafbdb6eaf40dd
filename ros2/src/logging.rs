//! The node's log: the console (stderr) and `/rosout` (`rcl_interfaces/msg/Log`, what
//! `ros2 topic echo /rosout`, rqt_console and the launch log read), at `--log-level`.
//!
//! Every `tracing` event of the node goes through [`RosoutLayer`], which publishes it on the
//! node's `/rosout` writer (ros2-client's, with rcl's QoS) once [`attach`] has named the node.
//! ros2-client's own `rosout!` is not used: it logs each record to `tracing` again, which
//! would come back here. RustDDS and ros2-client records stay on the console only.

use std::cell::Cell;
use std::fmt::Write as _;
use std::sync::{Arc, OnceLock};

use ros2_client::builtin_interfaces::Time;
use ros2_client::log::Log;
use ros2_client::rosout::RosoutRaw;
use ros2_client::{Node, Publisher};
use tracing::field::{Field, Visit};
use tracing::{Event, Level, Subscriber};
use tracing_subscriber::filter::{EnvFilter, LevelFilter};
use tracing_subscriber::layer::{Context, Layer, SubscriberExt};
use tracing_subscriber::util::SubscriberInitExt;

use crate::params::{Cli, Params};

/// The `/rosout` writer and the node's logger name, once the node exists.
struct Sink {
    writer: Arc<Option<Publisher<Log>>>,
    logger: String,
}

static SINK: OnceLock<Sink> = OnceLock::new();

thread_local! {
    /// Set while a record is published: a record logged by the publishing itself (RustDDS)
    /// is not published again.
    static PUBLISHING: Cell<bool> = const { Cell::new(false) };
}

/// Crates whose records are for the console only: RustDDS logs its own traffic, so publishing
/// its records would feed on itself.
fn console_only(target: &str) -> bool {
    target.starts_with("rustdds") || target.starts_with("ros2_client")
}

/// The console's filter: `RUST_LOG` if set, else `--log-level` (default info), with RustDDS
/// at error and ros2-client at warn (RustDDS warns about every peer locator it cannot use,
/// many times a second).
fn console_filter(level: Option<Level>) -> EnvFilter {
    EnvFilter::try_from_default_env().unwrap_or_else(|_| {
        let level = level.unwrap_or(Level::INFO).to_string().to_lowercase();
        EnvFilter::new(format!("{level},rustdds=error,ros2_client=warn"))
    })
}

/// Installs the process's logging as the command line asks: the console unless
/// `--disable-stdout-logs`, `/rosout` unless `--disable-rosout-logs`, both at `--log-level`.
/// Then logs the command line's warnings.
pub fn init(cli: &Cli) {
    let level = cli.log_level.unwrap_or(Level::INFO);
    let console = cli.console_logs.then(|| {
        tracing_subscriber::fmt::layer()
            .with_writer(std::io::stderr)
            .with_filter(console_filter(cli.log_level))
    });
    let rosout = cli.rosout_logs.then(|| {
        RosoutLayer
            .with_filter(LevelFilter::from_level(level))
            .with_filter(tracing_subscriber::filter::filter_fn(|m| {
                !console_only(m.target())
            }))
    });
    // Fails only if a subscriber is already installed (a test's): that one is kept.
    let _ = tracing_subscriber::registry()
        .with(console)
        .with(rosout)
        .try_init();
    for w in &cli.warnings {
        tracing::warn!("{w}");
    }
}

/// From now on, records are published on `node`'s `/rosout` (the first node of the process:
/// the binary has one).
pub fn attach(node: &Node, params: &Params) {
    let _ = SINK.set(Sink {
        writer: node.logging_handle().rosout_writer(),
        logger: params.logger_name(),
    });
}

/// rcl_interfaces/msg/Log's level of a `tracing` level (Log.msg: DEBUG 10, INFO 20, WARN 30,
/// ERROR 40; `tracing` has no FATAL, and TRACE is below DEBUG).
pub fn ros_level(level: Level) -> u8 {
    match level {
        Level::ERROR => 40,
        Level::WARN => 30,
        Level::INFO => 20,
        _ => 10,
    }
}

/// The `tracing` layer that publishes on `/rosout`.
pub struct RosoutLayer;

impl<S: Subscriber> Layer<S> for RosoutLayer {
    fn on_event(&self, event: &Event<'_>, _ctx: Context<'_, S>) {
        let Some(sink) = SINK.get() else {
            return;
        };
        let Some(writer) = sink.writer.as_ref() else {
            return;
        };
        if PUBLISHING.with(|p| p.replace(true)) {
            return;
        }
        let meta = event.metadata();
        let mut text = Text::default();
        event.record(&mut text);
        let record = Log {
            stamp: Time::now(),
            level: ros_level(*meta.level()),
            name: sink.logger.clone(),
            msg: text.0,
            file: meta.file().unwrap_or_default().to_owned(),
            function: meta.target().to_owned(),
            line: meta.line().unwrap_or_default(),
        };
        // A lost record is not worth a record of its own.
        let _ = writer.publish(record);
        PUBLISHING.with(|p| p.set(false));
    }
}

/// An event's text: its message, then its other fields as `name=value`.
#[derive(Default)]
struct Text(String);

impl Visit for Text {
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            let rest = std::mem::take(&mut self.0);
            let _ = write!(self.0, "{value:?}");
            if !rest.is_empty() {
                let _ = write!(self.0, " {rest}");
            }
        } else {
            if !self.0.is_empty() {
                self.0.push(' ');
            }
            let _ = write!(self.0, "{}={value:?}", field.name());
        }
    }

    fn record_str(&mut self, field: &Field, value: &str) {
        if field.name() == "message" {
            self.record_debug(field, &format_args!("{value}"));
        } else {
            self.record_debug(field, &value);
        }
    }
}
