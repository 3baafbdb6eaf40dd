//! The rules of issue 29 for the text client, judged on what the client itself wrote and read
//! (`tap.rs`), with the numbers and wording every protocol's oracle uses:
//!
//! 6. **A connection is lost only for cause**: the client gives a connection up on time
//!    ("no reply to CMD long after its timeout") only if no reply of CMD's name reached it since
//!    it wrote CMD: not when the reply came (a decoder that lost it), nor when the device had
//!    acknowledged the motion (`ACK MOVE`: the device answers in order, the motion runs; issue
//!    29 L). Losses by the end of the stream (a cut, a restart) are the schedule's. Judged for
//!    the first call each connection failed with the loss, and for each loss the client
//!    reported (`connection_events`, on the connection of that moment).
//! 7. **A Timeout only when its reply did not arrive in time**: a call that ended `Timeout`
//!    after the client wrote its line must not have had a reply of its name read by the client
//!    before its deadline (the next such line after the write is the call's: one command per
//!    name on the wire).
//! 8. **A call without timeout ends, and frees what it held**: a `Duration::MAX` call must end
//!    (the workload drops it after `FOREVER_BOUND` and records it `Hung`); its name must be free
//!    afterwards (`quiet.rs`, rule 10's calls).
//! 9. **A stop is sent at once, faults or not**: `STOP()`/`FASTSTOP()` is written the instant it
//!    is called, unless one of the same name is on the wire unanswered (one command per name: by
//!    design, not judged) or `BYE()` was written. Issue 29 K: a queue full of calls whose
//!    callers gave up holds it. A stop called while a reconnecting client has no connection
//!    (a loss reported, the next session not yet restored) waits for the restore, as every
//!    call does (`ClientConfig::reconnect`): it is judged from the restore, and not at all if
//!    it ended before.
//!
//! And promise 5's documented errors after `close()` (issue 29 N): nothing is written after
//! `BYE()`, and a call after `close()` fails at once.

use std::collections::BTreeSet;
use std::time::Duration;

use gripper::wsg::text::line::{parse_reply, ReplyLine};
use gripper::wsg::text::ClientConfig;
use tokio::time::Instant;

use super::oracle::{request_name, same_err, ParseErrors};
use super::tap::{Line, SharedTap, TapLog};
use super::workload::{AfterClose, CallRec, Expect, Res, FOREVER_BOUND};

/// How far before its deadline a reply must have been read to count as in time (the task and
/// the caller's timer may run in either order at one instant).
const MARGIN: Duration = Duration::from_millis(1);

/// How late after a call began its stop may be written (the task's turn, simulated).
const AT_ONCE: Duration = Duration::from_millis(1);

const MOTIONS: [&str; 4] = ["HOME", "MOVE", "GRIP", "RELEASE"];

/// Whether `line` ends a command `name` that waits for `expect` (what the client's pairing
/// takes as its reply: a final reply, an `ERR`, or a wrong form of that name; a motion's `ACK`
/// does not end it, nor a push or an `ERR` without a name).
fn ends(line: &str, name: &str, expect: Expect) -> bool {
    // A line that is not UTF-8 (a flipped bit; the tap shows it with U+FFFD) is discarded by the
    // client's reader before any pairing.
    if line.contains('\u{FFFD}') {
        return false;
    }
    let n = match parse_reply(line) {
        Ok(ReplyLine::Ack(_)) if expect == Expect::Fin => return false,
        Ok(ReplyLine::Ack(n) | ReplyLine::Fin(n) | ReplyLine::Value { name: n, .. }) => n,
        Ok(ReplyLine::Err { name: Some(n), .. }) => n,
        _ => return false,
    };
    n.eq_ignore_ascii_case(name)
}

/// What a command of `name` waits for.
fn expect_of(name: &str, calls: &[CallRec]) -> Expect {
    if MOTIONS.contains(&name) {
        return Expect::Fin;
    }
    calls
        .iter()
        .find(|c| c.name.eq_ignore_ascii_case(name))
        .map_or(Expect::Ack, |c| c.expect)
}

