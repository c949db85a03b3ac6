//! The one implementation of each effect's physics: the torque a unit coefficient adds at one
//! joint. It is the identification's regressor column (with the training data's smoothing
//! [`Scales`]) and the simulated plant's effect torque (with [`Scales::EXACT`]: an exact sign).

use serde::Serialize;

use super::{Effect, Term};

/// Velocity scales of one joint's friction columns (fixed from the training data, reused for
/// validation so the model is the same function everywhere).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Scales {
    /// Smoothing velocity of the Coulomb sign, `tanh(q̇ / v)`; `0` is the exact sign.
    pub coulomb_v: f64,
    /// Stribeck velocity.
    pub stribeck_v: f64,
    /// Wavenumber of the position ripple columns (rad⁻¹ or m⁻¹; `sin(k·q)`, `cos(k·q)`); 0 when
    /// the joint has none.
    pub ripple_k: f64,
    /// Velocity unit `u` of the friction spline's columns ([`super::spline::velocity_unit`]).
    pub spline_v: f64,
}

impl Scales {
    /// The plant's friction: an exact sign (`sign(0) = 0`) and a Stribeck velocity of 0.1 (rad/s
    /// or m/s).
    pub const EXACT: Scales = Scales {
        coulomb_v: 0.0,
        stribeck_v: 0.1,
        ripple_k: 0.0,
        spline_v: 1.0,
    };

    /// The default Coulomb smoothing velocity as a fraction of the RMS joint velocity.
    pub const COULOMB_FRACTION: f64 = 0.01;
    /// The Stribeck velocity as a fraction of the RMS joint velocity.
    pub const STRIBECK_FRACTION: f64 = 0.1;

    /// From the RMS joint velocity of the training data: `v` = 1 %, Stribeck velocity = 10 % of it
    /// (the spline's unit: the RMS velocity until [`Scales::with_spline_unit`] sets it).
    pub fn from_rms_velocity(rms: f64) -> Self {
        let rms = if rms.is_finite() && rms > 0.0 {
            rms
        } else {
            1.0
        };
        Scales {
            coulomb_v: Self::COULOMB_FRACTION * rms,
            stribeck_v: Self::STRIBECK_FRACTION * rms,
            ripple_k: 0.0,
            spline_v: rms,
        }
    }

    /// The same scales with the Coulomb velocity `fraction` of the RMS velocity they were made
    /// from (read back from the Stribeck velocity).
    pub fn with_coulomb_fraction(&self, fraction: f64) -> Self {
        Scales {
            coulomb_v: fraction * self.stribeck_v / Self::STRIBECK_FRACTION,
            ..*self
        }
    }

    /// The same scales with the friction spline's velocity unit `u`.
    pub fn with_spline_unit(&self, u: f64) -> Self {
        Scales {
            spline_v: u,
            ..*self
        }
    }

    /// The same scales with ripple wavenumber `k`.
    pub fn with_ripple(&self, k: f64) -> Self {
        Scales {
            ripple_k: k,
            ..*self
        }
    }

    /// The (smoothed) sign of the velocity: `tanh(q̇ / v)`, or `sign(q̇)` when `v = 0`.
    pub fn sign(&self, dq: f64) -> f64 {
        if self.coulomb_v == 0.0 {
            sign(dq)
        } else {
            (dq / self.coulomb_v).tanh()
        }
    }
}

/// Which run a state belongs to, as the per-run columns ([`Effect::PER_RUN`]) read it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Run {
    /// Training run `index` (0-based, in the order of the training files).
    Training(usize),
    /// A run the model was not fitted on, with the number of training runs: its per-run
    /// columns are `1 / runs` each (the mean of the training runs' effects).
    Unseen { runs: usize },
}

impl Run {
    /// Training run `m`'s column of a per-run effect at a state of this run.
    pub fn indicator(self, m: usize) -> f64 {
        match self {
            Run::Training(r) => f64::from(u8::from(r == m)),
            Run::Unseen { runs } => 1.0 / runs.max(1) as f64,
        }
    }
}

