//! GRIPLINK's oracle: the promises of docs/EXPLORER.md, each violation named by its number.
//!
//! 1. *bounded*: every call ends within its timeout + [`CALL_SLACK`].
//! 2. *the controller's answer*: every answer (a value read as the call's method reads it, or a
//!    device status) is one reply the controller sent to that client, during the call, to that
//!    very command line; one reply answers one call (a maximum matching).
//! 5. *documented errors*: `Closed` only after `close()`.
//! 6. *a connection is lost only for cause*: a reported loss for an overdue reply needs the
//!    controller silent (no reply line reaching the client) for at least `give_up_after` while
//!    a request waited (the documented give-up time counts from when a request waits at the
//!    front, so the silence before the loss is at least that long); a loss for a reply that did
//!    not answer its command needs a reason for one (a reply the controller dropped, a reply
//!    longer than `max_line_len`).
//! 7. *a Timeout only when its reply did not arrive in time*: a call that timed out must not
//!    have had its reply delivered intact to the client before its deadline.
//! 8. *a call without timeout ends*: a `Duration::MAX` call ends (the caller's guard,
//!    `mod.rs`), and not later than its reply's delivery.
//! 10. *the quiet phase serves every kind of call*: see `mod.rs` (checked there).
//!
//! Rule 9 (a stop is sent at once) has nothing to judge: GRIPLINK has no stop command (manual
//! chapter 3; a motion ends, or `DISABLE` takes the device out of operation, a command like any
//! other).

use std::collections::BTreeSet;
use std::time::Duration;

use gripper::griplink::command::GripConfig;
use gripper::griplink::command::GripConfigF;
use gripper::griplink::reply::interpret;
use gripper::griplink::sim::SimExchange;
use gripper::griplink::{Answer, DeviceState, Error};
use tokio::time::Instant;

use super::workload::{CallRec, Op, Render};
use crate::core::matching;
use crate::core::servers::{self, session_at, silence_before, SessionRec};

/// How late a call may end after its timeout (the task's own bookkeeping; simulated time).
pub const CALL_SLACK: Duration = Duration::from_millis(10);

/// How much earlier than a call's deadline its reply must have reached the client for a
/// `Timeout` to be wrong (the reply and the deadline at one instant may go either way).
const DELIVERY_MARGIN: Duration = Duration::from_millis(1);

/// What the oracle knows of one client.
pub struct ClientView {
    pub sessions: Vec<SessionRec>,
    /// Whether `close()` was called on it.
    pub closing: bool,
    /// Each loss it reported: when, and why.
    pub losses: Vec<(Instant, String)>,
    pub give_up_after: Duration,
    pub max_line_len: usize,
}

/// A reply the controller sent: where, what, and when it reached the client intact.
type Sent<'a> = servers::Sent<'a, SimExchange>;

/// Every reply sent on one of `view`'s sessions, in order, with when it was delivered.
fn sent_on<'a>(view: &ClientView, records: &'a [Vec<SimExchange>]) -> Vec<Sent<'a>> {
    servers::sent_on(
        &view.sessions,
        records,
        |e| e.session,
        |e| e.reply.len() as u64 + 1,
    )
}

/// The oracle over every client's calls and every controller's record. `dropped`: the
/// controller dropped replies in this run.
pub fn judge(
    views: &[ClientView],
    calls: &[CallRec],
    records: &[Vec<SimExchange>],
    dropped: bool,
) -> Vec<String> {
    let mut out = Vec::new();
    let sent: Vec<Vec<Sent>> = views.iter().map(|v| sent_on(v, records)).collect();
    bounded_and_documented(views, calls, &mut out);
    answers(calls, &sent, dropped, &mut out);
    for (i, v) in views.iter().enumerate() {
        losses(i, v, calls, &sent[i], dropped, &mut out);
    }
    timeouts(views, calls, &sent, dropped, &mut out);
    fault_waits(calls, &sent, &mut out);
    helpers(calls, &sent, &mut out);
    out
}

