//! Effects beyond the rigid body, each one regressor column per joint (the identification's
//! selection loop searches them).
//!
//! | effect | column for joint j | coefficient unit (revolute) |
//! |---|---|---|
//! | `viscous` | `q̇ⱼ` | N·m·s/rad |
//! | `coulomb` | `tanh(q̇ⱼ / vⱼ)`, `vⱼ` = 1 % of the RMS of q̇ⱼ (a sign that is smooth near rest) | N·m |
//! | `stribeck` | `tanh(q̇ⱼ / vⱼ) · exp(−(q̇ⱼ / sⱼ)²)`, `sⱼ` = 10 % of the RMS of q̇ⱼ (extra breakaway friction at low speed) | N·m |
//! | `offset` | `1` | N·m |
//! | `asym_coulomb` | `|tanh(q̇ⱼ / vⱼ)|`, `vⱼ` as for `coulomb` (1 while the joint moves either way, 0 at rest: with `coulomb`, friction of different levels `Fc⁺`, `Fc⁻` in the two directions) | N·m |
//! | `armature` | `q̈ⱼ` (rotor inertia reflected through the gear) | kg·m² |
//! | `spring` | `qⱼ` (linear spring; its rest angle appears as an offset) | N·m/rad |
//! | `drift` | `t`, the time since the start of the run (slow thermal drift: a motor's and gear's friction and a torque sensor's zero change as they warm up, over minutes — nearly linear over one run) | N·m/s |
//! | `ripple_sin`, `ripple_cos` | `sin(kⱼ·qⱼ)`, `cos(kⱼ·qⱼ)`, `kⱼ` the joint's ripple wavenumber (rad⁻¹), found from the residual (position-dependent ripple: cogging, gear and sensor ripple; the pair is any phase) | N·m |
//! | `run_offset` | `1` in training run m, `0` in the other training runs, `1/R` in any other run (R training runs): one column per training run after the first (whose offset is `offset`'s), so an unseen run gets the mean of the runs' offsets (a torque sensor or current offset re-zeroed between runs) | N·m |
//! | `spline_a`, `spline_b`, `spline_c` | natural cubic spline columns in `q̇ⱼ / uⱼ`, `uⱼ` the 8-norm of q̇ⱼ (near its top speed), knots at 0, ±½, ±1 ([`spline`]; friction no closed form fits — with `viscous` and `offset` any natural cubic spline on those knots; the three are one unit) | N·m |
//! | `loadcoulomb` | `tanh(q̇ⱼ / vⱼ) · |τ̂ⱼ|`, τ̂ⱼ the rigid-body torque of joint j (load-dependent friction: a gear's friction grows with the torque it transmits) | N·m per N·m |
//!
//! `loadcoulomb` is bilinear (its column holds the rigid-body parameters), so it is fitted in two
//! stages: τ̂ comes from the rigid-body part of the model selected without it, held fixed; the
//! column is then filtered and tested like any other ([`Effect::LOADED`] are searched after the
//! rest, in the identification's second stage). The ripple pair's wavenumber is not linear either:
//! it is the peak of the periodogram of the residual against qⱼ of the model selected without
//! them ([`crate::identify::ripple`]), then the pair is tested like any other column.
//!
//! Asymmetric Coulomb friction (`Fc⁺` for q̇ > 0, `Fc⁻` for q̇ < 0) is `coulomb` + `asym_coulomb`:
//! `Fc⁺·[q̇>0] − Fc⁻·[q̇<0] = ½(Fc⁺+Fc⁻)·sgn q̇ + ½(Fc⁺−Fc⁻)·|sgn q̇|`. The second column is the
//! constant `offset` wherever the joint moves, so only data with rests tells them apart (on a
//! motion that never stops, either stands for the other). More effects: add a variant, its
//! column in [`Effect::column`] (`column.rs`: the one implementation of its physics, used by
//! identification, simulation and synthetic data) and its name.
//!
//! **Identifiability.** An effect column that lies in the span of the base regressor for *every*
//! motion is merged with rigid-body parameters and never reported as found: the armature of a
//! revolute first joint about a fixed axis is exactly the `ZZR1` column (`τ₁ += Ia₁·q̈₁`), so
//! `ZZR1` absorbs it ([`structural_merges`] detects this numerically for any arm). Columns that
//! are collinear only in the given data are skipped with a note.

use serde::Serialize;