/// The first line read after the line numbered `after` and before `to` that ends `name`, no
/// longer than the client reads.
/// Whether `line` is an `ERR <name> 14` or `15` (unknown command, format error): the gripper's
/// answer to a line it could not parse, under whatever name the line began with.
pub fn parse_error(line: &str) -> bool {
    matches!(
        parse_reply(line),
        Ok(ReplyLine::Err {
            name: Some(_),
            code: Some(14 | 15),
            ..
        })
    )
}

fn reply_read<'a>(
    log: &'a TapLog,
    name: &str,
    expect: Expect,
    (after, to): (u64, Instant),
    max_line_len: usize,
) -> Option<&'a Line> {
    log.read.lines.iter().find(|l| {
        l.seq > after && l.at < to && l.text.len() <= max_line_len && ends(&l.text, name, expect)
    })
}

/// Whether a command of `name` was on the wire unanswered at `at` (written, and no line that
/// ends it read since, by `at`).
pub fn busy(log: &TapLog, name: &str, expect: Expect, at: Instant, max_line_len: usize) -> bool {
    let last = log
        .written
        .lines
        .iter()
        .rfind(|l| l.at <= at && request_name(&l.text) == name);
    // `at` itself counts: a reply read at that instant freed the name by then.
    let until = at + Duration::from_nanos(1);
    last.is_some_and(|w| reply_read(log, name, expect, (w.seq, until), max_line_len).is_none())
}

/// The lines (`seq`) a reconnecting client wrote on a new connection to restore its session
/// (`ClientConfig::reconnect`): no call's. The restore writes the settings one at a time, each
/// after the reply to the one before, and no call is written before it ends (at or before
/// `restored`, the `Restored` event): the longest prefix of the connection's writes that are
/// setting lines so spaced. A queued setting call answered before the next write looks the
/// same: it is then taken for the restore's, and not judged (no false alarm either way).
pub fn restore_writes(log: &TapLog, restored: Option<Instant>) -> BTreeSet<u64> {
    let mut out = BTreeSet::new();
    let mut prev: Option<u64> = None;
    for w in &log.written.lines {
        let setting = super::restore::setting_of(&w.text, &request_name(&w.text)).is_some();
        let replied = prev.is_none_or(|p| {
            log.read
                .lines
                .iter()
                .any(|r| r.seq > p && r.seq < w.seq && !r.text.starts_with('@'))
        });
        if !setting || !replied || restored.is_some_and(|r| w.at > r) {
            break;
        }
        out.insert(w.seq);
        prev = Some(w.seq);
    }
    out
}

/// When each call's own line was written (time, place), if it was: the writes of a line pair
/// with the calls of that line in the order the calls began (a name's requests wait in order;
/// identical lines of several callers are told apart only so). The restore's writes
/// (`restores[client][conn]`) are no call's.
fn own_writes(
    calls: &[CallRec],
    taps: &[Vec<SharedTap>],
    restores: &[Vec<BTreeSet<u64>>],
) -> Vec<Option<(Instant, u64)>> {
    let mut own = vec![None; calls.len()];
    let mut order: Vec<usize> = (0..calls.len()).collect();
    order.sort_by_key(|&i| calls[i].start);
    let mut taken = BTreeSet::new();
    for i in order {
        let c = &calls[i];
        let Some(tap) = taps[c.client].get(c.conn) else {
            continue;
        };
        let log = tap.lock().unwrap();
        let w = log.written.lines.iter().find(|l| {
            l.at >= c.start
                && l.at <= c.end
                && l.text == c.line
                && !taken.contains(&(c.client, c.conn, l.seq))
                && !restores[c.client][c.conn].contains(&l.seq)
        });
        if let Some(w) = w {
            taken.insert((c.client, c.conn, w.seq));
            own[i] = Some((w.at, w.seq));
        }
    }
    own
}

