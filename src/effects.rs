//! Effects beyond the rigid body, each one regressor column per joint (the identification's
//! selection loop searches them).
//!
//! | effect | column for joint j | coefficient unit (revolute) |
//! |---|---|---|
//! | `viscous` | `q̇ⱼ` | N·m·s/rad |
//! | `coulomb` | `tanh(q̇ⱼ / vⱼ)`, `vⱼ` = 1 % of the RMS of q̇ⱼ (a sign that is smooth near rest) | N·m |
//! | `stribeck` | `tanh(q̇ⱼ / vⱼ) · exp(−(q̇ⱼ / sⱼ)²)`, `sⱼ` = 10 % of the RMS of q̇ⱼ (extra breakaway friction at low speed) | N·m |
//! | `offset` | `1` | N·m |
//! | `armature` | `q̈ⱼ` (rotor inertia reflected through the gear) | kg·m² |
//! | `spring` | `qⱼ` (linear spring; its rest angle appears as an offset) | N·m/rad |
//! | `loadcoulomb` | `tanh(q̇ⱼ / vⱼ) · |τ̂ⱼ|`, τ̂ⱼ the rigid-body torque of joint j (load-dependent friction: a gear's friction grows with the torque it transmits) | N·m per N·m |
//!
//! `loadcoulomb` is bilinear (its column holds the rigid-body parameters), so it is fitted in two
//! stages: τ̂ comes from the rigid-body part of the model selected without it, held fixed; the
//! column is then filtered and tested like any other ([`Effect::LOADED`] are searched after the
//! rest, in the identification's second stage).
//!
//! Asymmetric Coulomb friction (`Fc⁺` for q̇ > 0, `Fc⁻` for q̇ < 0) is `coulomb` + `offset` in
//! disguise: `Fc⁺·[q̇>0] − Fc⁻·[q̇<0] = ½(Fc⁺+Fc⁻)·sgn q̇ + ½(Fc⁺−Fc⁻)`, so the report derives it
//! when both are found instead of adding a redundant column. More effects: add a variant, its
//! column in [`Effect::column`] and its name.
//!
//! **Identifiability.** An effect column that lies in the span of the base regressor for *every*
//! motion is merged with rigid-body parameters and never reported as found: the armature of a
//! revolute first joint about a fixed axis is exactly the `ZZR1` column (`τ₁ += Ia₁·q̈₁`), so
//! `ZZR1` absorbs it ([`structural_merges`] detects this numerically for any arm). Columns that
//! are collinear only in the given data are skipped with a note.

use serde::Serialize;

/// One kind of effect (one column per joint).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    Viscous,
    Coulomb,
    Stribeck,
    Offset,
    Armature,
    Spring,
    #[serde(rename = "loadcoulomb")]
    LoadCoulomb,
}

impl Effect {
    /// Every effect, in the order candidates are listed.
    pub const ALL: [Effect; 6] = [
        Effect::Viscous,
        Effect::Coulomb,
        Effect::Stribeck,
        Effect::Offset,
        Effect::Armature,
        Effect::Spring,
    ];

    /// Effects whose column needs the rigid-body torque of a first-stage fit: searched after
    /// [`Effect::ALL`], with that fit's parameters.
    pub const LOADED: [Effect; 1] = [Effect::LoadCoulomb];

    /// Whether the column needs the rigid-body torque (see [`Effect::LOADED`]).
    pub fn needs_load(self) -> bool {
        Effect::LOADED.contains(&self)
    }

    /// Every effect, by name.
    pub fn named() -> impl Iterator<Item = Effect> {
        Effect::ALL.into_iter().chain(Effect::LOADED)
    }

    pub fn name(self) -> &'static str {
        match self {
            Effect::Viscous => "viscous",
            Effect::Coulomb => "coulomb",
            Effect::Stribeck => "stribeck",
            Effect::Offset => "offset",
            Effect::Armature => "armature",
            Effect::Spring => "spring",
            Effect::LoadCoulomb => "loadcoulomb",
        }
    }

    /// Parses a name as used on the command line.
    pub fn parse(s: &str) -> Option<Effect> {
        Effect::named().find(|e| e.name() == s.trim().to_ascii_lowercase())
    }

    /// Unit of the coefficient for a revolute joint.
    pub fn unit(self) -> &'static str {
        match self {
            Effect::Viscous => "N·m·s/rad",
            Effect::Coulomb | Effect::Stribeck | Effect::Offset => "N·m",
            Effect::Armature => "kg·m²",
            Effect::Spring => "N·m/rad",
            Effect::LoadCoulomb => "N·m/N·m",
        }
    }

    /// The regressor column of this effect for one joint's state; `load` is the joint's
    /// rigid-body torque (used by [`Effect::LOADED`] only).
    pub fn column(self, q: f64, dq: f64, ddq: f64, load: f64, s: &Scales) -> f64 {
        match self {
            Effect::Viscous => dq,
            Effect::Coulomb => (dq / s.coulomb_v).tanh(),
            Effect::Stribeck => (dq / s.coulomb_v).tanh() * (-(dq / s.stribeck_v).powi(2)).exp(),
            Effect::Offset => 1.0,
            Effect::Armature => ddq,
            Effect::Spring => q,
            Effect::LoadCoulomb => (dq / s.coulomb_v).tanh() * load.abs(),
        }
    }
}

/// Velocity scales of one joint's friction columns (fixed from the training data, reused for
/// validation so the model is the same function everywhere).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Scales {
    /// Smoothing velocity of the Coulomb sign.
    pub coulomb_v: f64,
    /// Stribeck velocity.
    pub stribeck_v: f64,
}

