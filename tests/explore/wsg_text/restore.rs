//! What a reconnect restores (`text::ClientConfig::reconnect`, the client docs): on a new
//! connection the client sends again the last `VERBOSE=…`, `PWT=…` and `CLT=…` the gripper
//! accepted and each `AUTOSEND(…)` still on (per connection on the gripper, manual chapter 2:
//! a new connection starts without them), before any call is served on it.
//!
//! After recovery each reconnecting client's connection is cut on purpose (on the client's
//! side, [`super::tap::Cut`]; the faults are off): the client must report the loss, reconnect
//! and restore within [`RESTORED_WITHIN`] (promise 5), and on the new connection it must have
//! written each setting the workload's calls left it remembering; an `AUTOSEND` switched off
//! (its stop accepted) must not come back. In a run without corruption the part width
//! tolerance and clamping travel read back from the gripper are the values it reported when
//! they were set. A setting the log cannot decide (a caller dropped an `AUTOSEND` after it may
//! have been acknowledged; two accepted at one instant) is not judged.

use std::collections::BTreeMap;
use std::sync::atomic::Ordering;
use std::time::Duration;

use futures_util::StreamExt;
use gripper::reconnect::ConnectionEvent;
use tokio::time::Instant;

use super::workload::{classify, CallRec, Expect, Log, Res};
use super::Ctx;
use crate::core::{note, SharedTrace};

/// How long after the cut the session must be restored: the policy's first delay (50 ms) and a
/// few exchanges on a quiet link, with a wide margin.
const RESTORED_WITHIN: Duration = Duration::from_secs(10);

/// Timeout of the read-back queries.
const QUERY: Duration = Duration::from_secs(2);

/// What the client should remember for one setting.
#[derive(Clone, Debug, PartialEq)]
enum Want {
    /// This line, which the gripper answered with this value (a setter's; `None`: an `ACK`).
    Line(String, Option<f64>),
    /// An `AUTOSEND` switched off: not restored.
    Off,
    /// The log cannot tell.
    Unknown,
}

/// What a call sets, if it is a setting a reconnect restores: its key (`PWT`, `AUTOSEND POS`)
/// and, for an `AUTOSEND`, whether it switches the pushes on.
pub fn setting_of(line: &str, name: &str) -> Option<(String, bool)> {
    match name {
        "VERBOSE" | "PWT" | "CLT" if line.contains('=') => Some((name.to_owned(), true)),
        "AUTOSEND" => {
            // `AUTOSEND("POS",50)`, `AUTOSEND("POS",50,true)`, `AUTOSEND("POS",0)` (off).
            let (quantity, rest) = line.strip_prefix("AUTOSEND(\"")?.split_once("\",")?;
            let interval = rest.trim_end_matches(')').split(',').next()?;
            Some((format!("AUTOSEND {quantity}"), interval != "0"))
        }
        _ => None,
    }
}

/// What client `index` should remember, by key, after `calls` (in the order they ended: the
/// client remembers a setting when its call returns Ok, and forgets an `AUTOSEND` when its
/// stop returns Ok; a failed call changes nothing).
fn remembered(index: usize, calls: &[CallRec]) -> BTreeMap<String, Want> {
    let mut mine: Vec<&CallRec> = calls.iter().filter(|c| c.client == index).collect();
    mine.sort_by_key(|c| c.end);
    let mut want: BTreeMap<String, (Want, Instant)> = BTreeMap::new();
    for c in mine {
        let Some((key, on)) = setting_of(&c.line, c.name) else {
            continue;
        };
        let new = match (&c.res, on) {
            (Res::Value(v), true) if c.expect == Expect::Value => {
                Want::Line(c.line.clone(), Some(*v))
            }
            (Res::Done, true) => Want::Line(c.line.clone(), None),
            (Res::Done, false) => Want::Off,
            // The workload's `AUTOSEND` call goes on reading pushes after its `ACK`: dropped
            // (by the workload, or by rule 8's guard when it has no timeout and no push comes:
            // wsg-text:0xf3a9834df9c7ac21), it may have been remembered.
            (Res::Cancelled | Res::Hung, true) if c.name == "AUTOSEND" => Want::Unknown,
            _ => continue,
        };
        let new = match want.get(&key) {
            // Two ended at one instant: either may have been remembered last.
            Some((old, at)) if *at == c.end && *old != new => Want::Unknown,
            _ => new,
        };
        want.insert(key, (new, c.end));
    }
    want.into_iter().map(|(k, (w, _))| (k, w)).collect()
}