/// Every rule above. What each connection carried, client `i`'s connection `k` at `[i][k]`:
/// the client's side of the wire (`taps`), and the device's parse errors that answered a
/// request damaged on the way (`damaged_errors`, `oracle::damaged_parse_errors`).
pub fn check(
    calls: &[CallRec],
    (taps, damaged_errors): (&[Vec<SharedTap>], &[Vec<ParseErrors>]),
    configs: &[ClientConfig],
    after_close: &[AfterClose],
    downs: &[Vec<super::Down>],
    restores: &[Vec<BTreeSet<u64>>],
    exact: bool,
) -> Vec<String> {
    let mut out = Vec::new();
    let mut judged_losses = BTreeSet::new();
    let own = own_writes(calls, taps, restores);
    for (i, c) in calls.iter().enumerate() {
        let Some(tap) = taps[c.client].get(c.conn) else {
            continue;
        };
        let log = tap.lock().unwrap();
        let max = configs[c.client].max_line_len;
        let who = format!("client {} {}", c.client, c.line);
        match &c.res {
            Res::Timeout => {
                let queue_len = configs[c.client].queue_len;
                let damaged = &damaged_errors[c.client][c.conn];
                out.extend(timeout(i, calls, &own, &log, damaged, (max, queue_len)));
            }
            Res::Lost(why) if judged_losses.insert((c.client, c.conn)) => {
                let who = format!("client {} (connection {})", c.client, c.conn);
                out.extend(loss(&who, (c.end, why), calls, &log, (max, exact)));
            }
            Res::Hung => {
                // M: the call's own command, or the one of its name it waited behind, was never
                // answered (its reply was damaged): the name was still busy when it was dropped.
                // A call left waiting after its name freed up is another bug: untagged.
                // K with M: never written, behind a queue full of such calls.
                // (Not written while its caller waited: a line of its text written after the
                // drop is not the call's, wsg-text:0x3f4ccb36950e9049.)
                let full = own[i].is_none_or(|(w, _)| w >= c.end)
                    && queued_before(i, calls, &own) >= configs[c.client].queue_len.max(1);
                // (Strictly before the drop: the caller's next line may draw a reply at once.)
                let dropped = c.end - Duration::from_nanos(1);
                let tag = if busy(&log, c.name, c.expect, dropped, max) {
                    " [no reply of its name reached the client]"
                } else if full {
                    FULL
                } else {
                    ""
                };
                out.push(format!(
                    "8 (a call without timeout ends, and frees what it held): {who} (no timeout) had not ended {FOREVER_BOUND:?} after it began{tag}"
                ));
            }
            _ => {}
        }
        if matches!(c.name, "STOP" | "FASTSTOP") {
            out.extend(stop(
                i,
                calls,
                &own,
                &log,
                &configs[c.client],
                &downs[c.client],
            ));
        }
    }
    for a in after_close {
        let Some(tap) = taps[a.client].get(a.conn) else {
            continue;
        };
        let log = tap.lock().unwrap();
        out.extend(closed(a, &log, configs[a.client].max_line_len));
    }
    out
}

