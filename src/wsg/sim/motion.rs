//! The motion model: trapezoidal speed profiles (accelerate, cruise, decelerate) within the
//! model's limits, and the move in progress with the session and command that started it.

use super::sessions::SessionId;

/// What a move is for: decides the grip state and the final status when it ends (Anhang C).
/// A pre-position that is `blocked` stops on a part before its target (E_AXIS_BLOCKED).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum MotionKind {
    Homing,
    PrePosition { blocked: bool },
    Grasp { found: bool },
    Release,
}

/// A trapezoidal move (accelerate, cruise, decelerate) from `from_mm` to `to_mm`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Profile {
    pub(super) from_mm: f64,
    pub(super) to_mm: f64,
    acc: f64,
    v_peak: f64,
    t_acc: f64,
    pub(super) total: f64,
}

impl Profile {
    pub(super) fn new(from_mm: f32, to_mm: f32, speed: f32, acc: f32) -> Self {
        let (from_mm, to_mm, v, acc) = (
            f64::from(from_mm),
            f64::from(to_mm),
            f64::from(speed),
            f64::from(acc),
        );
        let dist = (to_mm - from_mm).abs();
        let (t_acc, v_peak, total) = if dist <= v * v / acc {
            let t = (dist / acc).sqrt();
            (t, acc * t, 2.0 * t)
        } else {
            (v / acc, v, dist / v + v / acc)
        };
        Self {
            from_mm,
            to_mm,
            acc,
            v_peak,
            t_acc,
            total,
        }
    }

    fn travelled(&self, t: f64) -> f64 {
        let dist = (self.to_mm - self.from_mm).abs();
        if t <= 0.0 {
            0.0
        } else if t >= self.total {
            dist
        } else if t < self.t_acc {
            0.5 * self.acc * t * t
        } else if t < self.total - self.t_acc {
            0.5 * self.acc * self.t_acc * self.t_acc + self.v_peak * (t - self.t_acc)
        } else {
            let r = self.total - t;
            dist - 0.5 * self.acc * r * r
        }
    }

    pub(super) fn position(&self, t: f64) -> f32 {
        let s = self.travelled(t);
        let p = if self.to_mm >= self.from_mm {
            self.from_mm + s
        } else {
            self.from_mm - s
        };
        p as f32
    }

    pub(super) fn speed(&self, t: f64) -> f32 {
        let v = if t <= 0.0 || t >= self.total {
            0.0
        } else if t < self.t_acc {
            self.acc * t
        } else if t < self.total - self.t_acc {
            self.v_peak
        } else {
            self.acc * (self.total - t)
        };
        v as f32
    }
}

/// The move in progress: who started it (its final reply goes there, manual 1.3) and how.
#[derive(Clone, Copy, Debug)]
pub(super) struct Motion {
    pub(super) session: SessionId,
    pub(super) command: u8,
    pub(super) kind: MotionKind,
    /// Simulated seconds.
    pub(super) start: f64,
    pub(super) profile: Profile,
    /// Simulated seconds between the fingers' stop and the final reply
    /// ([`SimConfig::final_reply_lag`](super::SimConfig::final_reply_lag)).
    pub(super) settle: f64,
}

impl Motion {
    /// When the fingers stop, simulated seconds.
    pub(super) fn end(&self) -> f64 {
        self.start + self.profile.total
    }

    /// When the command ends and its final reply is sent, simulated seconds.
    pub(super) fn done(&self) -> f64 {
        self.end() + self.settle
    }
}
#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_reaches_its_end() {
        let p = Profile::new(0.0, 100.0, 50.0, 100.0);
        assert!((p.total - 2.5).abs() < 1e-9, "{}", p.total);
        assert_eq!(p.position(p.total), 100.0);
        assert!((p.speed(1.0) - 50.0).abs() < 1e-4);
        let short = Profile::new(10.0, 9.0, 400.0, 100.0);
        assert!((short.total - 0.2).abs() < 1e-9);
        assert_eq!(short.position(1.0), 9.0);
    }
}