/// The check above for one client (only a reconnecting one, not closing).
pub async fn check(ctx: &Ctx, log: &Log, trace: &SharedTrace) -> Vec<String> {
    if !ctx.reconnect || ctx.closing.load(Ordering::SeqCst) || ctx.client.is_closed() {
        return Vec::new();
    }
    let want = remembered(ctx.index, &log.calls.lock().unwrap());
    let mut events = ctx.client.connection_events();
    let Some(cut) = ctx.conns.lock().unwrap().last().map(|c| c.cut.clone()) else {
        return Vec::new();
    };
    note(
        trace,
        format!(
            "restore client {}: the connection is cut; remembered {want:?}",
            ctx.index
        ),
    );
    cut.cut();
    let cut_at = Instant::now();
    let restored = tokio::time::timeout(RESTORED_WITHIN, async {
        while let Some(ev) = events.next().await {
            if matches!(ev, ConnectionEvent::Restored { .. }) {
                return true;
            }
        }
        false
    })
    .await;
    let who = format!("client {} (reconnect true)", ctx.index);
    if restored != Ok(true) {
        return vec![format!(
            "5 (recovery): {who}: its connection, cut on purpose after recovery, was not restored within {RESTORED_WITHIN:?} (events ended: {})",
            restored.is_ok()
        )];
    }
    let (conn, tap) = {
        let conns = ctx.conns.lock().unwrap();
        (conns.len() - 1, conns[conns.len() - 1].tap.clone())
    };
    let written: Vec<String> = tap
        .lock()
        .unwrap()
        .written
        .lines
        .iter()
        .map(|l| l.text.clone())
        .collect();
    note(
        trace,
        format!(
            "restore client {}: restored on connection {conn} after {:?}, wrote {written:?}",
            ctx.index,
            cut_at.elapsed()
        ),
    );
    let mut v = Vec::new();
    for (key, w) in &want {
        match w {
            Want::Line(line, _) if !written.contains(line) => v.push(format!(
                "5 (a reconnect restores what the program set up): {who}: {line}, the last {key} the gripper accepted, was not sent again on the new connection (the client wrote {written:?})"
            )),
            Want::Off => {
                let back = written
                    .iter()
                    .find(|l| setting_of(l, "AUTOSEND").is_some_and(|(k, on)| &k == key && on));
                if let Some(l) = back {
                    v.push(format!(
                        "5 (a reconnect restores what the program set up): {who}: {l} came back on the new connection, though its pushes were switched off (AUTOSEND(…,0) accepted)"
                    ));
                }
            }
            _ => {}
        }
    }
    // A flipped bit may have changed the value the gripper reported when it was set.
    if !ctx.corrupting {
        let c = ctx.client.with_timeout(QUERY);
        for (key, line) in [("PWT", "PWT?"), ("CLT", "CLT?")] {
            let Some(Want::Line(set, Some(value))) = want.get(key) else {
                continue;
            };
            let start = Instant::now();
            let r = if key == "PWT" {
                c.part_width_tolerance_mm().await
            } else {
                c.clamping_travel_mm().await
            };
            note(trace, format!("restore client {}: {line} {r:?}", ctx.index));
            if r.as_ref().ok() != Some(value) {
                v.push(format!(
                    "5 (a reconnect restores what the program set up): {who}: after the reconnect {line} ended {r:?}, not {value} ({set} was the last the gripper accepted)"
                ));
            }
            log.calls.lock().unwrap().push(CallRec {
                client: ctx.index,
                conn,
                line: line.into(),
                name: key,
                expect: Expect::Value,
                start,
                end: Instant::now(),
                timeout: QUERY,
                res: r.as_ref().map_or_else(classify, |x| Res::Value(*x)),
            });
        }
    }
    v
}