/// Rule 7 for call `i`, which ended `Timeout`.
fn timeout(
    i: usize,
    calls: &[CallRec],
    own: &[Option<(Instant, u64)>],
    log: &TapLog,
    damaged_errors: &[(Instant, String)],
    (max, queue_len): (usize, usize),
) -> Option<String> {
    let c = &calls[i];
    let deadline = c.start.checked_add(c.timeout)?;
    let (w, seq) = own[i].filter(|(w, _)| *w < deadline)?;
    // Another live call of the client with the very same line: the write may be either's. On
    // any connection: a call made during a reconnect that no write was credited to stays filed
    // on the old one, yet its request may be this write, and this call's own a later one
    // (wsg-text:0x6fe85ed992023b5a: two `POS?`, the later call's written first after the
    // reconnect; the client has one connection at a time, so a call live at the write was in it).
    let shared = calls.iter().enumerate().any(|(j, o)| {
        j != i && o.client == c.client && o.line == c.line && o.start <= w && w <= o.end
    });
    if shared {
        return None;
    }
    let mut r = reply_read(log, c.name, c.expect, (seq, deadline), max)?;
    // An `ERR <name> 14|15` followed by another reply of the name (its `ACK`, a value) before
    // the deadline answered another request, damaged into the name: the gripper answers in
    // order and answers each line once, and the client holds such a line until it can tell
    // (src/wsg/text/book.rs `Held`; wsg-text:0x0518b210eda1929b: `GRIPSTATE?` read as
    // `GRIP\x13TATE?`, then GRIP's own `ACK GRIP`). The call's reply is a later one.
    // So too one the device sent in answer to a request damaged on the way (it answers under
    // whatever name the damage left): the call's reply is a later one, if any came in time
    // (`oracle::damaged_parse_errors`; wsg-text:0xe8d183fd8b4c4f31).
    let ack = format!("ACK {}", c.name);
    let answers_damage = |r: &Line| {
        damaged_errors.iter().any(|(at, text)| {
            *at <= r.at && *at + super::oracle::DAMAGE_REACH >= c.start && same_err(text, &r.text)
        })
    };
    while parse_error(&r.text)
        && (answers_damage(r)
            || log.read.lines.iter().any(|l| {
                l.seq > r.seq
                    && l.at < deadline
                    && (l.text == ack || (!parse_error(&l.text) && ends(&l.text, c.name, c.expect)))
            }))
    {
        r = reply_read(log, c.name, c.expect, (r.seq, deadline), max)?;
    }
    (r.at + MARGIN <= deadline).then(|| {
        format!(
            "7 (a Timeout only when its reply did not arrive in time): client {} {} (timeout {:?}) ended Timeout, yet the client wrote it {:?} after the call began and read {:?} {:?} after, {:?} before its deadline{}{}",
            c.client,
            c.line,
            c.timeout,
            w - c.start,
            r.text,
            r.at - w,
            deadline - r.at,
            probe_tag(i, calls, own, log, (deadline, r.at, queue_len)),
            refusal_in_doubt_tag(c.name, r, log, deadline),
        )
    })
}

/// The tag of a motion's Timeout whose reply was a parse error (`ERR <name> 14|15`) followed,
/// before its deadline, by two lines that could not be read. The client holds such a line
/// while an earlier command's reply is due (it may answer that line, damaged into the name);
/// after a line that could not be read (maybe the motion's `ACK`) it asks the gripper whether
/// the motion runs, and takes the line for the motion's own only on two reports of no motion
/// with nothing unreadable since (src/wsg/text/book.rs `Book::doubt_held_motion`). A second
/// unreadable line may have held the motion's `FIN`, so from then on no report can tell a
/// motion that never ran from one that ran and ended: the call times out rather than take a
/// refusal that may be another line's (`wsg-text:0x939e47e5d1d27846` after session 11's
/// review: the second check's reply read as `GRIPSTATE96`).
///
/// So too when, after one unreadable line, the state reported was another motion's (a
/// `GRIPSTATE=` of a moving state other than this motion's own, shared note §4.4): a motion
/// already running says nothing of this one, and the client asks again until the deadline
/// (`wsg-text:0x5148348896596cd1`: `RELEASE()` in doubt while `MOVE` ran, `GRIPSTATE=6`).
fn refusal_in_doubt_tag(name: &str, r: &Line, log: &TapLog, deadline: Instant) -> &'static str {
    let after = || {
        log.read
            .lines
            .iter()
            .filter(|l| l.seq > r.seq && l.at < deadline)
    };
    let unreadable = after().filter(|l| damaged(&l.text)).count();
    let own = match name {
        "GRIP" => "1",
        "RELEASE" => "5",
        _ => "6",
    };
    let another_motion = after().any(|l| {
        let state = l.text.strip_prefix("GRIPSTATE=");
        state.is_some_and(|v| matches!(v, "1" | "5" | "6") && v != own)
    });
    let doubt = unreadable >= 2 || (unreadable >= 1 && another_motion);
    if MOTIONS.contains(&name) && parse_error(&r.text) && doubt {
        " [a parse error in its name, then lines that could not tell before its deadline]"
    } else {
        ""
    }
}

