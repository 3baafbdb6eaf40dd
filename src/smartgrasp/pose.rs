//! Poses (manual 5): a typed pose per format with the wire's integers kept exact, conversion to SI
//! (metres and a normalised unit quaternion) and between formats.
//!
//! Rotation conventions, as the manual states them:
//! - quaternion: `qx qy qz qw`, scaled by 10^6, not normalised on the wire;
//! - axis-angle: rotation vector in µrad (direction = axis, length = angle), Universal Robots;
//! - WPR: W about the fixed x axis, then P about the fixed y axis, then R about the fixed z axis
//!   (extrinsic x-y-z), µdeg, FANUC and Yaskawa: `R = Rz(R)·Ry(P)·Rx(W)`;
//! - ABC: A about z, then B about the new y', then C about the new x'' (intrinsic z-y'-x''),
//!   µdeg, KUKA: `R = Rz(A)·Ry(B)·Rx(C)`.
//!
//! Extrinsic x-y-z and intrinsic z-y'-x'' give the same matrix, so ABC is WPR with the angles
//! named in the other order (A = R, B = P, C = W); the tests pin both against elementary rotations.

use std::f64::consts::PI;
use std::fmt;

use super::types::PoseFormat;

/// A pose could not be read, built or converted.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PoseError {
    /// The pose format is not one of the manual's four.
    #[error("unsupported pose format {0}")]
    UnsupportedFormat(PoseFormat),
    /// A quaternion of length zero (or not finite) describes no rotation.
    #[error("the quaternion has no direction (all zero or not finite)")]
    DegenerateQuaternion,
    /// A V4 pose carries six values (PROTOCOLS.md 2b); a quaternion needs seven, and whether V4
    /// sends a seventh (at response bytes 68–71) is not public.
    #[error("pose format {0} needs seven values; a V4 pose carries six")]
    SevenValuesInV4(PoseFormat),
    /// A value does not fit the wire's i32 in its unit.
    #[error("{what} does not fit the wire's 32-bit integer")]
    OutOfRange {
        /// Which value.
        what: &'static str,
    },
}

/// A rotation as a normalised unit quaternion, scalar last like the wire (`x y z w`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnitQuaternion {
    x: f64,
    y: f64,
    z: f64,
    w: f64,
}

impl UnitQuaternion {
    /// No rotation.
    pub const IDENTITY: UnitQuaternion = UnitQuaternion {
        x: 0.0,
        y: 0.0,
        z: 0.0,
        w: 1.0,
    };

    /// Normalises `(x, y, z, w)`; fails for a zero or non-finite quaternion.
    pub fn new(x: f64, y: f64, z: f64, w: f64) -> Result<UnitQuaternion, PoseError> {
        let norm = (x * x + y * y + z * z + w * w).sqrt();
        if !norm.is_finite() || norm == 0.0 {
            return Err(PoseError::DegenerateQuaternion);
        }
        Ok(UnitQuaternion {
            x: x / norm,
            y: y / norm,
            z: z / norm,
            w: w / norm,
        })
    }

    /// The components `[x, y, z, w]`.
    pub fn xyzw(&self) -> [f64; 4] {
        [self.x, self.y, self.z, self.w]
    }

    /// The rotation of `angle_rad` about `axis` (need not be normalised; a zero axis gives the
    /// identity).
    pub fn from_axis_angle(axis: [f64; 3], angle_rad: f64) -> UnitQuaternion {
        let n = norm3(axis);
        if n == 0.0 || !n.is_finite() || !angle_rad.is_finite() {
            return UnitQuaternion::IDENTITY;
        }
        let (s, c) = (angle_rad / 2.0).sin_cos();
        UnitQuaternion {
            x: axis[0] / n * s,
            y: axis[1] / n * s,
            z: axis[2] / n * s,
            w: c,
        }
    }

    /// From a rotation vector in radians (direction = axis, length = angle), as Universal Robots
    /// write it.
    pub fn from_rotation_vector(v_rad: [f64; 3]) -> UnitQuaternion {
        UnitQuaternion::from_axis_angle(v_rad, norm3(v_rad))
    }

