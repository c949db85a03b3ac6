//! Synthetic identification data with a known answer: inverse dynamics of the reference RNEA
//! along a sum-of-sines (Fourier) trajectory, plus chosen effects, plus measurement noise
//! (Gaussian torque noise relative to each joint's RMS torque, encoder quantisation of q).
//! Tests use it as the oracle: the true base parameters are `base_params(p)` and the true effect
//! coefficients are the ones put in.
//!
//! ```
//! use dynid::identify::synth::{Spec, generate};
//! let arm = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/arms/planar2.toml")).unwrap();
//! let table = dynid::dh::DhTable::from_str(&arm, "planar2.toml").unwrap();
//! let spec = Spec::new(table, 1);
//! let data = generate(&spec);
//! assert_eq!(data.dof, 2);
//! assert!(data.tau.is_some() && data.dq.is_none());
//! ```

use std::f64::consts::PI;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::data::Trajectory;
use crate::dh::{DhTable, JointKind};
use crate::effects::{self, Effect, JointState, Scales, Term};
use crate::measurement::add_measurement_noise;
use crate::reference::RefModel;

/// What to simulate.
#[derive(Debug, Clone)]
pub struct Spec {
    pub table: DhTable,
    /// Full inertial parameters (10 per link, about the link frames).
    pub p: Vec<f64>,
    /// Effects and their true coefficients. Coulomb is the exact `sgn(q̇)`; Stribeck is
    /// `sgn(q̇)·exp(−(q̇/0.1)²)`; the others are their columns in [`crate::effects`].
    pub effects: Vec<(Term, f64)>,
    pub duration: f64,
    pub rate_hz: f64,
    /// Fundamental of the Fourier trajectory (Hz) and number of harmonics.
    pub base_hz: f64,
    pub harmonics: usize,
    /// Torque noise standard deviation as a fraction of each joint's RMS torque.
    pub tau_noise: f64,
    /// Encoder resolution (rad or m); `None` = exact positions.
    pub q_resolution: Option<f64>,
    /// Write exact q̇, q̈ columns (otherwise only t, q, τ).
    pub with_derivatives: bool,
    /// Random sample-time jitter as a fraction of the step (0 = uniform).
    pub jitter: f64,
    /// Joints held still (at a constant position) during the motion.
    pub still: Vec<usize>,
    /// The plant's friction scales per joint (a smoothed Coulomb sign); empty = [`Scales::EXACT`].
    pub plant_scales: Vec<Scales>,
    pub seed: u64,
}

impl Spec {
    /// Defaults: random plausible parameters, no effects, 30 s at 500 Hz, 0.1 Hz × 5 harmonics,
    /// 1 % torque noise, a 2^17-count encoder.
    pub fn new(table: DhTable, seed: u64) -> Self {
        let p = random_params(&table, seed);
        Spec {
            table,
            p,
            effects: Vec::new(),
            duration: 30.0,
            rate_hz: 500.0,
            base_hz: 0.1,
            harmonics: 5,
            tau_noise: 0.01,
            q_resolution: Some(2.0 * PI / 131072.0),
            with_derivatives: false,
            jitter: 0.0,
            still: Vec::new(),
            plant_scales: Vec::new(),
            seed,
        }
    }

    pub fn with_effect(mut self, effect: Effect, joint: usize, value: f64) -> Self {
        self.effects.push((Term::new(effect, joint), value));
        self
    }
}

/// Physically plausible random link parameters: mass 0.5–3 kg, centre of mass within 0.3 m of
/// the frame origin, principal central inertias 0.01–0.02·m kg·m² (triangle inequality holds),
/// randomly rotated; converted to the link frame origin.
pub fn random_params(table: &DhTable, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
    let mut p = Vec::with_capacity(10 * table.dof());
    for _ in 0..table.dof() {
        let m: f64 = rng.gen_range(0.5..3.0);
        let c = nalgebra::Vector3::new(
            rng.gen_range(-0.3..0.3),
            rng.gen_range(-0.3..0.3),
            rng.gen_range(-0.3..0.3),
        );
        let d = nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(
            m * rng.gen_range(0.01..0.02),
            m * rng.gen_range(0.01..0.02),
            m * rng.gen_range(0.01..0.02),
        ));
        let axis = nalgebra::Vector3::new(
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
        );
        let rot = nalgebra::Rotation3::new(axis * rng.gen_range(0.0..PI) / axis.norm().max(1e-9));
        let ic = rot.matrix() * d * rot.matrix().transpose();
        let io: nalgebra::Matrix3<f64> =
            ic + m * (nalgebra::Matrix3::<f64>::identity() * c.norm_squared() - c * c.transpose());
        p.extend([
            io[(0, 0)],
            io[(0, 1)],
            io[(0, 2)],
            io[(1, 1)],
            io[(1, 2)],
            io[(2, 2)],
            m * c.x,
            m * c.y,
            m * c.z,
            m,
        ]);
    }
    p
}