/// The queries the text client writes on its own (its probes, issue 29 L and M).
const PROBES: [&str; 4] = ["GRIPSTATE?", "POS?", "SPEED?", "FORCE?"];

/// The tag of a Timeout whose write of its text may have been the client's own probe: a
/// probe's query behind a full queue, else [`own_probe`]'s. A probe's answer serves a call of
/// its query made before the probe was written, once the call leaves the client's queue (the
/// client's `Book::answer_from_probe`); a call held in the queue (`queue_len` calls ahead of it still
/// not written when the answer was read) may never leave it in time, and its text written by
/// then is then the probe's, not its own: the wire cannot tell which
/// (`wsg-text:0x3b91b8f4d71e229e`: `GRIPSTATE?` in the channel behind `GRIP(32,40,21.5)`,
/// which waited for the running grip). "Ahead" counts the calls begun by the time the answer
/// was read, not only those begun before the call: while the channel is full, a freed slot goes
/// to the first sender polled, so a call begun later may enter it first. A caller woken for a
/// slot 16 ms after it asked was overtaken by `GRIP(…)` and `MOVE(…)` begun in the very step
/// that freed the slots, and the two filled the queue (`wsg-text:0x14b97cbc075d3039`).
fn probe_tag(
    i: usize,
    calls: &[CallRec],
    own: &[Option<(Instant, u64)>],
    log: &TapLog,
    (deadline, read, queue_len): (Instant, Instant, usize),
) -> &'static str {
    let c = &calls[i];
    let ahead = calls
        .iter()
        .enumerate()
        .filter(|&(j, o)| {
            j != i
                && o.client == c.client
                && o.conn == c.conn
                && o.start <= read
                && own[j].is_none_or(|(w, _)| w > read)
                && (o.end > read
                    || matches!(o.res, Res::Timeout | Res::Cancelled | Res::Hung)
                        && own[j].is_none())
        })
        .count();
    // The full queue first: it explains the Timeout (the call never reached the task), a
    // probe on the wire alone does not since a probe's answer serves the calls behind it.
    if PROBES.contains(&c.line.as_str()) && ahead >= queue_len.max(1) {
        " [a probe's query behind a full queue: its write may have been the client's own probe]"
    } else {
        own_probe(i, calls, own, log, deadline)
    }
}

/// The tag of a Timeout next to a line of the call's text that the client wrote on its own, no
/// call's write (the probes of issue 29 L and M: `GRIPSTATE?`, `POS?`, `SPEED?`), within
/// `PROBE_REACH` before the call began and its deadline: which of the two writes a reply answers
/// cannot be told from the wire, and the call may have waited behind the probe (an open finding
/// of the text client, `wsg-text:0x3b91b8f4d71e229e`).
fn own_probe(
    i: usize,
    calls: &[CallRec],
    own: &[Option<(Instant, u64)>],
    log: &TapLog,
    deadline: Instant,
) -> &'static str {
    const PROBE_REACH: Duration = Duration::from_secs(5);
    let c = &calls[i];
    let attributed: BTreeSet<u64> = calls
        .iter()
        .zip(own)
        .filter(|(o, _)| o.client == c.client && o.conn == c.conn)
        .filter_map(|(_, w)| w.map(|(_, seq)| seq))
        .collect();
    let probe = log.written.lines.iter().any(|l| {
        l.text == c.line
            && l.at <= deadline
            && l.at + PROBE_REACH >= c.start
            && !attributed.contains(&l.seq)
    });
    if probe {
        " [a line of its text the client wrote on its own (a probe) was on the wire]"
    } else {
        ""
    }
}