/// One joint's state as its effect columns read it. The (smoothed) velocity sign is computed on
/// first use and shared by every column of the state (Coulomb, Stribeck, load-dependent).
#[derive(Debug, Clone)]
pub struct JointState {
    pub q: f64,
    pub dq: f64,
    pub ddq: f64,
    /// Time since the start of the run (s), read by `drift` only; 0 unless set ([`JointState::at`]).
    pub t: f64,
    /// The run, read by the per-run columns only; one unseen run of one unless set
    /// ([`JointState::in_run`]).
    pub run: Run,
    scales: Scales,
    sign: std::cell::Cell<Option<f64>>,
}

impl JointState {
    pub fn new(q: f64, dq: f64, ddq: f64, scales: &Scales) -> Self {
        JointState {
            q,
            dq,
            ddq,
            t: 0.0,
            run: Run::Unseen { runs: 1 },
            scales: *scales,
            sign: std::cell::Cell::new(None),
        }
    }

    /// The state at time `t` since the start of its run (s).
    pub fn at(mut self, t: f64) -> Self {
        self.t = t;
        self
    }

    /// The state in run `run`.
    pub fn in_run(mut self, run: Run) -> Self {
        self.run = run;
        self
    }

    /// The smoothed sign of the velocity ([`Scales::sign`]).
    pub fn sign(&self) -> f64 {
        match self.sign.get() {
            Some(s) => s,
            None => {
                let s = self.scales.sign(self.dq);
                self.sign.set(Some(s));
                s
            }
        }
    }
}

impl Effect {
    /// The torque one unit of this effect adds at a joint in state `(q, q̇, q̈)`, at the start of a
    /// run (`drift` is 0 there; [`Effect::column_at`] with [`JointState::at`] for later times):
    /// the regressor column. `load` is the joint's rigid-body torque (used by [`Effect::LOADED`]
    /// only; the plant's load-dependent friction is [`super::load`]).
    pub fn column(self, q: f64, dq: f64, ddq: f64, load: f64, s: &Scales) -> f64 {
        self.column_at(&JointState::new(q, dq, ddq, s), load)
    }

    /// [`Effect::column`] at a [`JointState`] that several columns share (a per-run effect's
    /// column is [`Term::column_at`]'s: this is run 0's).
    pub fn column_at(self, st: &JointState, load: f64) -> f64 {
        Term::new(self, 0).column_at(st, load)
    }
}

impl Term {
    /// The term's regressor column at joint state `st` ([`Effect::column_at`]; a per-run
    /// effect's is its run's indicator, [`Run::indicator`]).
    pub fn column_at(&self, st: &JointState, load: f64) -> f64 {
        match self.effect {
            Effect::Viscous => st.dq,
            Effect::Coulomb => st.sign(),
            Effect::Stribeck => st.sign() * (-(st.dq / st.scales.stribeck_v).powi(2)).exp(),
            Effect::Offset => 1.0,
            Effect::AsymCoulomb => st.sign().abs(),
            Effect::Armature => st.ddq,
            Effect::Spring => st.q,
            Effect::Drift => st.t,
            Effect::RippleSin => (st.scales.ripple_k * st.q).sin(),
            Effect::RippleCos => (st.scales.ripple_k * st.q).cos(),
            Effect::RunOffset => st.run.indicator(self.run),
            Effect::SplineA => super::spline::column(0, st.dq / st.scales.spline_v),
            Effect::SplineB => super::spline::column(1, st.dq / st.scales.spline_v),
            Effect::SplineC => super::spline::column(2, st.dq / st.scales.spline_v),
            Effect::LoadCoulomb => st.sign() * load.abs(),
        }
    }
}

/// `sign(x)` with `sign(0) = 0`.
pub fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}