mod column;
mod load;
mod merges;
pub mod spline;
#[cfg(test)]
mod tests;

pub use column::{sign, JointState, Run, Scales};
pub use load::{load, unload};
pub use merges::structural_merges;

/// One kind of effect (one column per joint).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    Viscous,
    Coulomb,
    Stribeck,
    Offset,
    AsymCoulomb,
    Armature,
    Spring,
    Drift,
    RippleSin,
    RippleCos,
    RunOffset,
    SplineA,
    SplineB,
    SplineC,
    #[serde(rename = "loadcoulomb")]
    LoadCoulomb,
}

impl Effect {
    /// Every effect, in the order candidates are listed.
    pub const ALL: [Effect; 8] = [
        Effect::Viscous,
        Effect::Coulomb,
        Effect::Stribeck,
        Effect::Offset,
        Effect::AsymCoulomb,
        Effect::Armature,
        Effect::Spring,
        Effect::Drift,
    ];

    /// Effects whose column needs the rigid-body torque of a first-stage fit: searched after
    /// [`Effect::ALL`], with that fit's parameters.
    pub const LOADED: [Effect; 1] = [Effect::LoadCoulomb];

    /// Position ripple, `sin(kⱼ·qⱼ)` and `cos(kⱼ·qⱼ)`: the wavenumber `kⱼ` comes from the
    /// residual of the model without them ([`crate::identify::ripple`]), so they are searched
    /// after [`Effect::ALL`], before [`Effect::LOADED`].
    pub const RIPPLE: [Effect; 2] = [Effect::RippleSin, Effect::RippleCos];

    /// A per-run offset: one column per training run after the first ([`Term::run`]), searched
    /// with [`Effect::ALL`] when there are two training runs or more.
    pub const PER_RUN: [Effect; 1] = [Effect::RunOffset];

    /// Friction as a spline in the velocity ([`spline`]): three columns per joint, searched as
    /// one unit after [`Effect::ALL`] and the ripple, before [`Effect::LOADED`]
    /// ([`crate::identify::friction_spline`]).
    pub const SPLINE: [Effect; spline::COLUMNS] =
        [Effect::SplineA, Effect::SplineB, Effect::SplineC];

    /// Share of a joint's training samples at rest below which `asym_coulomb` is not searched:
    /// its column then differs from `offset`'s only around velocity reversals (about 1 % of a
    /// smooth motion), so the data cannot tell the two apart.
    pub const ASYM_REST_MIN: f64 = 0.05;

    /// Whether `asym_coulomb` is searched on a joint at rest in share `at_rest` of the training
    /// samples ([`Effect::ASYM_REST_MIN`]).
    pub fn rests_enough(at_rest: f64) -> bool {
        at_rest >= Effect::ASYM_REST_MIN
    }

    /// Whether the effect has a column per training run (see [`Effect::PER_RUN`]).
    pub fn is_per_run(self) -> bool {
        Effect::PER_RUN.contains(&self)
    }

    /// Whether the column needs the joint's ripple wavenumber (see [`Effect::RIPPLE`]).
    pub fn is_ripple(self) -> bool {
        Effect::RIPPLE.contains(&self)
    }

    /// Whether the column is one of the friction spline's (see [`Effect::SPLINE`]).
    pub fn is_spline(self) -> bool {
        Effect::SPLINE.contains(&self)
    }

    /// Whether the column needs the rigid-body torque (see [`Effect::LOADED`]).
    pub fn needs_load(self) -> bool {
        Effect::LOADED.contains(&self)
    }

    /// Every effect, by name.
    pub fn named() -> impl Iterator<Item = Effect> {
        Effect::ALL
            .into_iter()
            .chain(Effect::RIPPLE)
            .chain(Effect::PER_RUN)
            .chain(Effect::SPLINE)
            .chain(Effect::LOADED)
    }

    pub fn name(self) -> &'static str {
        match self {
            Effect::Viscous => "viscous",
            Effect::Coulomb => "coulomb",
            Effect::Stribeck => "stribeck",
            Effect::Offset => "offset",
            Effect::AsymCoulomb => "asym_coulomb",
            Effect::Armature => "armature",
            Effect::Spring => "spring",
            Effect::Drift => "drift",
            Effect::RippleSin => "ripple_sin",
            Effect::RippleCos => "ripple_cos",
            Effect::RunOffset => "run_offset",
            Effect::SplineA => "spline_a",
            Effect::SplineB => "spline_b",
            Effect::SplineC => "spline_c",
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
            Effect::Coulomb
            | Effect::Stribeck
            | Effect::Offset
            | Effect::AsymCoulomb
            | Effect::RippleSin
            | Effect::RippleCos
            | Effect::RunOffset
            | Effect::SplineA
            | Effect::SplineB
            | Effect::SplineC => "N·m",
            Effect::Armature => "kg·m²",
            Effect::Spring => "N·m/rad",
            Effect::Drift => "N·m/s",
            Effect::LoadCoulomb => "N·m/N·m",
        }
    }
}