/// Rule 6 for a loss (`why`) declared at `end` on a connection (`log`).
fn loss(
    who: &str,
    (end, why): (Instant, &str),
    calls: &[CallRec],
    log: &TapLog,
    (max, exact): (usize, bool),
) -> Option<String> {
    let (_, command) = why.split_once("no reply to ")?;
    let command = command.split(" long after its timeout").next()?;
    let name = request_name(command);
    let expect = expect_of(&name, calls);
    let w = log
        .written
        .lines
        .iter()
        .rfind(|l| l.at <= end && l.text == command)?;
    if let Some(r) = reply_read(log, &name, expect, (w.seq, end), max) {
        return Some(format!(
            "6 (a connection is lost only for cause): {who} was given up for no reply to {command}, yet the client read {:?} {:?} after writing it and {:?} before giving up",
            r.text,
            r.at - w.at,
            end - r.at
        ));
    }
    let ack = format!("ACK {name}");
    let acked = log
        .read
        .lines
        .iter()
        .find(|l| l.seq > w.seq && l.at <= end && l.text == ack)?;
    // With corruption the motion's FIN may have reached the client damaged (a flipped LF joins
    // it to the line before: `ERR MOVE 4JFIN GRIP`, wsg-text:0x9a652396cb6037ed): then it
    // never came, and the give-up after the probes is the documented one.
    // Or the flipped LF became a printable byte inside the free text of an error, so the line
    // before still parses (`ERR GRIP 4 E_ALREADY_RUNNINGJFIN MOVE`, wsg-text:0x02ea1795365f5d6c):
    // the FIN's text arrived, run into another line, and never as a line of its own.
    let fin = format!("FIN {name}");
    let damaged = !exact
        && log.read.lines.iter().any(|l| {
            l.seq > acked.seq
                && l.at <= end
                && (damaged(&l.text) || l.text != fin && l.text.ends_with(&fin))
        });
    (!damaged).then_some(acked).map(|r| {
        format!(
            "6 (a connection is lost only for cause): {who} was given up for no reply to {command}, which the device had acknowledged ({ack:?} read {:?} after writing it, {:?} before giving up) [an acknowledged motion: the device answers in order]",
            r.at - w.at,
            end - r.at
        )
    })
}

/// Rule 6 for each loss a client reported (`losses[i]`, from its connection events), on the
/// connection of that moment (the last one `conns[i]` opened by then): a give-up on time needs
/// a command whose reply never reached the client. A loss the same call-based check already
/// reported is not reported twice.
pub fn losses(
    losses: &[Vec<(Instant, String)>],
    conns: &[Vec<super::Conn>],
    calls: &[CallRec],
    configs: &[ClientConfig],
    exact: bool,
) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for (i, reported) in losses.iter().enumerate() {
        for (t, why) in reported {
            let Some((k, conn)) = conns[i].iter().enumerate().rfind(|(_, c)| c.opened <= *t) else {
                continue;
            };
            let who = format!("client {i} (connection {k}, its reported loss)");
            let log = conn.tap.lock().unwrap();
            let max = configs[i].max_line_len;
            if let Some(v) = loss(&who, (*t, why), calls, &log, (max, exact)) {
                if !out.contains(&v) {
                    out.push(v);
                }
            }
        }
    }
    out
}

/// The names of GCL's replies (chapter 2 and 3; the client's commands).
pub(super) const NAMES: [&str; 17] = [
    "HOME",
    "MOVE",
    "GRIP",
    "RELEASE",
    "STOP",
    "FASTSTOP",
    "FSACK",
    "BYE",
    "POS",
    "SPEED",
    "FORCE",
    "GRIPSTATE",
    "TEMP",
    "VERBOSE",
    "PWT",
    "CLT",
    "AUTOSEND",
];

