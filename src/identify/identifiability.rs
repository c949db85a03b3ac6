//! **Identifiability warnings**: what the training data cannot determine, named with the motion
//! that would fix it. A joint that barely moves leaves the columns of its own motion (its
//! velocity and acceleration terms, its friction, and how gravity varies with its angle)
//! constant or zero to the noise, so the fit attributes that joint's torque to whatever else it
//! has; the result is fitted, but it is not a model of that joint.
//!
//! Threshold: a revolute joint "barely moves" when its position spans less than
//! [`STILL_RAD`] over all training files (cos q then varies by under 0.04 %: the gravity
//! column's change with the angle is below a 0.3 %-noise torque sensor), a prismatic one when it
//! spans less than [`STILL_M`].

use super::prepare::Prepared;
use crate::dh::{DhTable, JointKind};

/// Least span of a revolute joint's position over the training data (rad): 0.05 rad ≈ 2.9°.
pub const STILL_RAD: f64 = 0.05;
/// Least span of a prismatic joint's position (m).
pub const STILL_M: f64 = 0.005;

/// Warnings about the training data `train` (joint kinds from `table`; revolute without one).
pub fn warnings(train: &[Prepared], table: Option<&DhTable>, dof: usize) -> Vec<String> {
    let mut lo = vec![f64::INFINITY; dof];
    let mut hi = vec![f64::NEG_INFINITY; dof];
    for p in train {
        p.log.rows(p.raw_keep.0, p.raw_keep.1, |row| {
            for j in 0..dof {
                let q = row[1 + j];
                lo[j] = lo[j].min(q);
                hi[j] = hi[j].max(q);
            }
        });
    }
    let mut out = Vec::new();
    for j in 0..dof {
        let prismatic = table
            .and_then(|t| t.joints.get(j))
            .is_some_and(|jt| jt.kind == JointKind::Prismatic);
        let (limit, unit, fix) = if prismatic {
            (STILL_M, "m", "±0.05 m")
        } else {
            (STILL_RAD, "rad", "±0.5 rad")
        };
        let span = hi[j] - lo[j];
        if span.is_finite() && span < limit {
            out.push(format!(
                "joint {} barely moves in the training data (it spans {span:.2e} {unit}; at least {limit} {unit} is needed): what acts through its motion — its inertia, friction and rotor terms, and how its gravity load changes with its position — cannot be identified, and the fit attributes its torque to the other parameters. Record a trajectory that moves joint {} through at least {fix} with changing velocity.",
                j + 1,
                j + 1
            ));
        }
    }
    out
}
