//! The streaming identification benchmark: a long PUMA 560 log made on the fly (a sum-of-sines
//! excitation), lane-batched inverse dynamics and base regressor, normal equations.

use super::*;

/// The excitation of the streaming identification: per joint a random 5-harmonic Fourier series
/// (Swevers et al.; not the [`crate::trajectory::fourier::Fourier`] trajectory type), fundamental
/// 0.1 Hz, with closed-form velocity and acceleration evaluated by an angle-addition recurrence.
#[derive(Debug, Clone)]
pub struct BenchExcitation {
    omega: f64,
    q0: Vec<f64>,
    /// Per harmonic `l`, per joint: `(a_l, b_l)` of `q̇ = Σ a_l sin(lωt) + b_l cos(lωt)`.
    a: [Vec<f64>; 5],
    b: [Vec<f64>; 5],
}

impl BenchExcitation {
    const HARMONICS: usize = 5;

    /// Random coefficients (deterministic for a seed) giving joint excursions of about ±1.5 rad.
    pub fn random(dof: usize, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let omega = 2.0 * std::f64::consts::PI * 0.1;
        let q0 = (0..dof).map(|_| rng.gen_range(-0.5..0.5)).collect();
        let mut a: [Vec<f64>; 5] = Default::default();
        let mut b: [Vec<f64>; 5] = Default::default();
        for _ in 0..dof {
            for l in 0..Self::HARMONICS {
                let s = 0.3 * omega * (l + 1) as f64;
                a[l].push(rng.gen_range(-s..s));
                b[l].push(rng.gen_range(-s..s));
            }
        }
        BenchExcitation { omega, q0, a, b }
    }

    /// `q, q̇, q̈` at time `t`.
    #[inline]
    pub fn eval(&self, t: f64, q: &mut [f64], dq: &mut [f64], ddq: &mut [f64]) {
        // sin/cos of the harmonics by the angle-addition recurrence from the fundamental.
        let (s1, c1) = crate::trig::sin_cos(self.omega * t);
        let (mut s, mut c) = (s1, c1);
        q.copy_from_slice(&self.q0);
        dq.fill(0.0);
        ddq.fill(0.0);
        for l in 0..Self::HARMONICS {
            let w = self.omega * (l + 1) as f64;
            let inv_w = 1.0 / w;
            for (j, (&a, &b)) in self.a[l].iter().zip(&self.b[l]).enumerate() {
                let (sa, cb) = (a * s + b * c, a * c - b * s);
                q[j] -= cb * inv_w;
                dq[j] += sa;
                ddq[j] += cb * w;
            }
            (s, c) = (s * c1 + c * s1, c * c1 - s * s1);
        }
    }
}

/// A tiny, fast generator for measurement noise (SplitMix64; not for anything cryptographic).
struct SplitMix64(u64);

impl SplitMix64 {
    /// Uniform in [0, 1).
    #[inline]
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// Outcome of [`identify_streaming`].
#[derive(Debug, Clone)]
pub struct IdentifyRun {
    pub timing: IdentifyTiming,
    pub solution: Solution,
    /// Largest `|θ̂ − θ| / max(|θ|, 1e-3·max|θ|)` over the base parameters.
    pub max_rel_error: f64,
}

/// Streaming identification of a generated log: `samples` samples at 1 kHz along a
/// [`BenchExcitation`]; torques from the generated inverse dynamics plus uniform noise of
/// ±`noise` N·m; base regressor and [`NormalEquations`] per sample, nothing stored per sample;
/// one thread.
///
/// Normal equations rather than the incremental QR of [`crate::identify::ls::Accumulator`]:
/// that one costs about 2.3 µs per PUMA sample (2.7 s for 10⁶), this about 0.3 µs. Squaring the
/// condition number is harmless here — the column-scaled regressor has cond ≈ 16 on this
/// excitation — and [`NormalEquations::solve`] refuses anything above 10⁸.
pub fn identify_streaming(
    arm: &dyn Model,
    samples: usize,
    noise: f64,
) -> Result<IdentifyRun, BenchError> {
    let (n, nb) = (arm.dof(), arm.nb());
    let p = plausible_params(n, 11);
    let mut theta = vec![0.0; nb];
    arm.base_params(&p, &mut theta);
    let traj = BenchExcitation::random(n, 5);
    let mut rng = SplitMix64(9);
    let t0 = Instant::now();
    let mut ne = NormalEquations::new(nb, NormalEquations::row_starts(arm));
    let (mut q, mut dq, mut ddq, mut tau) =
        (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut yb = vec![0.0; n * nb];
    // Four samples per kernel call (crate::pack), in sample order; the tail one by one.
    let theta_p: Vec<Pack> = theta.iter().map(|&t| Pack::splat(t)).collect();
    let (mut qp, mut dqp, mut ddqp) = (
        vec![Pack::default(); n],
        vec![Pack::default(); n],
        vec![Pack::default(); n],
    );
    let (mut taup, mut ybp) = (vec![Pack::default(); n], vec![Pack::default(); n * nb]);
    let (mut qs, mut dqs, mut ddqs) = (
        vec![vec![0.0; n]; LANES],
        vec![vec![0.0; n]; LANES],
        vec![vec![0.0; n]; LANES],
    );
    let full = samples / LANES * LANES;
    for k0 in (0..full).step_by(LANES) {
        for l in 0..LANES {
            traj.eval(
                (k0 + l) as f64 * 1e-3,
                &mut qs[l],
                &mut dqs[l],
                &mut ddqs[l],
            );
        }
        gather(std::array::from_fn(|l| &qs[l][..]), &mut qp);
        gather(std::array::from_fn(|l| &dqs[l][..]), &mut dqp);
        gather(std::array::from_fn(|l| &ddqs[l][..]), &mut ddqp);
        arm.inverse_dynamics_lanes(&qp, &dqp, &ddqp, &theta_p, &mut taup);
        arm.base_regressor_lanes(&qp, &dqp, &ddqp, &mut ybp);
        for l in 0..LANES {
            crate::pack::lane(&taup, l, &mut tau);
            for t in tau.iter_mut() {
                *t += noise * (2.0 * rng.uniform() - 1.0);
            }
            crate::pack::lane(&ybp, l, &mut yb);
            ne.add(&yb, &tau);
        }
    }
    for k in full..samples {
        traj.eval(k as f64 * 1e-3, &mut q, &mut dq, &mut ddq);
        arm.inverse_dynamics(&q, &dq, &ddq, &theta, &mut tau);
        for t in tau.iter_mut() {
            *t += noise * (2.0 * rng.uniform() - 1.0);
        }
        arm.base_regressor(&q, &dq, &ddq, &mut yb);
        ne.add(&yb, &tau);
    }
    let solution = ne.solve(1e8)?;
    let seconds = t0.elapsed().as_secs_f64();
    let big = theta.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let max_rel_error = solution.theta.iter().zip(&theta).fold(0.0f64, |m, (a, b)| {
        m.max((a - b).abs() / b.abs().max(1e-3 * big))
    });
    let timing = IdentifyTiming {
        arm: arm.name().to_string(),
        samples,
        seconds,
        peak_rss_mb: peak_rss_mb(),
    };
    Ok(IdentifyRun {
        timing,
        solution,
        max_rel_error,
    })
}
