//! `gripctl smartgrasp image --out FILE`: the kit's latest detection result, an image it serves
//! over plain HTTP at `/monitor/latest_result` (PROTOCOLS.md, seed 002). The simulator serves
//! its scene there too (`gripctl sim smartgrasp --http ADDR`).

use std::path::PathBuf;
use std::time::Duration;

use clap::Args as ClapArgs;
use serde_json::json;

use crate::common::with_default_port;
use crate::error::{CliError, Kind};
use crate::output::Out;

/// The port of the kit's web interface when `--http` names only a host (plain HTTP).
const HTTP_PORT: u16 = 80;

/// The path of the latest detection result.
const MONITOR_PATH: &str = "/monitor/latest_result";

/// How long the whole fetch may take when `--timeout` is not given.
const DEFAULT_TIMEOUT: Duration = Duration::from_secs(10);

/// The largest image accepted: a camera picture is a few MiB at most.
const MAX_IMAGE_BYTES: u64 = 32 * 1024 * 1024;

/// Options of `gripctl smartgrasp image`.
#[derive(Debug, ClapArgs)]
pub(super) struct ImageArgs {
    /// Where to write the image (as served: PNG, JPEG or SVG; the output names the type).
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// The web interface: HOST or HOST:PORT [default: the --addr host, port 80].
    #[arg(long, value_name = "HOST[:PORT]")]
    http: Option<String>,
}

/// Fetches the image from `http://<host>/monitor/latest_result` and writes it to `--out`.
pub(super) async fn fetch(
    server_addr: &str,
    args: ImageArgs,
    timeout: Option<Duration>,
    out: Out,
) -> Result<(), CliError> {
    let host = match &args.http {
        Some(http) => with_default_port(http, HTTP_PORT),
        None => with_default_port(host_of(server_addr), HTTP_PORT),
    };
    let url = format!("http://{host}{MONITOR_PATH}");
    let timeout = timeout.unwrap_or(DEFAULT_TIMEOUT);
    // ureq blocks: it runs on the blocking pool, the whole exchange bounded by its own timeout.
    let request_url = url.clone();
    let (content_type, bytes) = tokio::task::spawn_blocking(move || get(&request_url, timeout))
        .await
        .map_err(|e| CliError::new(Kind::Connection, format!("the HTTP request failed: {e}")))?
        .map_err(|e| e.context(&url))?;
    std::fs::write(&args.out, &bytes).map_err(|e| {
        CliError::new(
            Kind::Output,
            format!("cannot write {}: {e}", args.out.display()),
        )
    })?;
    out.emit(
        format!(
            "{content_type}, {} bytes written to {}",
            bytes.len(),
            args.out.display()
        ),
        json!({
            "url": url,
            "content_type": content_type,
            "bytes": bytes.len(),
            "out": args.out.display().to_string(),
        }),
    )
}

/// The host part of `host:port` (brackets of an IPv6 address kept).
fn host_of(addr: &str) -> &str {
    match addr.rsplit_once(':') {
        Some((host, port)) if port.parse::<u16>().is_ok() => host,
        _ => addr,
    }
}

/// One GET: the image's content type and bytes, or why there is no image.
fn get(url: &str, timeout: Duration) -> Result<(String, Vec<u8>), CliError> {
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .timeout_global(Some(timeout))
        // A status is looked at below, so that its error names it.
        .http_status_as_error(false)
        .build()
        .into();
    let mut response = agent.get(url).call().map_err(http_error)?;
    let status = response.status();
    let content_type = response
        .headers()
        .get("content-type")
        .and_then(|v| v.to_str().ok())
        .unwrap_or("")
        .to_owned();
    if !status.is_success() {
        return Err(CliError::new(
            Kind::Device,
            format!("the server answered HTTP {status}, not an image"),
        ));
    }
    // A login page or an error page in HTML must not be saved as the picture.
    if !content_type
        .trim_start()
        .to_ascii_lowercase()
        .starts_with("image/")
    {
        let shown = if content_type.is_empty() {
            "no Content-Type"
        } else {
            &content_type
        };
        return Err(CliError::new(
            Kind::Malformed,
            format!("the server answered {shown}, not an image"),
        ));
    }
    let bytes = response
        .body_mut()
        .with_config()
        .limit(MAX_IMAGE_BYTES)
        .read_to_vec()
        .map_err(http_error)?;
    Ok((content_type, bytes))
}

fn http_error(e: ureq::Error) -> CliError {
    let kind = match &e {
        ureq::Error::Timeout(_) => Kind::Timeout,
        ureq::Error::BodyExceedsLimit(_) => Kind::Malformed,
        _ => Kind::Connection,
    };
    CliError::new(kind, format!("HTTP: {e}"))
}

#[cfg(test)]
mod tests {
    use super::host_of;

    #[test]
    fn the_host_of_the_protocol_address() {
        assert_eq!(host_of("10.0.0.5:42001"), "10.0.0.5");
        assert_eq!(host_of("[::1]:42001"), "[::1]");
        assert_eq!(host_of("kit.local:42001"), "kit.local");
        assert_eq!(host_of("kit.local"), "kit.local");
    }
}
