//! The promises of issue 20 as they apply to GCL, checked against the simulator's record of
//! every line each text session sent and got (`SimEvent::TextRequest`/`TextReply`):
//!
//! 1. **Bounded**: every call ends within its timeout plus `CALL_SLACK` (panics, leaks and
//!    hangs: `core`).
//! 2. **The device's answer to that request**: a value, an `ACK`/`FIN`, or an `ERR` a call
//!    returned is the first reply *of the call's command name* the device sent, on that
//!    client's session, after a request line of that call received during the call; one request
//!    answers one call. Replies carry no id, only the name (manual chapter 2), so this is the
//!    pairing the client must get right, with queries answered while a motion waits for its
//!    `FIN`. On a session, requests and replies of one name alternate (the client keeps one
//!    command of each name on the wire). Pushes a stream hands out are `@NAME=value` lines the
//!    device sent to that client.
//! 3. **A stop is not held back**: `STOP()`/`FASTSTOP()` Ok is its own `ACK` (2, named 3 for
//!    stops); live in the quiet phase (`mod.rs`).
//! 4. **FIN means stopped**: a motion reported complete was answered by a `FIN` the device
//!    sent with its fingers stopped.
//! 5. **Recovery and documented errors**: `Closed` only after `close()`; the quiet phase.
//!
//! In a run with corruption (GCL has no checksum: a flipped bit makes another well-formed
//! line), a request is known by its name only and a reply is held to its form (a value, an
//! `ACK`/`FIN`, an `ERR`), not its content; the alternation check is off.

use std::collections::BTreeMap;
use std::time::Duration;

use gripper::wsg::sim::{SessionId, SimEvent, SimRecording};
use gripper::wsg::text::line::{parse_number, parse_reply, ReplyLine};
use tokio::time::Instant;

use super::workload::{CallRec, Expect, PushRec, Res};

/// How late a call may end after its timeout (the task's own bookkeeping; simulated time).
const CALL_SLACK: Duration = Duration::from_millis(10);

/// One line of a session, as recorded.
struct Ev<'a> {
    at: Instant,
    /// A command line the device read.
    request: Option<&'a str>,
    /// A line the device sent, and whether the fingers moved then.
    reply: Option<(&'a str, bool)>,
}

/// The bare name of a command line: `MOVE(20)` → `MOVE`, `POS?` → `POS`.
pub fn request_name(line: &str) -> String {
    line.chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect::<String>()
        .to_ascii_uppercase()
}

/// What a reply line answers a command `name` expecting `expect` with, if it is that
/// command's final reply (a motion's `ACK` is not; pushes are not replies).
fn final_of(line: &str, name: &str, expect: Expect) -> Option<Res> {
    let is = |n: &str| n.eq_ignore_ascii_case(name);
    match parse_reply(line).ok()? {
        ReplyLine::Err { name: Some(n), .. } if is(n) => Some(Res::Device(line.to_owned())),
        ReplyLine::Ack(n) if is(n) && expect == Expect::Fin => None,
        ReplyLine::Ack(n) | ReplyLine::Fin(n) if is(n) => Some(Res::Done),
        ReplyLine::Value { name: n, value } if is(n) => {
            Some(Res::Value(parse_number(value).unwrap_or(f64::NAN)))
        }
        _ => None,
    }
}

/// Whether the device's reply `got` is the call's result `res` (in a corrupting run: of the
/// same form).
fn same(got: &Res, res: &Res, exact: bool) -> bool {
    match (got, res) {
        (Res::Done, Res::Done) => true,
        (Res::Value(a), Res::Value(b)) => !exact || a == b,
        (Res::Device(a), Res::Device(b)) => !exact || a == b,
        _ => false,
    }
}