    /// The rotation vector in radians, angle in `[0, π]`.
    pub fn to_rotation_vector_rad(&self) -> [f64; 3] {
        // q and -q are the same rotation; w ≥ 0 picks the angle in [0, π].
        let q = if self.w < 0.0 { self.negated() } else { *self };
        let s = (q.x * q.x + q.y * q.y + q.z * q.z).sqrt();
        if s < 1e-12 {
            // Small angle: the vector part is half the rotation vector.
            return [2.0 * q.x, 2.0 * q.y, 2.0 * q.z];
        }
        let angle = 2.0 * s.atan2(q.w);
        [q.x / s * angle, q.y / s * angle, q.z / s * angle]
    }

    /// From roll–pitch–yaw in radians: `Rz(yaw)·Ry(pitch)·Rx(roll)`, i.e. roll about the fixed x
    /// axis, then pitch about the fixed y, then yaw about the fixed z (= intrinsic z-y'-x'').
    pub fn from_rpy(roll_rad: f64, pitch_rad: f64, yaw_rad: f64) -> UnitQuaternion {
        let qx = UnitQuaternion::from_axis_angle([1.0, 0.0, 0.0], roll_rad);
        let qy = UnitQuaternion::from_axis_angle([0.0, 1.0, 0.0], pitch_rad);
        let qz = UnitQuaternion::from_axis_angle([0.0, 0.0, 1.0], yaw_rad);
        qz.then_after(qy).then_after(qx)
    }

    /// Roll, pitch, yaw in radians for `Rz(yaw)·Ry(pitch)·Rx(roll)`: roll and yaw in `(-π, π]`,
    /// pitch in `[-π/2, π/2]`. At pitch ±90° (gimbal lock) only yaw ∓ roll is defined; roll is
    /// then reported as 0.
    pub fn to_rpy_rad(&self) -> [f64; 3] {
        let m = self.matrix();
        let r20 = m[2][0];
        let pitch = (-r20).atan2((m[0][0] * m[0][0] + m[1][0] * m[1][0]).sqrt());
        if r20.abs() > 1.0 - 1e-12 {
            // R = Rz(y)·Ry(±90°)·Rx(r) depends only on y ∓ r; with r = 0:
            // r01 = -sin y, r11 = cos y.
            let yaw = (-m[0][1]).atan2(m[1][1]);
            return [0.0, pitch, wrap(yaw)];
        }
        let roll = m[2][1].atan2(m[2][2]);
        let yaw = m[1][0].atan2(m[0][0]);
        [wrap(roll), pitch, wrap(yaw)]
    }

    /// This rotation composed with `inner`: the rotation that applies `inner` first, then `self`
    /// (the quaternion product `self · inner`).
    pub fn then_after(self, inner: UnitQuaternion) -> UnitQuaternion {
        let (a, b) = (self, inner);
        let q = UnitQuaternion {
            w: a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
            x: a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
            y: a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
            z: a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w,
        };
        // Renormalise so rounding does not accumulate over long compositions.
        UnitQuaternion::new(q.x, q.y, q.z, q.w).unwrap_or(UnitQuaternion::IDENTITY)
    }

    /// Rotates the vector `v`.
    pub fn rotate(&self, v: [f64; 3]) -> [f64; 3] {
        let m = self.matrix();
        std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
    }

    /// The angle in radians of the rotation that takes `self` to `other` (0 when they are the
    /// same rotation, whatever the quaternions' signs).
    pub fn angle_to_rad(&self, other: &UnitQuaternion) -> f64 {
        // The relative rotation conj(self)·other; atan2 keeps precision near 0, where acos of
        // the dot product would not.
        let (a, b) = (self, other);
        let w = a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z;
        let x = a.w * b.x - a.x * b.w - a.y * b.z + a.z * b.y;
        let y = a.w * b.y + a.x * b.z - a.y * b.w - a.z * b.x;
        let z = a.w * b.z - a.x * b.y + a.y * b.x - a.z * b.w;
        2.0 * (x * x + y * y + z * z).sqrt().atan2(w.abs())
    }