/// Whether a line the client read is not one the device sends (so a bit was flipped in it, or
/// in the LF that ended the line before): unreadable, a name no reply carries, an `ERR`
/// without its code.
fn damaged(line: &str) -> bool {
    let known = |n: &str| NAMES.iter().any(|k| k.eq_ignore_ascii_case(n));
    match parse_reply(line) {
        _ if line.contains('\u{FFFD}') => true,
        Err(_) => true,
        Ok(ReplyLine::Err { name, code, .. }) => code.is_none() || name.is_some_and(|n| !known(n)),
        Ok(ReplyLine::Ack(n) | ReplyLine::Fin(n)) => !known(n),
        Ok(ReplyLine::Value { name, .. } | ReplyLine::Push { name, .. }) => !known(name),
    }
}

/// Rule 9 for call `i`, a `STOP()` or `FASTSTOP()`.
fn stop(
    i: usize,
    calls: &[CallRec],
    own: &[Option<(Instant, u64)>],
    log: &TapLog,
    config: &ClientConfig,
    downs: &[super::Down],
) -> Option<String> {
    let c = &calls[i];
    let max = config.max_line_len;
    // Without a connection at its start (or from a loss within AT_ONCE of it), the stop goes
    // out once the next session is restored. The latest such episode counts: a session restored
    // at the very instant a new loss began gave the stop no connection
    // (wsg-text:0xcf19433c2e45e996: a STOP() made as the restore of one connection and the loss
    // of the next fell on one instant; wsg-text:0x98ad3703417b4ab0: a FASTSTOP() the same way,
    // then a failed restore and a second attempt).
    let down = downs.iter().rev().find(|(lost, restored)| {
        *lost <= c.start + AT_ONCE && restored.is_none_or(|r| r >= c.start)
    });
    // A session restored while a new loss began (a device restarting at that very instant)
    // gave the stop no connection either: the next restore counts (wsg-text:0x23c8c375f62cd632:
    // a FASTSTOP() made during a backoff, the first restore lost at once, written 64 ms later
    // at the second).
    let mut down = down;
    while let Some((_, Some(r))) = down {
        match downs
            .iter()
            .find(|(lost, _)| *lost >= *r && *lost <= *r + AT_ONCE)
        {
            Some(next) if !std::ptr::eq(next, down.unwrap()) => down = Some(next),
            _ => break,
        }
    }
    let from = match down {
        None => c.start,
        Some((_, Some(r))) if *r < c.end => *r,
        Some(_) => return None,
    };
    let ended_with_connection = matches!(c.res, Res::Lost(_) | Res::Closed);
    if c.timeout.is_zero() || ended_with_connection || c.end <= c.start {
        return None;
    }
    // A stop made without a connection has no connection of its own until it is written: one
    // of the calls it waits behind may go out on the restored one (wsg-text:0x68ed3d9361051ce9:
    // an earlier STOP() written at the restore, this one behind it, never written, its caller
    // gone 73 ms later).
    let same_conn = |o: &CallRec| o.client == c.client && (o.conn == c.conn || from > c.start);
    let unwritten_at = |j: usize, at: Instant| own[j].is_none_or(|(w, _)| w > at);
    // One command per name: a stop behind an unanswered one of its name, or behind an earlier
    // call of its name still waiting to be written, waits (by design, not judged).
    let earlier_waiting = calls.iter().enumerate().any(|(j, o)| {
        j != i
            && same_conn(o)
            && o.name == c.name
            && o.start <= c.start
            && o.end > c.start
            && unwritten_at(j, c.start)
    });
    if earlier_waiting || busy(log, c.name, Expect::Ack, c.start, max) {
        return None;
    }
    let bye = log
        .written
        .lines
        .iter()
        .any(|l| l.at <= c.start && l.text == "BYE()");
    if bye {
        return None;
    }
    let written = own[i].map(|(w, _)| w.saturating_duration_since(from));
    if written.is_some_and(|d| d <= AT_ONCE) {
        return None;
    }
    let restored = if from > c.start {
        format!(
            ", counted from the restore {:?} after it was called",
            from - c.start
        )
    } else {
        String::new()
    };
    // Issue 29 K: the client's queue (`queue_len` calls in its channel and as many again waiting
    // behind busy names) was full: at least `queue_len` other calls of the connection had begun
    // and not had their line written, each still waiting or given up (timed out, dropped)
    // without being written. A request whose caller gave up leaves the queue only when a request
    // is added behind a busy name or its own name frees up, so a queue of them can hold a stop
    // behind a motion for as long as the motion runs.
    let queued = queued_before(i, calls, own);
    let tag = if queued >= config.queue_len.max(1) {
        FULL
    } else {
        ""
    };
    Some(format!(
        "9 (a stop is sent at once, faults or not): client {} {} ({:?}, ended {:?}) was written {written:?} after it was called{restored} (none of its name on the wire; {queued} other calls not yet sent, queue_len {}){tag}",
        c.client, c.line, c.timeout, c.res, config.queue_len
    ))
}