impl Scales {
    /// From the RMS joint velocity of the training data.
    pub fn from_rms_velocity(rms: f64) -> Self {
        let rms = if rms.is_finite() && rms > 0.0 {
            rms
        } else {
            1.0
        };
        Scales {
            coulomb_v: 0.01 * rms,
            stribeck_v: 0.1 * rms,
        }
    }
}

/// An effect on one joint (0-based joint index).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct Term {
    pub effect: Effect,
    pub joint: usize,
}

impl Term {
    /// `coulomb2` (joints count from 1 for people).
    pub fn label(&self) -> String {
        format!("{}{}", self.effect.name(), self.joint + 1)
    }
}

/// Parses `--effects`: `auto`, `none`, or a comma list of `effect` (all joints) and
/// `effect:J` (joint J, from 1).
pub fn parse_list(spec: &str, dof: usize) -> Result<EffectsSpec, String> {
    let s = spec.trim();
    match s {
        "auto" => return Ok(EffectsSpec::Auto),
        "none" | "" => return Ok(EffectsSpec::Fixed(Vec::new())),
        _ => {}
    }
    let known = Effect::named()
        .map(|e| e.name())
        .collect::<Vec<_>>()
        .join(", ");
    let mut terms = Vec::new();
    for item in s.split(',') {
        let item = item.trim();
        let (name, joint) = match item.split_once(':') {
            Some((n, j)) => (n, Some(j)),
            None => (item, None),
        };
        let effect = Effect::parse(name).ok_or_else(|| {
            format!("--effects: unknown effect `{name}` — known: {known}; or `auto`, `none`")
        })?;
        match joint {
            None => terms.extend((0..dof).map(|joint| Term { effect, joint })),
            Some(j) => {
                let j: usize = j
                    .trim()
                    .parse()
                    .map_err(|_| format!("--effects: `{item}`: joint must be a number 1..{dof}"))?;
                if j == 0 || j > dof {
                    return Err(format!("--effects: `{item}`: joint must be 1..{dof}"));
                }
                terms.push(Term {
                    effect,
                    joint: j - 1,
                });
            }
        }
    }
    terms.sort();
    terms.dedup();
    Ok(EffectsSpec::Fixed(terms))
}

/// What `--effects` asked for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum EffectsSpec {
    /// Search with [`crate::identify::select`].
    Auto,
    /// Exactly these terms (possibly none).
    Fixed(Vec<Term>),
}

/// Candidates merged with rigid-body parameters for every motion, with the base parameters they
/// merge into. `base_rows(state, out)` fills the base regressor; `states` are random states.
pub fn structural_merges(
    terms: &[Term],
    nb: usize,
    dof: usize,
    states: &[[Vec<f64>; 3]],
    mut base_rows: impl FnMut(&[f64], &[f64], &[f64], &mut [f64]),
    names: &[String],
) -> Vec<(Term, Vec<String>)> {
    use nalgebra::{DMatrix, DVector};
    let rows = states.len() * dof;
    let mut a = DMatrix::zeros(rows, nb);
    let mut yb = vec![0.0; dof * nb];
    for (s, [q, dq, ddq]) in states.iter().enumerate() {
        base_rows(q, dq, ddq, &mut yb);
        for i in 0..dof {
            for k in 0..nb {
                a[(s * dof + i, k)] = yb[i * nb + k];
            }
        }
    }
    let unit = Scales {
        coulomb_v: 1.0,
        stribeck_v: 1.0,
    };
    let svd = a.clone().svd(true, true);
    let mut out = Vec::new();
    for &t in terms {
        let c = DVector::from_fn(rows, |r, _| {
            let (s, i) = (r / dof, r % dof);
            if i == t.joint {
                let [q, dq, ddq] = &states[s];
                t.effect.column(q[i], dq[i], ddq[i], 1.0, &unit)
            } else {
                0.0
            }
        });
        let Ok(k) = svd.solve(&c, 1e-12) else {
            continue;
        };
        let resid = (&c - &a * &k).norm();
        if resid < 1e-7 * c.norm().max(1e-300) {
            let kmax = k.amax();
            let with = (0..nb)
                .filter(|&i| k[i].abs() > 1e-6 * kmax)
                .map(|i| names[i].clone())
                .collect();
            out.push((t, with));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn effects_list_parses_all_joint_and_single_joint_forms() {
        let spec = parse_list("viscous, coulomb:2", 2).unwrap();
        assert_eq!(
            spec,
            EffectsSpec::Fixed(vec![
                Term {
                    effect: Effect::Viscous,
                    joint: 0
                },
                Term {
                    effect: Effect::Viscous,
                    joint: 1
                },
                Term {
                    effect: Effect::Coulomb,
                    joint: 1
                },
            ])
        );
        assert_eq!(parse_list("auto", 3).unwrap(), EffectsSpec::Auto);
        assert_eq!(parse_list("none", 3).unwrap(), EffectsSpec::Fixed(vec![]));
        assert!(parse_list("viscus", 2)
            .unwrap_err()
            .contains("unknown effect `viscus`"));
        assert!(parse_list("coulomb:3", 2)
            .unwrap_err()
            .contains("joint must be 1..2"));
    }

    #[test]
    fn coulomb_column_is_a_smoothed_sign() {
        let s = Scales::from_rms_velocity(1.0);
        assert!((Effect::Coulomb.column(0.0, 0.5, 0.0, 0.0, &s) - 1.0).abs() < 1e-12);
        assert!((Effect::Coulomb.column(0.0, -0.5, 0.0, 0.0, &s) + 1.0).abs() < 1e-12);
        assert_eq!(Effect::Coulomb.column(0.0, 0.0, 0.0, 0.0, &s), 0.0);
        assert!(Effect::Stribeck.column(0.0, 1.0, 0.0, 0.0, &s).abs() < 1e-30);
    }
}