/// An effect on one joint (0-based joint index).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct Term {
    pub effect: Effect,
    pub joint: usize,
    /// For a per-run effect ([`Effect::PER_RUN`]): the training run (0-based, in the order the
    /// files were given) whose column this is, from 1 (run 0's is the effect without runs); 0
    /// in a declared list means every run. 0 for every other effect.
    #[serde(skip_serializing_if = "is_zero")]
    pub run: usize,
}

fn is_zero(r: &usize) -> bool {
    *r == 0
}

impl Term {
    /// `effect` on `joint` (not per run).
    pub fn new(effect: Effect, joint: usize) -> Term {
        Term {
            effect,
            joint,
            run: 0,
        }
    }

    /// `coulomb2` (joints count from 1 for people); `run_offset2@3` for training run 3's
    /// offset on joint 2.
    pub fn label(&self) -> String {
        match self.run {
            0 => format!("{}{}", self.effect.name(), self.joint + 1),
            r => format!("{}{}@{}", self.effect.name(), self.joint + 1, r + 1),
        }
    }
}

/// Parses `--effects`: `auto`, `none`, or a comma list of `effect` (all joints) and
/// `effect:J` (joint J, from 1); a per-run effect also `effect:J@R` (training run R's column only,
/// R from 2; without `@R`, every run's).
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
        // `ripple` is the pair (any phase), `spline` the friction spline's three columns.
        let effects: Vec<Effect> = if name.trim().eq_ignore_ascii_case("ripple") {
            Effect::RIPPLE.to_vec()
        } else if name.trim().eq_ignore_ascii_case("spline") {
            Effect::SPLINE.to_vec()
        } else {
            vec![Effect::parse(name).ok_or_else(|| {
                format!("--effects: unknown effect `{name}` — known: {known}, ripple (the pair), spline (its three columns); or `auto`, `none`")
            })?]
        };
        for effect in effects {
            match joint {
                None => terms.extend((0..dof).map(|joint| Term::new(effect, joint))),
                Some(j) => {
                    // `run_offset:J@R`: training run R's column only.
                    let (j, run) = match j.split_once('@') {
                        Some((j, r)) => (j, Some(r)),
                        None => (j, None),
                    };
                    let j: usize = j.trim().parse().map_err(|_| {
                        format!("--effects: `{item}`: joint must be a number 1..{dof}")
                    })?;
                    if j == 0 || j > dof {
                        return Err(format!("--effects: `{item}`: joint must be 1..{dof}"));
                    }
                    let run = match run {
                        None => 0,
                        Some(r) => parse_run(item, effect, r)?,
                    };
                    terms.push(Term {
                        run,
                        ..Term::new(effect, j - 1)
                    });
                }
            }
        }
    }
    terms.sort();
    terms.dedup();
    Ok(EffectsSpec::Fixed(terms))
}

/// The `R` of `effect:J@R` as a 0-based run index (≥ 1: run 1's offset is the effect without
/// runs).
fn parse_run(item: &str, effect: Effect, r: &str) -> Result<usize, String> {
    if !effect.is_per_run() {
        return Err(format!(
            "--effects: `{item}`: `@R` (a training run) is for per-run effects only (run_offset)"
        ));
    }
    match r.trim().parse::<usize>() {
        Ok(r) if r >= 2 => Ok(r - 1),
        Ok(1) => Err(format!(
            "--effects: `{item}`: run 1's offset is `offset` (per-run offsets are runs 2.. over run 1's)"
        )),
        _ => Err(format!(
            "--effects: `{item}`: the run must be a number from 2 (training files in the order given)"
        )),
    }
}

/// What `--effects` asked for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum EffectsSpec {
    /// Search with [`crate::identify::select`].
    Auto,
    /// Exactly these terms (possibly none).
    Fixed(Vec<Term>),
}