    /// The rotation matrix, rows first.
    pub fn matrix(&self) -> [[f64; 3]; 3] {
        let UnitQuaternion { x, y, z, w } = *self;
        [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - w * z),
                2.0 * (x * z + w * y),
            ],
            [
                2.0 * (x * y + w * z),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - w * x),
            ],
            [
                2.0 * (x * z - w * y),
                2.0 * (y * z + w * x),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ]
    }

    fn negated(&self) -> UnitQuaternion {
        UnitQuaternion {
            x: -self.x,
            y: -self.y,
            z: -self.z,
            w: -self.w,
        }
    }
}

/// Position µm and quaternion ×10^6 (format 1). The quaternion is kept as sent: not normalised.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QuaternionPose {
    /// x, y, z in µm.
    pub position_um: [i32; 3],
    /// qx, qy, qz, qw scaled by 10^6.
    pub quaternion_e6: [i32; 4],
}

/// Position µm and rotation vector µrad (format 2, Universal Robots).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AxisAnglePose {
    /// x, y, z in µm.
    pub position_um: [i32; 3],
    /// Rotation vector x, y, z in µrad: direction = axis, length = angle.
    pub rotation_vector_urad: [i32; 3],
}

/// Position µm and W, P, R in µdeg about the fixed x, y, z axes (format 16, FANUC, Yaskawa).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WprPose {
    /// x, y, z in µm.
    pub position_um: [i32; 3],
    /// W (about fixed x), P (about fixed y), R (about fixed z) in µdeg, applied in that order.
    pub wpr_udeg: [i32; 3],
}

/// Position µm and A, B, C in µdeg about z, then y', then x'' (format 17, KUKA).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AbcPose {
    /// x, y, z in µm.
    pub position_um: [i32; 3],
    /// A (about z), B (about the new y'), C (about the new x'') in µdeg, applied in that order.
    pub abc_udeg: [i32; 3],
}

/// A pose as it travels on the wire: one of the manual's four formats (manual 5), integers exact.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pose {
    /// Format 1.
    Quaternion(QuaternionPose),
    /// Format 2.
    AxisAngle(AxisAnglePose),
    /// Format 16.
    Wpr(WprPose),
    /// Format 17.
    Abc(AbcPose),
}

/// A pose in SI units: position in metres, orientation as a unit quaternion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SiPose {
    /// x, y, z in metres.
    pub position_m: [f64; 3],
    /// Orientation.
    pub orientation: UnitQuaternion,
}

impl Pose {
    /// The pose's format number.
    pub fn format(&self) -> PoseFormat {
        match self {
            Pose::Quaternion(_) => PoseFormat::Quaternion,
            Pose::AxisAngle(_) => PoseFormat::AxisAngle,
            Pose::Wpr(_) => PoseFormat::Wpr,
            Pose::Abc(_) => PoseFormat::Abc,
        }
    }

    /// Position in µm, exactly as on the wire.
    pub fn position_um(&self) -> [i32; 3] {
        match self {
            Pose::Quaternion(p) => p.position_um,
            Pose::AxisAngle(p) => p.position_um,
            Pose::Wpr(p) => p.position_um,
            Pose::Abc(p) => p.position_um,
        }
    }

    /// Position in metres.
    pub fn position_m(&self) -> [f64; 3] {
        self.position_um().map(|um| f64::from(um) * 1e-6)
    }

    /// The seven wire integers; the unused seventh of the three-angle formats is 0.
    pub fn to_wire(&self) -> [i32; 7] {
        let ([x, y, z], [a, b, c, d]) = match *self {
            Pose::Quaternion(p) => (p.position_um, p.quaternion_e6),
            Pose::AxisAngle(p) => (p.position_um, with_unused(p.rotation_vector_urad)),
            Pose::Wpr(p) => (p.position_um, with_unused(p.wpr_udeg)),
            Pose::Abc(p) => (p.position_um, with_unused(p.abc_udeg)),
        };
        [x, y, z, a, b, c, d]
    }

