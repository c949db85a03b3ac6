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

use serde::Serialize;

use super::problem::Problem;
use crate::dh::{DhTable, JointKind};

/// A parameter the training data leave free (see [`torque_sigma`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Undetermined {
    pub name: String,
    pub value: f64,
    pub std: f64,
    /// How far a one-σ change moves the prediction, in units of the fit's residual.
    pub torque_sigma: f64,
}

/// Least span of a revolute joint's position over the training data (rad): 0.05 rad ≈ 2.9°.
pub const STILL_RAD: f64 = 0.05;
/// Least span of a prismatic joint's position (m).
pub const STILL_M: f64 = 0.005;

/// Warnings about the training data, from each joint's least and greatest position over the
/// training files (`lo`, `hi`: [`super::extrapolation::ranges`]; joint kinds from `table`,
/// revolute without one).
pub fn warnings((lo, hi): (&[f64], &[f64]), table: Option<&DhTable>) -> Vec<String> {
    let mut out = Vec::new();
    for j in 0..lo.len() {
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

/// Least torque, in units of the fit's residual, by which a one-σ change of a parameter must
/// move the prediction for the data to count as determining it (see [`torque_sigma`]).
pub const UNDETERMINED_SIGMA: f64 = 1.0;

/// Per parameter of `subset` (its block-jackknife standard deviation `std`), how far a one-σ
/// change moves the weighted prediction — RMS over every regression row, in units of the
/// weighted residual's RMS (the weights are `1/σⱼ`, so that is 1): `σₖ·√(Nₖₖ/R)` with
/// `Nₖₖ = Σⱼ wⱼ²‖Yⱼₖ‖²` and `R` rows. Small when the parameter is pinned down, whatever its
/// value (a well-determined zero included); above [`UNDETERMINED_SIGMA`] the data leave it free
/// to trade torque with other parameters by more than the noise — fitted, not measured.
pub fn torque_sigma(problem: &Problem, subset: &[usize], w: &[f64], std: &[f64]) -> Vec<f64> {
    let (n, _) = problem.normal_equations(subset, w);
    let rows = problem.rows().max(1) as f64;
    (0..subset.len())
        .map(|k| std[k] * (n[(k, k)] / rows).sqrt())
        .collect()
}

/// One warning naming the parameters the data leave free (none: `None`), with what would fix it.
pub fn undetermined_warning(u: &[Undetermined]) -> Option<String> {
    if u.is_empty() {
        return None;
    }
    let names: Vec<String> = u
        .iter()
        .map(|p| {
            format!(
                "`{}` = {:.4e} ± {:.1e} (a one-σ change moves the prediction by {:.1}× the residual)",
                p.name, p.value, p.std, p.torque_sigma
            )
        })
        .collect();
    Some(format!(
        "the training data do not determine {}: {} — the fit trades torque between them and the parameters they are collinear with, so their values are not measurements (the prediction is). Record motion that moves the joints these parameters belong to through larger ranges with varied velocities and accelerations (an optimised excitation: `dynid excite`), or give the values you trust with `--prior` and read the physically consistent estimate.",
        if u.len() == 1 { "one parameter" } else { "these parameters" },
        names.join(", ")
    ))
}

/// One warning naming the base parameters held at zero because the training data cannot
/// determine them at all (their columns are combinations of the others), if any.
pub fn fixed_warning(fixed: &[String]) -> Option<String> {
    if fixed.is_empty() {
        return None;
    }
    let names: Vec<String> = fixed.iter().map(|n| format!("`{n}`")).collect();
    Some(format!(
        "the training data cannot identify {} (each column is a combination of the others in this data): held at 0 in the least-squares fit, not fitted — so that fit is no model of them, and the physically consistent estimate decides them from `--prior` (without one, from its weak pull towards zero). Record motion that moves the joints they belong to through wide ranges with changing velocity.",
        names.join(", ")
    ))
}
