//! How the gripper's opening becomes the positions of a description's joints: one
//! `(multiplier, offset)` per name in `joint_names`, so that any URDF can be served.
//!
//! Joint `i` is at `joint_multipliers[i] × opening + joint_offsets[i]`, the opening in metres
//! (the distance between the fingers the device reports); its velocity is
//! `joint_multipliers[i] × finger speed`. The defaults are the joints of the description this
//! package ships (`urdf/`): `base_joint_gripper_left` at −opening/2 and
//! `base_joint_gripper_right` at +opening/2, the names and signs of the public WSG URDFs
//! (nalt/wsg50-ros-pkg, swilcock0/wsg50-ros2-pkg, ipa-vsp/wsg50_ros), whose left finger's limits
//! are negative. Publishing +opening/2 for both fingers, as this node did before, draws the left
//! finger on the wrong side and gives MoveIt a start state out of bounds.
//!
//! Empty `joint_multipliers` (the default) derives them from the number of names: two names are
//! the two fingers (−½, +½); one name is the opening in the `position_convention` (`width`: 1,
//! `finger`: ½); any other number of names needs `joint_multipliers` set. Empty
//! `joint_offsets` (the default) is all zeros.

use crate::params::{ParamError, Params, PositionConvention};

/// The default `joint_names` (with an empty `prefix`): the finger joints of the shipped
/// description, `urdf/wsg.urdf.xacro` and `urdf/griplink.urdf.xacro`.
pub const DEFAULT_JOINT_NAMES: [&str; 2] = ["base_joint_gripper_left", "base_joint_gripper_right"];

/// The multipliers two finger joints get when `joint_multipliers` is empty: the left finger at
/// −opening/2, the right one at +opening/2.
pub const FINGER_MULTIPLIERS: [f64; 2] = [-0.5, 0.5];

/// The resolved mapping, one entry per joint name.
#[derive(Clone, Debug, PartialEq)]
pub struct JointMap {
    /// The joint names, as published.
    pub names: Vec<String>,
    /// Joint position per metre of opening (and joint velocity per m/s of finger speed).
    pub multipliers: Vec<f64>,
    /// Joint position at a closed gripper (opening 0).
    pub offsets: Vec<f64>,
}

impl JointMap {
    /// The mapping `params` asks for, or which parameter is wrong: no names, an empty or
    /// repeated name, a list whose length differs from `joint_names`, a value that is not finite.
    pub fn new(params: &Params) -> Result<JointMap, ParamError> {
        let names = params.joint_names.clone();
        if names.is_empty() {
            return Err(ParamError("joint_names must hold at least one name".into()));
        }
        for (i, n) in names.iter().enumerate() {
            if n.is_empty() {
                return Err(ParamError(format!("joint_names[{i}] is empty")));
            }
            if names[..i].contains(n) {
                return Err(ParamError(format!("joint_names lists {n:?} twice")));
            }
        }
        let multipliers = if !params.joint_multipliers.is_empty() {
            params.joint_multipliers.clone()
        } else {
            match names.len() {
                1 => vec![match params.position_convention {
                    PositionConvention::Width => 1.0,
                    PositionConvention::Finger => 0.5,
                }],
                2 => FINGER_MULTIPLIERS.to_vec(),
                n => {
                    return Err(ParamError(format!(
                        "joint_multipliers must be set for {n} joint names \
                         (defaults exist only for one name, the opening, or two, the fingers)"
                    )))
                }
            }
        };
        let offsets = if params.joint_offsets.is_empty() {
            vec![0.0; names.len()]
        } else {
            params.joint_offsets.clone()
        };
        for (what, list) in [
            ("joint_multipliers", &multipliers),
            ("joint_offsets", &offsets),
        ] {
            if list.len() != names.len() {
                return Err(ParamError(format!(
                    "{what} has {} values for {} joint names",
                    list.len(),
                    names.len()
                )));
            }
            if let Some(v) = list.iter().find(|v| !v.is_finite()) {
                return Err(ParamError(format!("{what} holds {v}, not a finite number")));
            }
        }
        Ok(JointMap {
            names,
            multipliers,
            offsets,
        })
    }

    /// Each joint's position at an opening of `width_mm`.
    pub fn positions(&self, width_mm: f64) -> Vec<f64> {
        let width_m = width_mm / 1000.0;
        self.multipliers
            .iter()
            .zip(&self.offsets)
            .map(|(m, o)| m * width_m + o)
            .collect()
    }

    /// Each joint's velocity at a finger speed of `speed_mm_per_s` (the opening's rate).
    pub fn velocities(&self, speed_mm_per_s: f64) -> Vec<f64> {
        let speed_m = speed_mm_per_s / 1000.0;
        self.multipliers.iter().map(|m| m * speed_m).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(names: &[&str]) -> Params {
        Params {
            joint_names: names.iter().map(|n| (*n).to_owned()).collect(),
            ..Params::default()
        }
    }

    #[test]
    fn the_defaults_are_the_shipped_descriptions_fingers_left_negative() {
        let map = JointMap::new(&Params::default()).unwrap();
        assert_eq!(map.names, DEFAULT_JOINT_NAMES.map(str::to_owned).to_vec());
        assert_eq!(map.positions(40.0), vec![-0.02, 0.02]);
        assert_eq!(map.velocities(10.0), vec![-0.005, 0.005]);
        assert_eq!(map.positions(0.0), vec![0.0, 0.0]);
    }

    #[test]
    fn one_name_is_the_opening_in_the_position_convention() {
        let mut p = params(&["gripper_joint"]);
        assert_eq!(JointMap::new(&p).unwrap().positions(40.0), vec![0.04]);
        p.position_convention = PositionConvention::Finger;
        assert_eq!(JointMap::new(&p).unwrap().positions(40.0), vec![0.02]);
    }

    #[test]
    fn multipliers_and_offsets_serve_any_description() {
        // A linkage gripper whose revolute joints turn 10 rad per metre of opening, from
        // 0.3 rad at closed, one of them mirrored.
        let mut p = params(&["a", "b", "c"]);
        p.joint_multipliers = vec![10.0, -10.0, 0.5];
        p.joint_offsets = vec![0.3, -0.3, 0.0];
        let map = JointMap::new(&p).unwrap();
        let pos = map.positions(20.0);
        let want = [0.5, -0.5, 0.01];
        for (got, want) in pos.iter().zip(want) {
            assert!((got - want).abs() < 1e-12, "{pos:?}");
        }
        assert_eq!(map.velocities(100.0), vec![1.0, -1.0, 0.05]);
    }

    #[test]
    fn inconsistent_mappings_are_errors() {
        let with = |names: &[&str], m: &[f64], o: &[f64]| {
            let mut p = params(names);
            p.joint_multipliers = m.to_vec();
            p.joint_offsets = o.to_vec();
            JointMap::new(&p)
        };
        assert!(with(&[], &[], &[]).is_err());
        assert!(with(&["a", ""], &[], &[]).is_err());
        assert!(with(&["a", "a"], &[], &[]).is_err());
        assert!(with(&["a", "b", "c"], &[], &[]).is_err());
        assert!(with(&["a", "b"], &[1.0], &[]).is_err());
        assert!(with(&["a", "b"], &[], &[0.0, 0.0, 0.0]).is_err());
        assert!(with(&["a"], &[f64::NAN], &[]).is_err());
        assert!(with(&["a"], &[], &[f64::INFINITY]).is_err());
        assert!(with(&["a", "b", "c"], &[1.0, 1.0, 1.0], &[]).is_ok());
    }
}