    /// Reads the seven wire integers in `format`; the unused seventh is ignored.
    pub fn from_wire(format: PoseFormat, v: [i32; 7]) -> Result<Pose, PoseError> {
        let [x, y, z, a, b, c, d] = v;
        let position_um = [x, y, z];
        Ok(match format {
            PoseFormat::Quaternion => Pose::Quaternion(QuaternionPose {
                position_um,
                quaternion_e6: [a, b, c, d],
            }),
            PoseFormat::AxisAngle => Pose::AxisAngle(AxisAnglePose {
                position_um,
                rotation_vector_urad: [a, b, c],
            }),
            PoseFormat::Wpr => Pose::Wpr(WprPose {
                position_um,
                wpr_udeg: [a, b, c],
            }),
            PoseFormat::Abc => Pose::Abc(AbcPose {
                position_um,
                abc_udeg: [a, b, c],
            }),
            other @ PoseFormat::Unknown(_) => return Err(PoseError::UnsupportedFormat(other)),
        })
    }

    /// The six wire integers of a V4 pose (PROTOCOLS.md 2b: ROBOT_POSE at 24, the GET_GRASP
    /// response's pose at 44). The example only uses ABC (17); axis-angle and WPR have no seventh
    /// value either, a quaternion is refused.
    pub fn to_wire6(&self) -> Result<[i32; 6], PoseError> {
        if let Pose::Quaternion(_) = self {
            return Err(PoseError::SevenValuesInV4(PoseFormat::Quaternion));
        }
        let [x, y, z, a, b, c, _] = self.to_wire();
        Ok([x, y, z, a, b, c])
    }

    /// Reads the six wire integers of a V4 pose in `format` (see [`to_wire6`](Self::to_wire6)).
    pub fn from_wire6(format: PoseFormat, v: [i32; 6]) -> Result<Pose, PoseError> {
        if format == PoseFormat::Quaternion {
            return Err(PoseError::SevenValuesInV4(format));
        }
        let [x, y, z, a, b, c] = v;
        Pose::from_wire(format, [x, y, z, a, b, c, 0])
    }

    /// The orientation as a unit quaternion. Fails only for a quaternion pose of length zero.
    pub fn orientation(&self) -> Result<UnitQuaternion, PoseError> {
        match *self {
            Pose::Quaternion(p) => {
                let [x, y, z, w] = p.quaternion_e6.map(|v| f64::from(v) * 1e-6);
                UnitQuaternion::new(x, y, z, w)
            }
            Pose::AxisAngle(p) => Ok(UnitQuaternion::from_rotation_vector(
                p.rotation_vector_urad.map(|v| f64::from(v) * 1e-6),
            )),
            Pose::Wpr(p) => {
                let [w, p, r] = p.wpr_udeg.map(udeg_to_rad);
                Ok(UnitQuaternion::from_rpy(w, p, r))
            }
            Pose::Abc(p) => {
                let [a, b, c] = p.abc_udeg.map(udeg_to_rad);
                Ok(UnitQuaternion::from_rpy(c, b, a))
            }
        }
    }

    /// The pose in SI units.
    pub fn to_si(&self) -> Result<SiPose, PoseError> {
        Ok(SiPose {
            position_m: self.position_m(),
            orientation: self.orientation()?,
        })
    }

    /// The same pose in another format (rounded to the wire's resolution).
    pub fn to_format(&self, format: PoseFormat) -> Result<Pose, PoseError> {
        if format == self.format() {
            return Ok(*self);
        }
        self.to_si()?.to_pose(format)
    }
}

