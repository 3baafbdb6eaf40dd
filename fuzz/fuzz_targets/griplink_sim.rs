//! The GRIPLINK simulator's command parser and controller state machine fed arbitrary lines.
//!
//! Input: `[config, lines..]`. The first byte picks the controller (GRIPLINK-ET4 or WPG,
//! standalone or master, time scale 0, 0.001, 1 or 10) and how far the simulated clock moves
//! between commands; the rest is cut into lines by the line codec and handled as the server's
//! connection loop does: `clean_line`, empty lines skipped, `parse_command`, then
//! `Controller::execute`; a held reply is polled at the times `next_wake` names, as the server's
//! `hold` does.
//!
//! Checked, besides "no panic":
//! - no spinning: while a reply is held, `next_wake` is always later than now (the server sleeps
//!   until then); a reply held longer than a simulated day or 100 000 wake-ups ends the input;
//! - every reply line is one the client can read: `parse_reply` accepts it, and when the client
//!   can send the command, `interpret` with that command's expectation gives a success or the
//!   device's `ERR` — never "malformed" or "unexpected";
//! - a command the client encodes is read back by the simulator's parser as the same command.
#![no_main]

use std::time::Duration;

use bytes::BytesMut;
use gripper::griplink::codec::{Discarded, Line, LineCodec};
use gripper::griplink::reply::{interpret, parse_reply};
use gripper::griplink::sim::controller::{Outcome, Session};
use gripper::griplink::sim::parse::{clean_line, parse_command};
use gripper::griplink::sim::{Controller, Role, SimConfig};
use gripper::griplink::{Command, Error};
use gripper_fuzz as _; // the bounded allocator
use libfuzzer_sys::fuzz_target;
use tokio_util::codec::Decoder;

/// Checks a reply the simulator sends to `command`.
fn check_reply(command: Option<&Command>, reply: &str) {
    if let Err(e) = parse_reply(reply) {
        panic!("the client cannot parse the simulator's reply {reply:?}: {e}");
    }
    let Some(command) = command else { return };
    let Ok(line) = command.encode() else { return };
    match interpret(&line, command.expect(), reply) {
        Ok(_) | Err(Error::Device { .. }) => {}
        Err(e) => panic!("{command:?} ({line:?}) answered {reply:?}: {e}"),
    }
}

/// Longest simulated jump followed, and most wake-ups, while a reply is held.
const MAX_HOLD: Duration = Duration::from_secs(86_400);
const MAX_WAKES: usize = 100_000;

fuzz_target!(|data: &[u8]| {
    let Some((&config, stream)) = data.split_first() else {
        return;
    };
    let mut sim = if config & 1 == 0 {
        SimConfig::et4()
    } else {
        SimConfig::wpg()
    };
    if config & 2 != 0 {
        sim.role = Role::Master;
    }
    sim.time_scale = [0.0, 0.001, 1.0, 10.0][usize::from((config >> 2) & 3)];
    let step = [
        Duration::ZERO,
        Duration::from_millis(1),
        Duration::from_millis(100),
        Duration::from_secs(3),
    ][usize::from((config >> 4) & 3)];
    let mut controller = Controller::new(sim);
    let mut session = Session::default();
    let mut now = Duration::ZERO;

    let mut codec = LineCodec::default();
    let mut buf = BytesMut::from(stream);
    let mut lines = Vec::new();
    while let Some(line) = codec.decode_eof(&mut buf).unwrap() {
        lines.push(line);
    }

    for line in lines {
        now += step;
        let text = match line {
            Line::Text(text) => text,
            // The server answers these with ERR without parsing anything.
            Line::Discarded(Discarded::TooLong | Discarded::NotAscii) => continue,
        };
        let clean = clean_line(&text);
        if clean.is_empty() {
            continue;
        }
        let command = match parse_command(&clean) {
            Ok(command) => command,
            Err(_status) => continue, // answered `ERR <status>` by `error_line`
        };
        // The client's encoding of the command reads back as the same command.
        if let Ok(encoded) = command.encode() {
            assert_eq!(
                parse_command(&encoded).as_ref(),
                Ok(&command),
                "{clean:?} parsed as {command:?}, which encodes as {encoded:?}"
            );
        }
        let reply = match controller.execute(&mut session, &command, now) {
            Outcome::Reply(reply) => reply,
            Outcome::Bye => "ACK".to_owned(),
            Outcome::Wait(wait) => {
                let mut wakes = 0;
                loop {
                    if let Some(reply) = controller.poll(&session, &wait, now) {
                        break reply;
                    }
                    // The server sleeps until `next_wake`: a wake that is not later than now,
                    // with the reply still not due, would make it spin.
                    let wake = controller.next_wake(&wait, now);
                    assert!(
                        wake > now,
                        "{command:?}: next_wake {wake:?} is not after {now:?} and the reply is \
                         not due ({wait:?})"
                    );
                    wakes += 1;
                    if wake - now > MAX_HOLD || wakes > MAX_WAKES {
                        // A reply held as long as the command asked (a slow real-time motion,
                        // a WAITVAL timeout of years): the connection waits; this input ends.
                        return;
                    }
                    now = wake;
                }
            }
        };
        check_reply(Some(&command), &reply);
    }
});