/// Every promise the record can decide; `closed_at[i]`: when client `i` began `close()`.
pub fn check(
    calls: &[CallRec],
    pushes: &[PushRec],
    record: &SimRecording,
    sim_t0: Instant,
    sessions: &[Vec<SessionId>],
    closed_at: &[Option<Instant>],
    exact: bool,
) -> Vec<String> {
    let mut out = Vec::new();
    if record.dropped > 0 {
        out.push(format!(
            "0 (oracle): the simulator's record lost {} entries",
            record.dropped
        ));
    }
    let mut by_session: BTreeMap<SessionId, Vec<Ev>> = BTreeMap::new();
    for r in &record.records {
        let at = sim_t0 + r.at;
        let ev = match &r.event {
            SimEvent::TextRequest { line } => Ev {
                at,
                request: Some(line.as_deref().unwrap_or("")),
                reply: None,
            },
            SimEvent::TextReply { line, moving } => Ev {
                at,
                request: None,
                reply: Some((line, *moving)),
            },
            _ => continue,
        };
        by_session.entry(r.session).or_default().push(ev);
    }
    if exact {
        out.extend(one_per_name(&by_session));
    }
    // Each answered call: the requests (session, index) that could be its own, with the
    // device's reply to each.
    let mut edges: Vec<Vec<Cand>> = vec![Vec::new(); calls.len()];
    for (i, c) in calls.iter().enumerate() {
        let who = format!("client {} {}", c.client, c.line);
        let bound = c.start.checked_add(c.timeout).map(|t| t + CALL_SLACK);
        // A dropped call's end is when its caller dropped it (an AUTOSEND's, after its pushes).
        if c.res != Res::Cancelled && bound.is_some_and(|b| c.end > b) {
            out.push(format!(
                "1 (bounded): {who} with timeout {:?} took {:?}",
                c.timeout,
                c.end - c.start
            ));
        }
        match &c.res {
            Res::Value(_) | Res::Done | Res::Device(_) => {}
            Res::Closed => {
                if closed_at[c.client].is_none_or(|t| t > c.end) {
                    out.push(format!(
                        "5 (documented errors): {who} ended Closed without close()"
                    ));
                }
                continue;
            }
            Res::Malformed(e) => {
                if exact {
                    out.push(format!(
                        "2 (the device's answer to that request): {who} ended {e}, in a run where no byte was corrupted"
                    ));
                }
                continue;
            }
            Res::Other(e) => {
                out.push(format!("5 (documented errors): {who} ended {e}"));
                continue;
            }
            Res::Lost(_) | Res::Timeout | Res::Cancelled | Res::Hung => continue,
        }
        edges[i] = candidates(c, calls, &sessions[c.client], &by_session, exact);
    }
    let requests: Vec<Vec<(SessionId, usize)>> = edges
        .iter()
        .map(|e| e.iter().map(|c| c.request).collect())
        .collect();
    let owner = crate::core::matching::maximum(&requests);
    for (i, c) in calls.iter().enumerate() {
        if !matches!(c.res, Res::Value(_) | Res::Done | Res::Device(_)) {
            continue;
        }
        let who = format!("client {} {}", c.client, c.line);
        let Some(cand) = edges[i].iter().find(|e| owner.get(&e.request) == Some(&i)) else {
            let promise = match (c.name, &c.res) {
                ("STOP" | "FASTSTOP", Res::Done) => "3 (a stop's Ok is its own ACK)",
                _ => "2 (the device's answer to that request)",
            };
            let seen: Vec<&str> = edges[i].iter().map(|e| e.reply.as_str()).collect();
            let tag = if !exact && answers_a_damaged_request(c, &sessions[c.client], &by_session) {
                DAMAGED_INTO_ITS_NAME
            } else {
                ""
            };
            out.push(format!(
                "{promise}: {who} returned {:?}, which is not the device's reply to a request of that call, or that reply answered another call (the device's fitting replies during the call: {seen:?}){tag}",
                c.res
            ));
            continue;
        };
        if c.expect == Expect::Fin && c.res == Res::Done && cand.moving {
            out.push(format!(
                "4 (FIN means stopped): {who} returned Ok on {:?}, which the device sent while the fingers still moved",
                cand.reply
            ));
        }
    }
    for p in pushes {
        let sent = sessions[p.client].iter().any(|s| {
            by_session.get(s).is_some_and(|evs| {
                evs.iter().any(|e| {
                    let Some((line, _)) = e.reply else {
                        return false;
                    };
                    let Ok(ReplyLine::Push { name, value }) = parse_reply(line) else {
                        return false;
                    };
                    e.at <= p.at
                        && name.eq_ignore_ascii_case(p.name)
                        && (!exact || parse_number(value) == Some(p.value))
                })
            })
        });
        if !sent {
            out.push(format!(
                "2 (the device's answer: pushes): client {} received @{}={}, which the device did not send it",
                p.client, p.name, p.value
            ));
        }
    }
    out
}