/// The excitation of the synthetic data: per joint a random-coefficient Fourier series
/// (not the [`crate::trajectory::fourier::Fourier`] trajectory type),
/// `qⱼ(t) = q0ⱼ + Σₗ aⱼₗ/(ωl)·sin(ωlt) − bⱼₗ/(ωl)·cos(ωlt)`.
#[derive(Debug, Clone)]
pub struct SynthExcitation {
    pub w: f64,
    pub q0: Vec<f64>,
    pub a: Vec<Vec<f64>>,
    pub b: Vec<Vec<f64>>,
}

impl SynthExcitation {
    /// Random coefficients, scaled so each joint's peak excursion is about `range[j]`.
    pub fn random(range: &[f64], base_hz: f64, harmonics: usize, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xf0_u64);
        let w = 2.0 * PI * base_hz;
        let n = range.len();
        let mut f = SynthExcitation {
            w,
            q0: vec![0.0; n],
            a: Vec::new(),
            b: Vec::new(),
        };
        for &r in range {
            let a: Vec<f64> = (0..harmonics).map(|_| rng.gen_range(-1.0..1.0)).collect();
            let b: Vec<f64> = (0..harmonics).map(|_| rng.gen_range(-1.0..1.0)).collect();
            f.a.push(a);
            f.b.push(b);
            let _ = r;
        }
        // Scale to the requested excursion.
        #[allow(clippy::needless_range_loop)]
        for j in 0..n {
            let peak = (0..400)
                .map(|k| f.eval(j, k as f64 / 400.0 * 2.0 * PI / w).0.abs())
                .fold(0.0, f64::max)
                .max(1e-9);
            let s = range[j] / peak;
            f.a[j].iter_mut().for_each(|v| *v *= s);
            f.b[j].iter_mut().for_each(|v| *v *= s);
            f.q0[j] = rng.gen_range(-0.2..0.2) * range[j];
        }
        f
    }

    /// `(q, q̇, q̈)` of joint `j` at `t`.
    pub fn eval(&self, j: usize, t: f64) -> (f64, f64, f64) {
        let (mut q, mut dq, mut ddq) = (self.q0[j], 0.0, 0.0);
        for (l, (a, b)) in self.a[j].iter().zip(&self.b[j]).enumerate() {
            let wl = self.w * (l + 1) as f64;
            let (s, c) = (wl * t).sin_cos();
            q += a / wl * s - b / wl * c;
            dq += a * c + b * s;
            ddq += -a * wl * s + b * wl * c;
        }
        (q, dq, ddq)
    }
}

/// Simulates `spec` (see the module docs).
pub fn generate(spec: &Spec) -> Trajectory {
    let table = &spec.table;
    let n = table.dof();
    let model = RefModel::new(table);
    let mut ws = model.workspace();
    let range: Vec<f64> = table
        .joints
        .iter()
        .enumerate()
        .map(|(i, j)| {
            if spec.still.contains(&i) {
                0.0
            } else if j.kind == JointKind::Revolute {
                1.5
            } else {
                0.2
            }
        })
        .collect();
    let traj = SynthExcitation::random(&range, spec.base_hz, spec.harmonics, spec.seed);
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed ^ 0x0007_015e);
    let len = (spec.duration * spec.rate_hz).round() as usize;
    let dt = 1.0 / spec.rate_hz;
    let mut t = Vec::with_capacity(len);
    let (mut q, mut dq, mut ddq, mut tau) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut tk = 0.0;
    let (mut qs, mut dqs, mut ddqs, mut ts) =
        (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for _ in 0..len {
        t.push(tk);
        for j in 0..n {
            (qs[j], dqs[j], ddqs[j]) = traj.eval(j, tk);
        }
        model.inverse_dynamics(&mut ws, &qs, &dqs, &ddqs, &spec.p, &mut ts);
        // Additive effects first; load-dependent friction scales the torque they leave
        // (rigid body + other effects), as `dynid simulate` does.
        for (term, v) in &spec.effects {
            let j = term.joint;
            if !term.effect.needs_load() {
                let sc = spec.plant_scales.get(j).unwrap_or(&Scales::EXACT);
                let st = JointState::new(qs[j], dqs[j], ddqs[j], sc).at(tk);
                ts[j] += v * term.column_at(&st, 0.0);
            }
        }
        for (term, v) in spec.effects.iter().filter(|(t, _)| t.effect.needs_load()) {
            let j = term.joint;
            ts[j] = effects::load(*v, dqs[j], ts[j], &Scales::EXACT);
        }
        q.extend_from_slice(&qs);
        dq.extend_from_slice(&dqs);
        ddq.extend_from_slice(&ddqs);
        tau.extend_from_slice(&ts);
        tk += dt * (1.0 + spec.jitter * rng.gen_range(-1.0..1.0));
    }
    let resolution = spec.q_resolution.map(|r| vec![r; n]);
    add_measurement_noise(
        n,
        &mut q,
        &mut tau,
        spec.tau_noise,
        resolution.as_deref(),
        &mut rng,
    );
    Trajectory {
        source: format!("synthetic:{}:seed{}", table.name, spec.seed),
        dof: n,
        t,
        q,
        dq: spec.with_derivatives.then_some(dq),
        ddq: spec.with_derivatives.then_some(ddq),
        tau: Some(tau),
    }
}