/// Rule 2 for the helpers: each reading a watch yielded is a reply to its query (`DEVSTATE` or
/// `VALUEF` of its port) sent to that client during the watch, and a wait's outcome is a state
/// the device reported (`DEVSTATE` or `WSTR` of its port) during the wait.
fn helpers(calls: &[CallRec], sent: &[Vec<Sent>], out: &mut Vec<String>) {
    for c in calls {
        let Some(Ok(shown)) = &c.result else { continue };
        let during = |line: &str| -> Vec<&str> {
            sent[c.client]
                .iter()
                .filter(|s| s.exchange.request == line)
                .filter(|s| s.exchange.sent_at >= c.start && s.exchange.sent_at <= c.end)
                .map(|s| s.exchange.reply.as_str())
                .collect()
        };
        match &c.op {
            Op::Watch { port, value, .. } => {
                let (line, as_read) = if *value {
                    (format!("VALUEF[{port}][0]?"), Render::Float)
                } else {
                    (format!("DEVSTATE[{port}]?"), Render::State)
                };
                let expect = Op::Typed(
                    if *value {
                        gripper::griplink::command::Command::ValueF {
                            port: *port,
                            index: 0,
                        }
                    } else {
                        gripper::griplink::command::Command::DevState(*port)
                    },
                    as_read,
                )
                .expect();
                let readings: BTreeSet<String> = during(&line)
                    .into_iter()
                    .filter_map(|r| interpret(&line, expect, r).ok())
                    .filter_map(|a| render(as_read, &a))
                    .map(|v| format!("Ok({v})"))
                    .collect();
                for item in shown.split(", ").filter(|i| i.starts_with("Ok(")) {
                    if !readings.contains(item) {
                        out.push(format!(
                            "2 (the controller's answer): client {} {} yielded {item}, which the controller did not send to {line} during the watch",
                            c.client,
                            c.op.kind()
                        ));
                    }
                }
            }
            Op::Wait { port, kind, .. } => {
                let code = match (kind.is_grip(), shown.as_str()) {
                    (true, "Holding") => 5,
                    (true, "NoPart") => 4,
                    (false, "Released") => 3,
                    (_, "Fault") => 7,
                    _ => continue,
                };
                let states = [format!("DEVSTATE[{port}]="), format!("WSTR[{port}]=")];
                let reported = [format!("DEVSTATE[{port}]?"), format!("WSTR[{port}]?")]
                    .iter()
                    .flat_map(|l| during(l))
                    .any(|r| {
                        states
                            .iter()
                            .any(|k| r.strip_prefix(k.as_str()) == Some(&code.to_string()))
                    });
                if !reported {
                    out.push(format!(
                        "2 (the controller's answer): client {} {} ended {shown}, a state the device did not report during the wait",
                        c.client,
                        c.op.kind()
                    ));
                }
            }
            _ => {}
        }
    }
}

/// Rule 7 for the grip helpers started in `DS_FAULT` (client docs, "Waiting for a motion":
/// from `DS_FAULT`, a state other than `DS_FAULT` read after the command shows the re-enable,
/// and then any outcome state read later, `DS_FAULT` included, ends the wait): a helper that
/// timed out although those two readings reached the client in time. Judged only where no
/// other call of the client may have read that port's state meanwhile (the readings are then
/// the helper's own).
fn fault_waits(calls: &[CallRec], sent: &[Vec<Sent>], out: &mut Vec<String>) {
    for c in calls {
        let Op::Wait { port, kind, .. } = &c.op else {
            continue;
        };
        if !kind.is_grip() || !matches!(c.result, Some(Err(Error::Timeout { .. }))) {
            continue;
        }
        let state_of = |line: &str| -> Option<i64> {
            let key = [format!("DEVSTATE[{port}]="), format!("WSTR[{port}]=")];
            let v = key.iter().find_map(|k| line.strip_prefix(k.as_str()))?;
            v.parse().ok()
        };
        let others = calls.iter().any(|o| {
            !std::ptr::eq(o, c)
                && o.client == c.client
                && o.start <= c.end
                && o.end >= c.start
                && (o.op.may_send(&format!("DEVSTATE[{port}]?"))
                    || o.op.line().is_some_and(|l| {
                        l == format!("DEVSTATE[{port}]?") || l == format!("WSTR[{port}]?")
                    }))
        });
        if others {
            continue;
        }
        let deadline = c.start.checked_add(c.timeout);
        let mine: Vec<&Sent> = sent[c.client]
            .iter()
            .filter(|s| s.exchange.sent_at >= c.start && s.exchange.sent_at <= c.end)
            .collect();
        let Some(ack) = mine.iter().position(|s| {
            s.exchange.reply == "ACK"
                && (s.exchange.request.starts_with("GRIP(")
                    || s.exchange.request.starts_with("FLEXGRIP"))
        }) else {
            continue;
        };
        let started_in_fault = mine[..ack]
            .iter()
            .rev()
            .find_map(|s| state_of(&s.exchange.reply))
            == Some(7);
        if !started_in_fault {
            continue;
        }
        let states: Vec<(i64, Instant)> = mine[ack + 1..]
            .iter()
            .filter_map(|s| Some((state_of(&s.exchange.reply)?, s.delivered?)))
            .collect();
        let Some(left) = states.iter().position(|&(v, _)| v != 7) else {
            continue;
        };
        let ended = states[left + 1..].iter().find(|&&(v, d)| {
            matches!(v, 4 | 5 | 7) && deadline.is_none_or(|dl| d + DELIVERY_MARGIN < dl)
        });
        if let Some((v, d)) = ended {
            out.push(format!(
                "7 (a Timeout only when its reply did not arrive in time): client {} {} started in DS_FAULT; after the command the device read state {} (re-enabled), then state {v}, which reached the client {:?} after the call began, within its timeout {:?}; the wait ended {:?}",
                c.client,
                c.op.kind(),
                states[left].0,
                *d - c.start,
                c.timeout,
                c.result
            ));
        }
    }
}