impl SiPose {
    /// The pose in a wire format, rounded to the nearest µm, µrad, µdeg or 10^-6.
    /// Euler angles come out in `(-180°, 180°]` (pitch/B in `[-90°, 90°]`); at the gimbal lock
    /// (pitch/B = ±90°) W, respectively C, is 0.
    pub fn to_pose(&self, format: PoseFormat) -> Result<Pose, PoseError> {
        let position_um = [
            to_wire_int(self.position_m[0] * 1e6, "position x")?,
            to_wire_int(self.position_m[1] * 1e6, "position y")?,
            to_wire_int(self.position_m[2] * 1e6, "position z")?,
        ];
        let q = self.orientation;
        Ok(match format {
            PoseFormat::Quaternion => {
                let mut e6 = [0; 4];
                for (out, v) in e6.iter_mut().zip(q.xyzw()) {
                    *out = to_wire_int(v * 1e6, "quaternion")?;
                }
                Pose::Quaternion(QuaternionPose {
                    position_um,
                    quaternion_e6: e6,
                })
            }
            PoseFormat::AxisAngle => {
                let v = q.to_rotation_vector_rad();
                Pose::AxisAngle(AxisAnglePose {
                    position_um,
                    rotation_vector_urad: angles_to_wire(v.map(|r| r * 1e6))?,
                })
            }
            PoseFormat::Wpr => {
                let [roll, pitch, yaw] = q.to_rpy_rad();
                Pose::Wpr(WprPose {
                    position_um,
                    wpr_udeg: euler_to_wire([roll, pitch, yaw])?,
                })
            }
            PoseFormat::Abc => {
                let [roll, pitch, yaw] = q.to_rpy_rad();
                Pose::Abc(AbcPose {
                    position_um,
                    abc_udeg: euler_to_wire([yaw, pitch, roll])?,
                })
            }
            other @ PoseFormat::Unknown(_) => return Err(PoseError::UnsupportedFormat(other)),
        })
    }
}

impl fmt::Display for Pose {
    /// The pose in the robot's own notation: millimetres and degrees for the Euler formats,
    /// millimetres and radians for axis-angle, millimetres and the raw scaled quaternion otherwise.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [x, y, z] = self.position_um().map(|um| f64::from(um) / 1000.0);
        write!(f, "X {x:.3} mm, Y {y:.3} mm, Z {z:.3} mm, ")?;
        match *self {
            Pose::Quaternion(p) => {
                let [a, b, c, d] = p.quaternion_e6.map(|v| f64::from(v) * 1e-6);
                write!(f, "qx {a:.6}, qy {b:.6}, qz {c:.6}, qw {d:.6}")
            }
            Pose::AxisAngle(p) => {
                let [a, b, c] = p.rotation_vector_urad.map(|v| f64::from(v) * 1e-6);
                write!(f, "RX {a:.6} rad, RY {b:.6} rad, RZ {c:.6} rad")
            }
            Pose::Wpr(p) => {
                let [a, b, c] = p.wpr_udeg.map(|v| f64::from(v) * 1e-6);
                write!(f, "W {a:.4}°, P {b:.4}°, R {c:.4}°")
            }
            Pose::Abc(p) => {
                let [a, b, c] = p.abc_udeg.map(|v| f64::from(v) * 1e-6);
                write!(f, "A {a:.4}°, B {b:.4}°, C {c:.4}°")
            }
        }
    }
}

fn with_unused([a, b, c]: [i32; 3]) -> [i32; 4] {
    [a, b, c, 0]
}