/// A request that could be a call's own, and the device's reply to it.
#[derive(Clone)]
struct Cand {
    /// (session, index of the request in the session's lines).
    request: (SessionId, usize),
    reply: String,
    moving: bool,
}

/// The requests of a call's client that could be its own: received during the call, with its
/// very line (in a corrupting run: its name), whose reply (the first final reply of the
/// call's name after it) the device sent before the call ended and equals the call's result.
/// The tag of a call answered by the device's reply to a request damaged on the way: a flipped
/// bit that turns one command line into another name (`GRIPSTATE?` read as `GRIP\x13TATE?`,
/// answered `ERR GRIP 15` while the program's own `GRIP(…)` waited: wsg-text:0xba0682223c8b01a8).
/// GCL replies carry a command's name and nothing else; the client cannot tell that `ERR` from
/// its own command's (a residual risk of the text interface, docs/EXPLORER.md). Also tagged: a
/// call's own request damaged out of its name and the `ERR` damaged back into it
/// (wsg-text:0x8ddb4ae5bbe5540e: `RELEACE()` answered `ERR RELEACE 14`, read as
/// `ERR RELEASE 14`: the call's own answer after all, which the pairing of lines cannot see).
const DAMAGED_INTO_ITS_NAME: &str =
    " [the device's answer to a request damaged on the way into this call's name]";

/// How long before a call the damaged request may have been read (its reply then held on the
/// way until the call's own request was on the wire).
pub const DAMAGE_REACH: Duration = Duration::from_secs(5);

/// Whether call `c` (an `ERR` of its name) got a line the device sent, during the call, in answer
/// to a request line the client never wrote that way: damaged on the way, so that it holds a
/// control character (the device reads the name up to it) or names no GCL command.
fn answers_a_damaged_request(
    c: &CallRec,
    sessions: &[SessionId],
    by_session: &BTreeMap<SessionId, Vec<Ev>>,
) -> bool {
    let Res::Device(line) = &c.res else {
        return false;
    };
    sessions.iter().any(|s| {
        let evs = by_session.get(s).map_or(&[][..], Vec::as_slice);
        evs.iter().enumerate().any(|(j, e)| {
            let damaged = e.request.is_some_and(damaged_request);
            // Read by the device before the call's own request may have been written (the
            // reply then waits on the way, as it did): within a few seconds before the call.
            damaged
                && e.at + DAMAGE_REACH >= c.start
                && e.at <= c.end
                && evs[j + 1..]
                    .iter()
                    .take_while(|r| r.request.is_none())
                    .any(|r| r.reply.is_some_and(|(l, _)| same_err(l, line)))
        })
    })
}

/// Whether the device read a command line no client writes: a control character, a name that
/// is no GCL command (`RELEACE()`), or a name not followed by `(`, `?` or `=` (`GRIP[TATE?`, a
/// `GRIPSTATE?` with one flipped bit: wsg-text:0xedbbc8a35fa7b2db).
fn damaged_request(line: &str) -> bool {
    let name = request_name(line);
    line.chars().any(|ch| ch.is_control())
        || !super::liveness::NAMES
            .iter()
            .any(|n| n.eq_ignore_ascii_case(&name))
        || !matches!(line[name.len()..].chars().next(), Some('(' | '?' | '='))
}

