//! Sessions (the connections to the device) and their auto-update streams (manual 3.4).
//!
//! A session is what the device tells its clients apart by: a TCP connection, a UDP peer, a
//! serial line. Its auto-updates are its own and end with it; the move it started answers it.
//!
//! [`Sessions`] is the device's book of them, a part the [`Device`](super::Device) holds: which
//! sessions are connected and how, which announced their disconnect, and each stream's mode and
//! schedule. It knows nothing of the fingers: the device passes in the value a stream sends.

use std::collections::{BTreeMap, HashSet};

use bytes::Bytes;

use crate::wsg::command::{id, UpdateMode};

/// The shortest auto-update period, ms: "Der minimale zulässige Wert beträgt 10 ms" (3.4.1,
/// 3.4.2, 3.4.4–3.4.6).
pub const MIN_UPDATE_PERIOD_MS: u16 = 10;

/// Identifies one connection (TCP connection, UDP peer, serial port) to the device.
pub type SessionId = u64;

/// The kind of a session's transport (the disconnect announcement is TCP-only, manual 3.1.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SessionKind {
    /// A TCP connection: an unannounced close triggers FAST STOP (manual 1.4.2).
    Tcp,
    /// A UDP peer.
    Udp,
    /// A serial line (or any other byte stream).
    Serial,
}

/// The sessions connected to the device and their auto-update streams.
#[derive(Debug, Default)]
pub(super) struct Sessions {
    kinds: BTreeMap<SessionId, SessionKind>,
    announced: HashSet<SessionId>,
    streams: BTreeMap<(SessionId, u8), Stream>,
}

/// One auto-update stream of one session.
#[derive(Clone, Debug)]
struct Stream {
    mode: UpdateMode,
    /// Wall seconds.
    next_due: f64,
    last: Option<Bytes>,
}

impl Stream {
    fn period_s(&self) -> f64 {
        f64::from(self.mode.period_ms.max(MIN_UPDATE_PERIOD_MS)) / 1000.0
    }
}

impl Sessions {
    /// A session opened.
    pub(super) fn connect(&mut self, session: SessionId, kind: SessionKind) {
        self.kinds.insert(session, kind);
    }

    /// Forgets a session that closed, and its streams: its transport (if it was connected) and
    /// whether it had announced its disconnect.
    pub(super) fn remove(&mut self, session: SessionId) -> (Option<SessionKind>, bool) {
        let kind = self.kinds.remove(&session);
        let announced = self.announced.remove(&session);
        self.streams.retain(|(s, _), _| *s != session);
        (kind, announced)
    }

    /// The transport of a session, if it is connected.
    pub(super) fn kind(&self, session: SessionId) -> Option<SessionKind> {
        self.kinds.get(&session).copied()
    }

    /// Whether a session has announced its disconnect.
    pub(super) fn announced(&self, session: SessionId) -> bool {
        self.announced.contains(&session)
    }

    /// The session announced its disconnect (3.1.2): the device refuses its later commands.
    pub(super) fn announce(&mut self, session: SessionId) {
        self.announced.insert(session);
    }

    /// Whether `session` has a stream on.
    pub(super) fn streams_to(&self, session: SessionId) -> bool {
        self.streams.keys().any(|(s, _)| *s == session)
    }

    /// Applies 0x40–0x45's flags and period (3.4.1) for `session` at wall time `wall`, the
    /// value being `value` now: with FLAGS bit0 set, updates every period from `wall` on;
    /// clear, any updates stop. The manual's status codes for these commands are E_SUCCESS
    /// and E_CMD_FORMAT_ERROR only, so a period under the 10 ms minimum is not refused: the
    /// stream runs at the minimum.
    pub(super) fn set_stream(
        &mut self,
        session: SessionId,
        id: u8,
        mode: UpdateMode,
        wall: f64,
        value: &Bytes,
    ) {
        if mode.auto {
            if mode.period_ms < MIN_UPDATE_PERIOD_MS {
                tracing::debug!(
                    id,
                    period_ms = mode.period_ms,
                    "simulator: auto-update period under the 10 ms minimum, run at 10 ms"
                );
            }
            let mut stream = Stream {
                mode,
                next_due: wall,
                last: Some(value.clone()),
            };
            stream.next_due = wall + stream.period_s();
            self.streams.insert((session, id), stream);
        } else {
            // FLAGS bit0 clear: answer once and stop any updates (3.4.1).
            self.stop_stream(session, id);
        }
    }

    /// Stops the stream of `id` to `session`, if one runs.
    pub(super) fn stop_stream(&mut self, session: SessionId, id: u8) {
        self.streams.remove(&(session, id));
    }

    /// How many auto-update streams are on (all sessions).
    pub(super) fn active_streams(&self) -> usize {
        self.streams.len()
    }

    /// When the next auto-update is due (wall seconds).
    pub(super) fn next_due(&self) -> Option<f64> {
        self.streams.values().map(|s| s.next_due).reduce(f64::min)
    }

    /// The streams whose update is due at wall time `wall`, as (session, command id).
    pub(super) fn due(&self, wall: f64) -> Vec<(SessionId, u8)> {
        self.streams
            .iter()
            .filter(|(_, s)| s.next_due <= wall)
            .map(|(k, _)| *k)
            .collect()
    }

    /// The due update of stream (`session`, `id`) at wall time `wall`, the value being `value`:
    /// schedules the next one, and returns the value if it is to be sent. A `paused` session
    /// gets none this time (its next one is a period later). On-change streams send only when
    /// the value moved by the manual's threshold (3.4.4–3.4.6: 0.01 mm, 0.05 mm/s, 0.05 N; any
    /// change of flags or state).
    pub(super) fn update(
        &mut self,
        session: SessionId,
        id: u8,
        value: Bytes,
        wall: f64,
        paused: bool,
    ) -> Option<Bytes> {
        let s = self.streams.get_mut(&(session, id))?;
        // Never fall behind by more than one period (no bursts after a stall).
        s.next_due = (s.next_due + s.period_s()).max(wall);
        if paused {
            return None;
        }
        let changed = match &s.last {
            None => true,
            Some(last) => changed(id, last, &value),
        };
        if !s.mode.on_change || changed {
            s.last = Some(value.clone());
            Some(value)
        } else {
            None
        }
    }
}

fn changed(id: u8, last: &[u8], now: &[u8]) -> bool {
    let threshold = match id {
        id::WIDTH => 0.01,
        id::SPEED | id::FORCE => 0.05,
        _ => return last != now,
    };
    match (
        crate::wsg::types::decode_f32(last),
        crate::wsg::types::decode_f32(now),
    ) {
        (Ok(a), Ok(b)) => (a - b).abs() >= threshold,
        _ => true,
    }
}
