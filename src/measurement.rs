//! Measurement noise of simulated logs: white Gaussian torque noise relative to each joint's RMS
//! torque and encoder quantisation of the positions. One place for the synthetic identification
//! data ([`crate::identify::synth`]), `dynid simulate` and the paper's noise study
//! ([`crate::paper::noise`]).

use std::f64::consts::PI;

use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// Gaussian samples (Box–Muller).
pub fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = rng.gen_range(f64::EPSILON..1.0);
    let u2: f64 = rng.gen_range(0.0..1.0);
    (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
}

/// Measurement noise on a row-major log of `n` joints (`q[k·n + j]`): white Gaussian torque noise
/// of `tau_noise` × each joint's RMS torque, then positions rounded to `resolution[j]` (an
/// encoder's step, rad or m). Used by [`crate::identify::synth::generate`] and `dynid simulate`.
pub fn add_measurement_noise(
    n: usize,
    q: &mut [f64],
    tau: &mut [f64],
    tau_noise: f64,
    resolution: Option<&[f64]>,
    rng: &mut ChaCha8Rng,
) {
    let len = tau.len() / n.max(1);
    for j in 0..n {
        let rms =
            ((0..len).map(|k| tau[k * n + j].powi(2)).sum::<f64>() / len.max(1) as f64).sqrt();
        for k in 0..len {
            tau[k * n + j] += tau_noise * rms * gauss(rng);
        }
    }
    if let Some(res) = resolution {
        for (i, v) in q.iter_mut().enumerate() {
            *v = (*v / res[i % n]).round() * res[i % n];
        }
    }
}

/// Rounds every position of a row-major log of `q.len() / zero.len()` samples to the grid
/// `zero[j] + i·lsb` of an encoder with step `lsb` and zero offset `zero[j]` for joint `j`.
pub fn quantise_with_zero(q: &mut [f64], lsb: f64, zero: &[f64]) {
    let n = zero.len();
    for (k, v) in q.iter_mut().enumerate() {
        let z = zero[k % n];
        *v = ((*v + z) / lsb).round() * lsb - z;
    }
}