/// Parse errors a device sent on one connection, each with when it sent it.
pub type ParseErrors = Vec<(Instant, String)>;

/// The device's parse errors (`ERR <name> 14|15`) that answered a request damaged on the way
/// (a control character, or a name that is no GCL command), per client and connection (as
/// `sessions`), each with when the device sent it. Liveness rule 7 does not take such a line
/// for a call's reply: the gripper answers the damaged line under whatever name the damage
/// left (`GRIPSTATE?` read as `GRIP\x13TATE?`, answered `ERR GRIP 15`, while GRIP's own
/// `ERR GRIP 4` was still on the way: wsg-text:0xe8d183fd8b4c4f31).
pub fn damaged_parse_errors(
    record: &SimRecording,
    sim_t0: Instant,
    sessions: &[Vec<SessionId>],
) -> Vec<Vec<ParseErrors>> {
    let mut by_session: BTreeMap<SessionId, Vec<(Instant, String)>> = BTreeMap::new();
    let mut damaged = BTreeMap::new();
    for r in &record.records {
        match &r.event {
            SimEvent::TextRequest { line } => {
                damaged.insert(r.session, damaged_request(line.as_deref().unwrap_or("")));
            }
            SimEvent::TextReply { line, .. }
                if damaged.get(&r.session) == Some(&true) && super::liveness::parse_error(line) =>
            {
                by_session
                    .entry(r.session)
                    .or_default()
                    .push((sim_t0 + r.at, line.clone()));
            }
            _ => {}
        }
    }
    sessions
        .iter()
        .map(|conns| {
            conns
                .iter()
                .map(|s| by_session.remove(s).unwrap_or_default())
                .collect()
        })
        .collect()
}

/// The same `ERR` line, or one whose name a single damaged byte changed on its way back
/// (`ERR RELEACE 14` read as `ERR RELEASE 14`, wsg-text:0x8ddb4ae5bbe5540e): same code, names
/// of one length differing in one byte.
pub fn same_err(a: &str, b: &str) -> bool {
    fn parts(l: &str) -> Option<(Option<&str>, Option<&str>)> {
        let mut w = l.split(' ');
        (w.next() == Some("ERR")).then(|| (w.next(), w.next()))
    }
    let near = |x: &str, y: &str| {
        x.len() == y.len() && x.bytes().zip(y.bytes()).filter(|(p, q)| p != q).count() <= 1
    };
    match (parts(a), parts(b)) {
        _ if a == b => true,
        (Some((Some(na), ca)), Some((Some(nb), cb))) => ca.is_some() && ca == cb && near(na, nb),
        _ => false,
    }
}

fn candidates(
    c: &CallRec,
    calls: &[CallRec],
    sessions: &[SessionId],
    by_session: &BTreeMap<SessionId, Vec<Ev>>,
    exact: bool,
) -> Vec<Cand> {
    let mut out = Vec::new();
    for &s in sessions {
        let evs = by_session.get(&s).map_or(&[][..], Vec::as_slice);
        for (j, e) in evs.iter().enumerate() {
            let Some(line) = e.request else { continue };
            let mine = line == c.line || !exact && request_name(line) == c.name;
            // One byte from another call's line of its client in flight then too (`POS?` and
            // `PWT?` are two apart): whose it was cannot be told, and it is no candidate.
            let another = || {
                calls.iter().any(|o| {
                    o.client == c.client
                        && o.line != c.line
                        && o.start <= e.at
                        && e.at <= o.end
                        && damaged_copy(line, &o.line)
                })
            };
            if !mine && !exact && damaged_copy(line, &c.line) && !another() {
                out.extend(damaged_copy_answer(c, (s, j), evs));
                continue;
            }
            if !mine || e.at < c.start || e.at > c.end {
                continue;
            }
            // Not a parse error (`ERR <name> 14|15`, sent at once) that answered a later
            // request: the device answers a line damaged on the way under whatever name the
            // damage left, and no accepted motion ends with one (`GRIPSTATE?` read as
            // `GRIP\x13TATE?` while the call's GRIP ran: wsg-text:0x8c62f95219960af6, whose
            // own `FIN GRIP` came later; the client counts such a line as damaged).
            let mut answering = j;
            let reply = evs.iter().enumerate().skip(j + 1).find_map(|(k, r)| {
                if r.request.is_some() {
                    answering = k;
                }
                let (l, moving) = r.reply?;
                if answering != j && super::liveness::parse_error(l) {
                    return None;
                }
                final_of(l, c.name, c.expect).map(|got| (r.at, l, moving, got))
            });
            if let Some((at, l, moving, got)) = reply {
                if at <= c.end && same(&got, &c.res, exact) {
                    out.push(Cand {
                        request: (s, j),
                        reply: l.to_owned(),
                        moving,
                    });
                }
            }
        }
    }
    out
}