/// Rules 1 and 5.
fn bounded_and_documented(views: &[ClientView], calls: &[CallRec], out: &mut Vec<String>) {
    for c in calls {
        let bound = c.start.checked_add(c.timeout).map(|t| t + CALL_SLACK);
        if c.result.is_some() && bound.is_some_and(|b| c.end > b) {
            out.push(format!(
                "1 (bounded): client {} {} with timeout {:?} took {:?}",
                c.client,
                c.op.kind(),
                c.timeout,
                c.end - c.start
            ));
        }
        // A wait helper without timeout has no documented bound but the device's evidence: a
        // device that acknowledged the motion and then never moves nor changes state keeps it
        // waiting (griplink-tcp:0xb2ea0527eb970982: GRIP after DISABLE, ACK, the fingers never
        // moved). Its guard only notes it.
        let helper = matches!(c.op, Op::Wait { .. });
        if c.timeout == Duration::MAX && c.result.is_none() && !helper {
            out.push(format!(
                "8 (a call without timeout ends): client {} {} ({}) did not end within {:?}",
                c.client,
                c.op.kind(),
                c.op.line().unwrap_or_default(),
                c.end - c.start
            ));
        }
        if matches!(c.result, Some(Err(Error::Closed))) && !views[c.client].closing {
            out.push(format!(
                "5 (documented errors): client {} {} ended Closed without close()",
                c.client,
                c.op.kind()
            ));
        }
    }
}

/// Rule 2: a maximum matching of the answered single-line calls to the replies that fit them.
fn answers(calls: &[CallRec], sent: &[Vec<Sent>], dropped: bool, out: &mut Vec<String>) {
    let answered: Vec<&CallRec> = calls
        .iter()
        .filter(|c| c.op.line().is_some())
        .filter(|c| matches!(c.result, Some(Ok(_) | Err(Error::Device { .. }))))
        .collect();
    let edges: Vec<Vec<(u64, usize)>> = answered
        .iter()
        .map(|c| {
            let line = c.op.line().unwrap_or_default();
            let result = c.result.as_ref().expect("answered");
            sent[c.client]
                .iter()
                .filter(|s| {
                    let e = s.exchange;
                    (e.request == line || dropped)
                        && e.sent_at >= c.start
                        && e.sent_at <= c.end
                        && same(&c.op, &line, &e.reply, result)
                })
                .map(|s| s.key)
                .collect()
        })
        .collect();
    let owner = matching::maximum(&edges);
    let matched: BTreeSet<usize> = owner.values().copied().collect();
    for (i, c) in answered.iter().enumerate() {
        if !matched.contains(&i) {
            out.push(format!(
                "2 (the controller's answer): client {} {} ({}) returned {:?}, which the controller did not send to that command during the call",
                c.client,
                c.op.kind(),
                c.op.line().unwrap_or_default(),
                c.result
            ));
        }
    }
}

