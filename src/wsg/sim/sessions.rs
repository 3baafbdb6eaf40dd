//! Sessions (the connections to the device) and their auto-update streams (manual 3.4).
//!
//! A session is what the device tells its clients apart by: a TCP connection, a UDP peer, a
//! serial line. Its auto-updates are its own and end with it; the move it started answers it.

use bytes::Bytes;

use super::device::{data, f32_bytes, finger_power_id, Device, Out, SessionId, SessionKind};
use crate::wsg::command::{id, UpdateMode};
use crate::wsg::{GripState, Status};

/// The shortest auto-update period, ms: "Der minimale zulässige Wert beträgt 10 ms" (3.4.1,
/// 3.4.2, 3.4.4–3.4.6).
pub const MIN_UPDATE_PERIOD_MS: u16 = 10;

/// One auto-update stream of one session.
#[derive(Clone, Debug)]
pub(super) struct Stream {
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

impl Device {
    /// A session opened.
    pub fn connect(&mut self, session: SessionId, kind: SessionKind) {
        self.sessions.insert(session, kind);
    }

    /// A session closed (or was unplugged, or a UDP peer expired). An unannounced TCP close
    /// triggers FAST STOP (manual 1.4.2), which ends a move in progress with E_CMD_ABORTED like
    /// a stop does (1.3): the returned reply goes to whichever session started the move, which
    /// may be another, still connected one (or this one, still reading after a half-close). The
    /// session's auto-updates end.
    pub fn disconnect(&mut self, session: SessionId, now: f64) -> Vec<Out> {
        let mut out = self.advance(now);
        let kind = self.sessions.remove(&session);
        let announced = self.announced.remove(&session);
        self.streams.retain(|(s, _), _| *s != session);
        if kind == Some(SessionKind::Tcp) && !announced && self.cfg.fast_stop_on_close {
            out.extend(self.trigger_fast_stop());
        }
        out
    }

    /// The transport of a session, if it is connected.
    pub fn session_kind(&self, session: SessionId) -> Option<SessionKind> {
        self.sessions.get(&session).copied()
    }

    /// Whether a session has announced its disconnect.
    pub fn announced(&self, session: SessionId) -> bool {
        self.announced.contains(&session)
    }

    /// Whether `session` is still owed something: the final reply of a move it started or of a
    /// finger power-on (3.6.3), or auto-updates (3.4.1) it switched on. A UDP peer is not
    /// forgotten while it is: the device keeps streaming to its UDP remote port whether or not
    /// the driver there ever sends again, and public drivers subscribe once and then only listen.
    pub fn owes_session(&self, session: SessionId) -> bool {
        self.streams.keys().any(|(s, _)| *s == session)
            || self.motion.is_some_and(|m| m.session == session)
            || self
                .finger_power_on
                .iter()
                .flatten()
                .any(|p| p.owed.iter().any(|(s, _)| *s == session))
    }

    /// Answers 0x40–0x45's flags and period (3.4.1): the value now, and with FLAGS bit0 set
    /// updates every period from wall time `wall`. The manual's status codes for these commands
    /// are E_SUCCESS and E_CMD_FORMAT_ERROR only, so a period under the 10 ms minimum is not
    /// refused: the stream runs at the minimum.
    pub(super) fn auto_update(
        &mut self,
        session: SessionId,
        id: u8,
        mode: UpdateMode,
        wall: f64,
    ) -> Out {
        let value = self.streamed_value(id);
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
            self.streams.remove(&(session, id));
        }
        data(session, id, value)
    }

    fn streamed_value(&self, id: u8) -> Bytes {
        match id {
            id::SYSTEM_STATE => Bytes::copy_from_slice(&self.system_state().bits().to_le_bytes()),
            id::GRIP_STATE => Bytes::copy_from_slice(&[self.grip.to_u8()]),
            id::WIDTH => f32_bytes(self.width_mm()),
            id::SPEED => f32_bytes(self.speed_mm_per_s()),
            _ => f32_bytes(self.force_n()),
        }
    }

    fn force_n(&self) -> f32 {
        if self.grip == GripState::Holding {
            self.force_limit
        } else {
            0.0
        }
    }

    /// How many auto-update streams are on (all sessions).
    pub fn active_streams(&self) -> usize {
        self.streams.len()
    }

    /// When the next auto-update or finger power-on is due (wall seconds).
    pub fn next_update_due(&self) -> Option<f64> {
        let power = self.finger_power_on.iter().flatten().map(|p| p.due_wall);
        self.streams
            .values()
            .map(|s| s.next_due)
            .chain(power)
            .reduce(f64::min)
    }

    /// The auto-updates due at wall time `wall` (after [`Device::advance`] to the current
    /// simulated time). On-change streams send only when the value moved by the manual's
    /// threshold (3.4.4–3.4.6: 0.01 mm, 0.05 mm/s, 0.05 N; any change of flags or state).
    /// Sessions for which `paused` is true get none this time (their next one is a period
    /// later): the server pauses a connection whose client does not read its replies.
    ///
    /// Finger power-ons due by `wall` finish here too (their 500 ms are wall time, 3.6.3).
    pub fn updates_due(&mut self, wall: f64, paused: impl Fn(SessionId) -> bool) -> Vec<Out> {
        let mut out = Vec::new();
        for i in 0..self.finger_power_on.len() {
            if let Some(p) = self.finger_power_on[i].take_if(|p| p.due_wall <= wall) {
                self.finger_powered[i] = true;
                out.extend(p.finish(finger_power_id(i), Status::Success));
            }
        }
        let due: Vec<(SessionId, u8)> = self
            .streams
            .iter()
            .filter(|(_, s)| s.next_due <= wall)
            .map(|(k, _)| *k)
            .collect();
        for (session, id) in due {
            let value = self.streamed_value(id);
            let Some(s) = self.streams.get_mut(&(session, id)) else {
                continue;
            };
            // Never fall behind by more than one period (no bursts after a stall).
            s.next_due = (s.next_due + s.period_s()).max(wall);
            if paused(session) {
                continue;
            }
            let changed = match &s.last {
                None => true,
                Some(last) => changed(id, last, &value),
            };
            if !s.mode.on_change || changed {
                s.last = Some(value.clone());
                out.push(data(session, id, value));
            }
        }
        out
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