/// Whether the device read `request` as the call's own `line` with one byte changed on the way
/// (`RELEASE()` read as `BELEASE()`, wsg-text:0xcdaeb186861eeadc): the call's request, answered
/// under the name the damage left. Never another command's line: a `GRIPSTATE?` damaged into
/// `GRIP\x13TATE?` and answered `ERR GRIP 15` is no `GRIP(…)`'s (wsg-text:0xba0682223c8b01a8).
fn damaged_copy(request: &str, line: &str) -> bool {
    request.len() == line.len()
        && request
            .bytes()
            .zip(line.bytes())
            .filter(|(a, b)| a != b)
            .count()
            == 1
}

/// The call's own request read damaged (`evs[j]`, [`damaged_copy`]) as a candidate, when the
/// device's answer to it (at once, before it read another line) is the call's `ERR`, or that
/// line with a damaged name byte ([`same_err`]: `ERR BELEASE 14` read as `ERR RELEASE 14`).
fn damaged_copy_answer(c: &CallRec, (s, j): (SessionId, usize), evs: &[Ev]) -> Option<Cand> {
    let Res::Device(got) = &c.res else {
        return None;
    };
    if evs[j].at < c.start || evs[j].at > c.end {
        return None;
    }
    evs[j + 1..]
        .iter()
        .take_while(|r| r.request.is_none())
        .find_map(|r| {
            let (l, moving) = r.reply?;
            (r.at <= c.end && same_err(l, got)).then(|| Cand {
                request: (s, j),
                reply: l.to_owned(),
                moving,
            })
        })
}

/// On each session, the requests and final replies of one name alternate: the client never
/// has two commands of a name on the wire (a reply names only its command, so two could not be
/// told apart), and the device answers each (no line is lost without corruption).
fn one_per_name(by_session: &BTreeMap<SessionId, Vec<Ev>>) -> Vec<String> {
    let mut out = Vec::new();
    for (s, evs) in by_session {
        let mut open: BTreeMap<String, &str> = BTreeMap::new();
        for e in evs {
            if let Some(line) = e.request {
                let name = request_name(line);
                if let Some(first) = open.insert(name, line) {
                    out.push(format!(
                        "2 (one command per name on the wire): session {s}: {line} was sent while {first} was not answered yet"
                    ));
                }
            } else if let Some((line, _)) = e.reply {
                let name = match parse_reply(line) {
                    Ok(ReplyLine::Fin(n) | ReplyLine::Value { name: n, .. }) => n,
                    Ok(ReplyLine::Err { name: Some(n), .. }) => n,
                    Ok(ReplyLine::Ack(n)) if !matches!(n, "HOME" | "MOVE" | "GRIP" | "RELEASE") => {
                        n
                    }
                    _ => continue,
                };
                open.remove(&name.to_ascii_uppercase());
            }
        }
    }
    out
}