/// Whether `reply` to `line`, read as the call's method reads it, is the call's `result`.
fn same(op: &Op, line: &str, reply: &str, result: &Result<String, Error>) -> bool {
    let read = interpret(line, op.expect(), reply);
    match (read, result) {
        (Err(x), Err(y)) => x.status().is_some() && x.status() == y.status(),
        (Ok(a), Ok(shown)) => render(op.render(), &a).as_deref() == Some(shown.as_str()),
        _ => false,
    }
}

/// An answer as the method of `render` returns it (`Debug`), `None` if it would fail.
fn render(render: Render, a: &Answer) -> Option<String> {
    let value = match a {
        Answer::Ack => None,
        Answer::Data(d) => Some(&d.value),
    };
    let int = || value.and_then(|v| v.as_int());
    let recipe = || match value? {
        gripper::griplink::value::Value::List(items) if items.len() == 9 => {
            let tag = items[0].as_str()?.to_owned();
            Some((tag, items[1..].to_vec()))
        }
        _ => None,
    };
    Some(match render {
        Render::Answer => format!("{a:?}"),
        Render::Unit => {
            value.is_none().then_some(())?;
            "()".into()
        }
        Render::Str => format!("{:?}", value?.as_str()?),
        Render::Int => format!("{}", int()?),
        Render::VendorId => match int()? {
            -1 => "None".into(),
            v => format!("{:?}", Some(u32::try_from(v).ok()?)),
        },
        Render::Float => format!("{:?}", value?.as_f64()?),
        Render::State => format!("{:?}", DeviceState::from_code(int()?)),
        Render::Bool => format!("{:?}", int()? != 0),
        Render::Recipe => {
            let (tag, values) = recipe()?;
            let mut params = [0i32; 8];
            for (p, v) in params.iter_mut().zip(&values) {
                *p = i32::try_from(v.as_int()?).ok()?;
            }
            format!("{:?}", GripConfig { tag, params })
        }
        Render::RecipeF => {
            let (tag, values) = recipe()?;
            let mut params = [0f64; 8];
            for (p, v) in params.iter_mut().zip(&values) {
                *p = v.as_f64()?;
            }
            format!("{:?}", GripConfigF { tag, params })
        }
    })
}

/// Whether a reply on the session was too long for the client's line limit (the client
/// discards it, documented: `ClientConfig::max_line_len`).
fn too_long(view: &ClientView, sent: &[Sent], gen: u64, session: u64) -> bool {
    sent.iter()
        .any(|s| s.gen == gen && s.session == session && s.exchange.reply.len() > view.max_line_len)
}

/// Issue 29 F: whether the loss at `t` of client `i` is the client's documented give-up of a
/// request that had waited behind another's reply (which reached the client at `last`, after
/// the request was sent): the give-up time counted from the send (`deadline + give_up_after`
/// of the call that sent the named line), not from when the request reached the front. A
/// helper's own commands (waits, watches) are not logged one by one: a helper running then
/// counts too.
fn behind(
    i: usize,
    view: &ClientView,
    calls: &[CallRec],
    (opened, t, last): (Instant, Instant, Instant),
    reason: &str,
) -> bool {
    let line = reason
        .split("no reply to ")
        .nth(1)
        .and_then(|r| r.split(" long after").next())
        .unwrap_or("");
    // The call that sent it: sent before the last reply came, and due (by the client's rule,
    // from its send) by the time of the loss.
    // (Its caller may have timed out long before: the slot stays, abandoned. It was not
    // answered, and it was sent on the session that was lost.)
    let by_call = calls.iter().any(|c| {
        c.client == i
            && c.start < last
            && c.end >= opened
            && !matches!(c.result, Some(Ok(_) | Err(Error::Device { .. })))
            && c.op.line().as_deref() == Some(line)
            && c.start
                .checked_add(c.timeout)
                .and_then(|d| d.checked_add(view.give_up_after))
                .is_some_and(|g| g <= t + DELIVERY_MARGIN)
    });
    let by_helper = calls
        .iter()
        .filter(|c| c.client == i && c.start < last && c.end >= opened)
        .any(|c| c.op.may_send(line));
    by_call || by_helper
}