fn norm3(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Wraps an angle into `(-π, π]`.
fn wrap(a: f64) -> f64 {
    let w = a.rem_euclid(2.0 * PI);
    if w > PI {
        w - 2.0 * PI
    } else {
        w
    }
}

fn udeg_to_rad(udeg: i32) -> f64 {
    (f64::from(udeg) * 1e-6).to_radians()
}

fn rad_to_udeg(rad: f64) -> f64 {
    rad.to_degrees() * 1e6
}

/// Euler angles in radians to µdeg. An angle that rounds to -180° is written as +180°, so the
/// half-open range `(-180°, 180°]` holds after rounding too.
fn euler_to_wire(rad: [f64; 3]) -> Result<[i32; 3], PoseError> {
    const HALF_TURN_UDEG: i32 = 180_000_000;
    Ok(angles_to_wire(rad.map(rad_to_udeg))?.map(|a| {
        if a == -HALF_TURN_UDEG {
            HALF_TURN_UDEG
        } else {
            a
        }
    }))
}

fn angles_to_wire(v: [f64; 3]) -> Result<[i32; 3], PoseError> {
    Ok([
        to_wire_int(v[0], "angle")?,
        to_wire_int(v[1], "angle")?,
        to_wire_int(v[2], "angle")?,
    ])
}

fn to_wire_int(v: f64, what: &'static str) -> Result<i32, PoseError> {
    let r = v.round();
    if r.is_finite() && r >= f64::from(i32::MIN) && r <= f64::from(i32::MAX) {
        // In range and integral: the cast is exact.
        Ok(r as i32)
    } else {
        Err(PoseError::OutOfRange { what })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const EPS: f64 = 1e-9;
    /// One wire step of an angle in µdeg, in radians: the resolution after rounding.
    const UDEG: f64 = 1e-6 * PI / 180.0;

    fn close3(a: [f64; 3], b: [f64; 3], eps: f64) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < eps)
    }

    fn orientation(p: Pose) -> UnitQuaternion {
        p.orientation().expect("valid pose")
    }

    fn wpr(w: f64, p: f64, r: f64) -> Pose {
        Pose::Wpr(WprPose {
            position_um: [0; 3],
            wpr_udeg: [w, p, r].map(|d| (d * 1e6) as i32),
        })
    }

    fn abc(a: f64, b: f64, c: f64) -> Pose {
        Pose::Abc(AbcPose {
            position_um: [0; 3],
            abc_udeg: [a, b, c].map(|d| (d * 1e6) as i32),
        })
    }

    const X: [f64; 3] = [1.0, 0.0, 0.0];
    const Y: [f64; 3] = [0.0, 1.0, 0.0];
    const Z: [f64; 3] = [0.0, 0.0, 1.0];

    #[test]
    fn ninety_degrees_about_each_axis() {
        // W = 90°: about x, y goes to z.
        assert!(close3(orientation(wpr(90.0, 0.0, 0.0)).rotate(Y), Z, EPS));
        // P = 90°: about y, z goes to x.
        assert!(close3(orientation(wpr(0.0, 90.0, 0.0)).rotate(Z), X, EPS));
        // R = 90°: about z, x goes to y.
        assert!(close3(orientation(wpr(0.0, 0.0, 90.0)).rotate(X), Y, EPS));
        // A = 90°: about z; B about y; C about x.
        assert!(close3(orientation(abc(90.0, 0.0, 0.0)).rotate(X), Y, EPS));
        assert!(close3(orientation(abc(0.0, 90.0, 0.0)).rotate(Z), X, EPS));
        assert!(close3(orientation(abc(0.0, 0.0, 90.0)).rotate(Y), Z, EPS));
        // Rotation vector (0, 0, π/2) µrad: about z.
        let aa = Pose::AxisAngle(AxisAnglePose {
            position_um: [0; 3],
            rotation_vector_urad: [0, 0, 1_570_796],
        });
        assert!(close3(orientation(aa).rotate(X), Y, 1e-6));
        // Quaternion (0, 0, sin 45°, cos 45°) ×10^6: about z.
        let q = Pose::Quaternion(QuaternionPose {
            position_um: [0; 3],
            quaternion_e6: [0, 0, 707_107, 707_107],
        });
        assert!(close3(orientation(q).rotate(X), Y, 1e-6));
    }

    /// WPR (90, 90, 0): W about fixed x first, then P about fixed y. x stays x after W, then
    /// goes to -z; y goes to z after W, then to x.
    #[test]
    fn composed_rotation_follows_the_fixed_axes_order() {
        let q = orientation(wpr(90.0, 90.0, 0.0));
        assert!(close3(q.rotate(X), [0.0, 0.0, -1.0], EPS));
        assert!(close3(q.rotate(Y), X, EPS));
        // ABC (90, 90, 0): A about z (x → y), then B about the new y' (the old -x): the intrinsic
        // order gives Rz(90)·Ry(90); z goes to x under Ry, then x to y under Rz.
        let k = orientation(abc(90.0, 90.0, 0.0));
        assert!(close3(k.rotate(Z), Y, EPS));
        assert!(close3(k.rotate(X), [0.0, 0.0, -1.0], EPS));
        // The same rotation with the angles in the other order is a different one.
        assert!(orientation(wpr(0.0, 90.0, 90.0)).angle_to_rad(&q) > 0.5);
    }

    #[test]
    fn abc_is_wpr_with_the_angles_reversed() {
        let a = orientation(abc(10.0, -20.0, 30.0));
        let w = orientation(wpr(30.0, -20.0, 10.0));
        assert!(a.angle_to_rad(&w) < EPS);
        let converted = abc(10.0, -20.0, 30.0).to_format(PoseFormat::Wpr).unwrap();
        assert_eq!(converted, wpr(30.0, -20.0, 10.0));
    }

    /// The manual's 6.5 example grasp pose.
    #[test]
    fn manual_example_quaternion_is_normalised() {
        let pose = Pose::from_wire(
            PoseFormat::Quaternion,
            [853_798, 111_998, 502_790, 775_990, 630_744, 0, 0],
        )
        .unwrap();
        let si = pose.to_si().unwrap();
        assert!(close3(si.position_m, [0.853798, 0.111998, 0.50279], 1e-12));
        let [x, y, z, w] = si.orientation.xyzw();
        assert!(((x * x + y * y + z * z + w * w) - 1.0).abs() < 1e-12);
        let norm = (0.77599f64.powi(2) + 0.630744f64.powi(2)).sqrt();
        assert!((x - 0.77599 / norm).abs() < 1e-12 && (y - 0.630744 / norm).abs() < 1e-12);
        assert!(z == 0.0 && w == 0.0);
        assert_eq!(
            pose.to_wire(),
            [853_798, 111_998, 502_790, 775_990, 630_744, 0, 0]
        );
    }

    #[test]
    fn round_trips_through_every_format() {
        let start = Pose::Abc(AbcPose {
            position_um: [853_798, -111_998, 502_790],
            abc_udeg: [-25_210_142, 33_000_000, 170_500_000],
        });
        for format in [
            PoseFormat::Quaternion,
            PoseFormat::AxisAngle,
            PoseFormat::Wpr,
        ] {
            let there = start.to_format(format).unwrap();
            assert_eq!(there.position_um(), start.position_um());
            let back = there.to_format(PoseFormat::Abc).unwrap();
            assert_eq!(back.position_um(), start.position_um());
            // Within the rounding of the intermediate format (10^-6 of a quaternion is coarser
            // than 1 µdeg).
            let err = orientation(back).angle_to_rad(&orientation(start));
            assert!(err < 4e-6, "{format}: {err}");
        }
        // WPR → ABC → WPR is exact: only the angles' names change.
        let w = wpr(12.5, -45.0, 179.0);
        assert_eq!(
            w.to_format(PoseFormat::Abc)
                .unwrap()
                .to_format(PoseFormat::Wpr)
                .unwrap(),
            w
        );
    }

    #[test]
    fn angles_wrap_into_the_half_open_range() {
        // R = 190° is R = -170°; W = -180° comes back as +180°.
        let back = wpr(-180.0, 0.0, 190.0)
            .to_si()
            .unwrap()
            .to_pose(PoseFormat::Wpr)
            .unwrap();
        let Pose::Wpr(p) = back else { unreachable!() };
        assert_eq!(p.wpr_udeg[0], 180_000_000);
        assert_eq!(p.wpr_udeg[2], -170_000_000);
        assert!(orientation(back).angle_to_rad(&orientation(wpr(-180.0, 0.0, 190.0))) < 1e-5);
    }

    #[test]
    fn gimbal_lock_keeps_the_rotation() {
        for (w, r, pitch) in [(30.0, 10.0, 90.0), (-40.0, 25.0, -90.0), (0.0, 0.0, 90.0)] {
            let start = wpr(w, pitch, r);
            let si = start.to_si().unwrap();
            let back = si.to_pose(PoseFormat::Wpr).unwrap();
            let Pose::Wpr(p) = back else { unreachable!() };
            assert_eq!(p.wpr_udeg[0], 0, "W is reported as 0 at the lock");
            assert!((p.wpr_udeg[1] - (pitch * 1e6) as i32).abs() <= 1);
            let err = orientation(back).angle_to_rad(&si.orientation);
            assert!(err < 10.0 * UDEG, "pitch {pitch}: {err}");
        }
    }

    #[test]
    fn axis_angle_near_pi_and_zero() {
        let half_turn = Pose::AxisAngle(AxisAnglePose {
            position_um: [0; 3],
            rotation_vector_urad: [0, 3_141_593, 0],
        });
        let q = orientation(half_turn);
        assert!(close3(q.rotate(X), [-1.0, 0.0, 0.0], 1e-6));
        let v = q.to_rotation_vector_rad();
        assert!((norm3(v) - PI).abs() < 1e-6);
        let zero = Pose::AxisAngle(AxisAnglePose {
            position_um: [0; 3],
            rotation_vector_urad: [0; 3],
        });
        assert_eq!(orientation(zero), UnitQuaternion::IDENTITY);
        assert_eq!(UnitQuaternion::IDENTITY.to_rotation_vector_rad(), [0.0; 3]);
    }

    #[test]
    fn bad_poses_are_refused() {
        let zero_q = Pose::Quaternion(QuaternionPose {
            position_um: [0; 3],
            quaternion_e6: [0; 4],
        });
        assert_eq!(zero_q.to_si(), Err(PoseError::DegenerateQuaternion));
        assert_eq!(
            Pose::from_wire(PoseFormat::Unknown(9), [0; 7]),
            Err(PoseError::UnsupportedFormat(PoseFormat::Unknown(9)))
        );
        let far = SiPose {
            position_m: [3000.0, 0.0, 0.0],
            orientation: UnitQuaternion::IDENTITY,
        };
        assert!(matches!(
            far.to_pose(PoseFormat::Wpr),
            Err(PoseError::OutOfRange { .. })
        ));
    }

    proptest::proptest! {
        /// Euler angles → rotation → Euler angles gives the same rotation (the angles may differ
        /// at the wrap and the gimbal lock), and the same angles away from those edges.
        #[test]
        fn euler_round_trips(
            a in -179_999_999i32..=180_000_000,
            b in -89_000_000i32..=89_000_000,
            c in -179_999_999i32..=180_000_000,
        ) {
            let pose = Pose::Abc(AbcPose { position_um: [a, b, c], abc_udeg: [a, b, c] });
            let back = pose.to_si().unwrap().to_pose(PoseFormat::Abc).unwrap();
            // Away from the lock (|B| ≤ 89°), the angles are unique: exact to the µdeg.
            let Pose::Abc(p) = back else { unreachable!() };
            for (x, y) in p.abc_udeg.iter().zip([a, b, c]) {
                proptest::prop_assert!((x - y).abs() <= 1, "{:?} vs {:?}", p.abc_udeg, [a, b, c]);
            }
            let wpr = pose.to_format(PoseFormat::Wpr).unwrap();
            // Rounded to the µdeg: at most half a µdeg about each of three axes.
            proptest::prop_assert!(orientation(wpr).angle_to_rad(&orientation(pose)) < 2.0 * UDEG);
        }

        /// Any non-degenerate quaternion survives a trip through every other format.
        #[test]
        fn quaternion_round_trips(q in proptest::array::uniform4(-1_000_000i32..=1_000_000)) {
            proptest::prop_assume!(q.iter().map(|&v| i64::from(v).pow(2)).sum::<i64>() > 10_000_000_000);
            let pose = Pose::Quaternion(QuaternionPose { position_um: [1, 2, 3], quaternion_e6: q });
            for format in [PoseFormat::AxisAngle, PoseFormat::Wpr, PoseFormat::Abc] {
                let there = pose.to_format(format).unwrap();
                let err = orientation(there).angle_to_rad(&orientation(pose));
                proptest::prop_assert!(err < 1e-5, "{format}: {err}");
            }
        }
    }

    #[test]
    fn angle_to_rad_measures_the_relative_rotation() {
        let a = UnitQuaternion::from_rpy(0.3, -0.2, 1.0);
        let turn = UnitQuaternion::from_axis_angle([1.0, 2.0, -0.5], 1e-7);
        assert!((a.angle_to_rad(&turn.then_after(a)) - 1e-7).abs() < 1e-12);
        let big = UnitQuaternion::from_axis_angle([0.0, 1.0, 0.0], 2.5);
        assert!((a.angle_to_rad(&a.then_after(big)) - 2.5).abs() < 1e-12);
        // -q is the same rotation.
        let [x, y, z, w] = a.xyzw();
        assert!(a.angle_to_rad(&UnitQuaternion::new(-x, -y, -z, -w).unwrap()) < 1e-15);
    }
}
