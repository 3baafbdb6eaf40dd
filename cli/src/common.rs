//! Small pieces every protocol's commands share: addresses with the manual's default port, and
//! durations on the command line.

use std::net::{IpAddr, SocketAddr};
use std::time::Duration;

/// `addr` as `host:port`, with `default_port` when it names only a host: `10.0.0.5`,
/// `gripper.local` and `::1` get the port; `10.0.0.5:1000`, `[::1]:1000` keep theirs.
pub fn with_default_port(addr: &str, default_port: u16) -> String {
    if addr.parse::<SocketAddr>().is_ok() {
        return addr.to_owned();
    }
    if let Ok(ip) = addr
        .trim_start_matches('[')
        .trim_end_matches(']')
        .parse::<IpAddr>()
    {
        return SocketAddr::new(ip, default_port).to_string();
    }
    if addr.contains(':') {
        // host:port with a name; anything odd is left for the resolver to refuse clearly.
        return addr.to_owned();
    }
    format!("{addr}:{default_port}")
}

/// Splits the `NAME (description)` form in which the library's status and state enums display
/// themselves; anything else is all name.
pub fn split_name(display: &str) -> (&str, &str) {
    match display.split_once(" (") {
        Some((name, rest)) => (name, rest.strip_suffix(')').unwrap_or(rest)),
        None => (display, ""),
    }
}

/// Parses a duration: `500ms`, `2s`, `1.5` (seconds), `1m`. Zero, negative and non-finite
/// values are refused: a zero timeout would fail every call.
pub fn parse_duration(text: &str) -> Result<Duration, String> {
    let text = text.trim();
    let (number, scale) = if let Some(n) = text.strip_suffix("ms") {
        (n, 1e-3)
    } else if let Some(n) = text.strip_suffix('s') {
        (n, 1.0)
    } else if let Some(n) = text.strip_suffix('m') {
        (n, 60.0)
    } else {
        (text, 1.0)
    };
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("{text:?} is not a duration (e.g. 500ms, 2s, 1.5)"))?;
    let seconds = value * scale;
    if !seconds.is_finite() || seconds <= 0.0 {
        return Err(format!("{text:?}: a duration must be positive"));
    }
    Duration::try_from_secs_f64(seconds).map_err(|e| format!("{text:?}: {e}"))
}

/// Parses hex bytes: `"01 0a FF"`, `"010aff"`, `"0x01,0x0a"`; separators are spaces, commas,
/// colons and `0x` prefixes. An odd number of digits is refused rather than guessed at.
pub fn parse_hex(text: &str) -> Result<Vec<u8>, String> {
    let digits: String = text
        .split(|c: char| c.is_whitespace() || c == ',' || c == ':')
        .map(|word| {
            word.strip_prefix("0x")
                .or(word.strip_prefix("0X"))
                .unwrap_or(word)
        })
        .collect();
    if digits.len() % 2 != 0 {
        return Err(format!("{text:?}: hex needs two digits per byte"));
    }
    (0..digits.len())
        .step_by(2)
        .map(|i| {
            digits
                .get(i..i + 2)
                .and_then(|pair| u8::from_str_radix(pair, 16).ok())
                .ok_or_else(|| format!("{text:?} is not hex"))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex() {
        assert_eq!(parse_hex(""), Ok(vec![]));
        assert_eq!(parse_hex("01 0a FF"), Ok(vec![1, 10, 255]));
        assert_eq!(parse_hex("010aff"), Ok(vec![1, 10, 255]));
        assert_eq!(parse_hex("0x01,0x0A"), Ok(vec![1, 10]));
        assert!(parse_hex("123").is_err());
        assert!(parse_hex("zz").is_err());
        // Multi-byte characters must not split a pair mid-character.
        assert!(parse_hex("é1").is_err());
    }

    #[test]
    fn default_port_only_when_missing() {
        assert_eq!(with_default_port("10.0.0.5", 1000), "10.0.0.5:1000");
        assert_eq!(with_default_port("10.0.0.5:7", 1000), "10.0.0.5:7");
        assert_eq!(with_default_port("::1", 1000), "[::1]:1000");
        assert_eq!(with_default_port("[::1]", 1000), "[::1]:1000");
        assert_eq!(with_default_port("[::1]:7", 1000), "[::1]:7");
        assert_eq!(with_default_port("wsg.local", 1000), "wsg.local:1000");
        assert_eq!(with_default_port("wsg.local:7", 1000), "wsg.local:7");
    }

    #[test]
    fn durations() {
        assert_eq!(parse_duration("500ms"), Ok(Duration::from_millis(500)));
        assert_eq!(parse_duration("2s"), Ok(Duration::from_secs(2)));
        assert_eq!(parse_duration("1.5"), Ok(Duration::from_millis(1500)));
        assert_eq!(parse_duration("1m"), Ok(Duration::from_secs(60)));
        assert!(parse_duration("0").is_err());
        assert!(parse_duration("-1s").is_err());
        assert!(parse_duration("inf").is_err());
        assert!(parse_duration("soon").is_err());
    }
}