/// Rule 6: each loss client `i` reported.
fn losses(
    i: usize,
    view: &ClientView,
    calls: &[CallRec],
    sent: &[Sent],
    dropped: bool,
    out: &mut Vec<String>,
) {
    for (t, reason) in &view.losses {
        let Some(s) = session_at(&view.sessions, *t) else {
            continue;
        };
        // After a dropped reply the pairing is shifted by one (a later reply taken for the
        // front's, which stays away): a reply reaching the client is no sign that the front
        // request was answered, so the silence cannot be measured.
        if reason.contains("long after its timeout") && !dropped {
            // Since the last reply line that reached the client on that session.
            let (silence, last) = silence_before(s, sent, *t);
            if silence < view.give_up_after {
                let tag = if behind(i, view, calls, (s.opened, *t, last), reason) {
                    " [the request waited behind another's reply; its give-up time counted from when it was sent]"
                } else {
                    ""
                };
                out.push(format!(
                    "6 (a connection is lost only for cause): client {i} declared its connection lost ({reason}) {silence:?} after the controller's last reply reached it, less than give_up_after {:?}: the controller was answering in order{tag}",
                    view.give_up_after
                ));
            }
        } else if reason.contains("did not answer its command")
            && !dropped
            && !too_long(view, sent, s.gen, s.session)
        {
            out.push(format!(
                "6 (a connection is lost only for cause): client {i} declared its connection lost ({reason}), but the controller dropped no reply and sent none too long: every reply answered its command in order"
            ));
        }
    }
}

/// Rules 7 and 8: a call that timed out (or, without a timeout, ended late) while its reply
/// had reached the client intact in time. The reply is one to the call's own line, sent and
/// delivered during the call, on a session where the pairing cannot have gone out of step (no
/// dropped reply in the run, no reply too long), and no other call that may have sent the same
/// line (or a helper's several lines, or a caller that gave up) overlapped it.
fn timeouts(
    views: &[ClientView],
    calls: &[CallRec],
    sent: &[Vec<Sent>],
    dropped: bool,
    out: &mut Vec<String>,
) {
    if dropped {
        return;
    }
    for c in calls {
        let Some(line) = c.op.line() else { continue };
        // A reconnect restores VERBOSE on its own (client docs): its reply is no caller's.
        if line.starts_with("VERBOSE") {
            continue;
        }
        let forever = c.timeout == Duration::MAX;
        let timed_out = matches!(c.result, Some(Err(Error::Timeout { .. })));
        if !timed_out && !forever {
            continue;
        }
        let deadline = c.start.checked_add(c.timeout);
        let view = &views[c.client];
        let found = sent[c.client].iter().find(|s| {
            let Some(d) = s.delivered else { return false };
            // Another call that may have sent that line: one overlapping, an earlier one
            // that got no answer (its reply may still have been on its way), or an earlier
            // helper of several lines (a watch or a wait), which may end with its answer while
            // a poll of its own is still on the wire: that poll's reply, identical to the
            // call's, comes later (griplink-tcp:0x06d10a7303e68adc: a watch's DEVSTATE[0]?,
            // abandoned at 64 ms, answered at the instant the call began, 318 ms).
            let others = calls.iter().any(|o| {
                let helper = o.op.line().is_none();
                !std::ptr::eq(o, c)
                    && o.client == c.client
                    && o.start <= d
                    && (o.end >= c.start
                        || helper
                        || !matches!(o.result, Some(Ok(_) | Err(Error::Device { .. }))))
                    && o.op.line().is_none_or(|l| l == line)
            });
            s.exchange.request == line
                && s.exchange.sent_at >= c.start
                && deadline.is_none_or(|dl| d + DELIVERY_MARGIN < dl)
                && !too_long(view, &sent[c.client], s.gen, s.session)
                && !others
        });
        let Some(s) = found else { continue };
        let d = s.delivered.expect("found");
        if timed_out {
            out.push(format!(
                "7 (a Timeout only when its reply did not arrive in time): client {} {} ({line}) with timeout {:?} ended {:?}, but its reply {:?} reached the client intact {:?} after the call began",
                c.client,
                c.op.kind(),
                c.timeout,
                c.result,
                s.exchange.reply,
                d - c.start
            ));
        } else if c.end > d + CALL_SLACK && c.result.is_some() {
            out.push(format!(
                "8 (a call without timeout ends): client {} {} ({line}) without timeout ended {:?} after its reply {:?} reached the client",
                c.client,
                c.op.kind(),
                c.end - d,
                s.exchange.reply
            ));
        }
    }
}