/// The tag of a call held behind a full queue (issue 29 K).
const FULL: &str = " [behind a full queue of calls not yet sent]";

/// How many other calls of call `i`'s connection had begun by its start and not had their line
/// written, each still waiting then, or given up (timed out, dropped, dropped by the workload
/// without timeout) without ever being written: the client's queue holds them (`queue_len` in
/// its channel, as many again behind busy names; a request whose caller gave up leaves only
/// when a request is added behind a busy name or its own name frees up).
fn queued_before(i: usize, calls: &[CallRec], own: &[Option<(Instant, u64)>]) -> usize {
    let c = &calls[i];
    calls
        .iter()
        .enumerate()
        .filter(|&(j, o)| {
            j != i
                && o.client == c.client
                && o.conn == c.conn
                && o.start <= c.start
                && own[j].is_none_or(|(w, _)| w > c.start)
                && (o.end > c.start
                    || matches!(o.res, Res::Timeout | Res::Cancelled | Res::Hung)
                        && own[j].is_none())
        })
        .count()
}

/// Promise 5 after a `close()` of the fault phase: nothing is written after `BYE()`, and the
/// call made right after `close()` fails with `Closed` (or `ConnectionLost`), not a timeout.
fn closed(a: &AfterClose, log: &TapLog, max: usize) -> Vec<String> {
    let mut out = Vec::new();
    if a.close.1 == Res::Hung {
        // Dropped at `a.after.0`; judged strictly before (as a call's `Hung`, rule 8).
        let dropped = a.after.0 - Duration::from_nanos(1);
        let tag = if busy(log, "BYE", Expect::Ack, dropped, max) {
            " [no reply of its name reached the client]"
        } else {
            ""
        };
        out.push(format!(
            "8 (a call without timeout ends, and frees what it held): client {} BYE() (close(), no timeout) had not ended {FOREVER_BOUND:?} after it began{tag}",
            a.client
        ));
    }
    let bye_acked = a.close.1 == Res::Done;
    let tag = if bye_acked {
        ""
    } else {
        " [BYE() was not answered ACK BYE]"
    };
    // A `close()` that ended before `BYE()` went out leaves the connection open (documented).
    let bye_written = log
        .written
        .lines
        .iter()
        .any(|l| l.at >= a.close.0 && l.at <= a.after.0 && l.text == "BYE()");
    if bye_written && !matches!(a.after.2, Res::Closed | Res::Lost(_)) {
        out.push(format!(
            "5 (documented errors): client {}: close() ended {:?}, then a call ended {:?} after {:?}, not Closed{tag}",
            a.client,
            a.close.1,
            a.after.2,
            a.after.1 - a.after.0
        ));
    }
    let bye = log
        .written
        .lines
        .iter()
        .position(|l| l.at >= a.close.0 && l.text == "BYE()");
    if let Some(i) = bye {
        let later: Vec<&str> = log.written.lines[i + 1..]
            .iter()
            .map(|l| l.text.as_str())
            .collect();
        if !later.is_empty() {
            out.push(format!(
                "5 (nothing is written after BYE()): client {}: the client wrote {later:?} after BYE()",
                a.client
            ));
        }
    }
    out
}
