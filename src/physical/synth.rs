//! Synthetic physically-consistent-identification problems with a known answer, sized like a
//! 7-DOF arm, for the tests and the benchmark.
//!
//! - Links: random solid boxes (mass 0.5–5 kg, centre of mass within ±0.2 m, sides 0.05–0.4 m);
//!   the last link is a thin rod (nearly on the boundary of the physical set).
//! - Base map `K` (49 × 70) with the regrouping pattern of a revolute chain: link 1 keeps only
//!   `ZZ1` (its other 9 parameters are unidentifiable: zero columns); each later link keeps
//!   `XX, XY, XZ, YZ, ZZ, MX, MY, MZ` and has `YY` and `M` regrouped — `YYₗ` into `XXₗ` (−1)
//!   and `ZZₗ₋₁` (+1), `Mₗ` into `XXₗ₋₁`, `ZZₗ₋₁` (`+dₗ²`) and `MZₗ₋₁` (`+dₗ`), `dₗ` a link
//!   length of 0.1–0.5 m.
//! - Effects per joint: viscous (≥ 0), Coulomb (≥ 0), load-dependent Coulomb (in `[0, 0.5]`);
//!   joint 3's Coulomb friction is truly 0, so noise can push its estimate below zero.
//! - `N = AᵀA` from a random regressor `A` (`rows × (49 + 21)`) whose columns have scales spread
//!   over three decades; `ŷ` is the least-squares estimate from torques `A·y + noise`.

use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::program::{ConsistentProblem, EffectBound};

/// Number of links and effects of the synthetic arm.
pub const LINKS: usize = 7;
pub const EFFECTS: usize = 21;

/// A generated problem and the truth it was made from.
#[derive(Debug, Clone)]
pub struct Synthetic {
    pub problem: ConsistentProblem,
    /// The true standard parameters (physically consistent).
    pub params: DVector<f64>,
    /// The true effect coefficients.
    pub effects: DVector<f64>,
}

fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    // Box–Muller.
    let u: f64 = rng.gen_range(f64::EPSILON..1.0);
    let v: f64 = rng.gen();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// A random solid box's standard parameters about the link origin.
fn random_link(rng: &mut ChaCha8Rng, thin: bool) -> [f64; 10] {
    let m: f64 = rng.gen_range(0.5..5.0);
    let c: [f64; 3] = std::array::from_fn(|_| rng.gen_range(-0.2..0.2));
    let mut s: [f64; 3] = std::array::from_fn(|_| rng.gen_range(0.05..0.4));
    if thin {
        s = [0.4, 0.002, 0.002];
    }
    let ic = |a: usize, b: usize| m / 12.0 * (s[a] * s[a] + s[b] * s[b]);
    let shift = |a: usize, b: usize| m * (c[a] * c[a] + c[b] * c[b]);
    [
        ic(1, 2) + shift(1, 2),
        -m * c[0] * c[1],
        -m * c[0] * c[2],
        ic(0, 2) + shift(0, 2),
        -m * c[1] * c[2],
        ic(0, 1) + shift(0, 1),
        m * c[0],
        m * c[1],
        m * c[2],
        m,
    ]
}

/// The base map `K` of the module docs (49 × 70).
pub fn base_map(rng: &mut ChaCha8Rng) -> DMatrix<f64> {
    // Rows: ZZ1, then per link l ≥ 1: XX, XY, XZ, YZ, ZZ, MX, MY, MZ.
    const KEPT: [usize; 8] = [0, 1, 2, 4, 5, 6, 7, 8];
    let nb = 1 + 8 * (LINKS - 1);
    let row = |l: usize, param: usize| -> Option<usize> {
        match l {
            0 => (param == 5).then_some(0),
            _ => KEPT
                .iter()
                .position(|&k| k == param)
                .map(|i| 1 + 8 * (l - 1) + i),
        }
    };
    let mut k = DMatrix::zeros(nb, 10 * LINKS);
    for l in 0..LINKS {
        for param in 0..10 {
            if let Some(r) = row(l, param) {
                k[(r, 10 * l + param)] = 1.0;
            }
        }
        if l == 0 {
            continue;
        }
        let d: f64 = rng.gen_range(0.1..0.5);
        let prev_zz = row(l - 1, 5).unwrap_or(0);
        // YY_l → XX_l (−1), ZZ_{l−1} (+1).
        k[(1 + 8 * (l - 1), 10 * l + 3)] = -1.0;
        k[(prev_zz, 10 * l + 3)] = 1.0;
        // M_l → XX_{l−1}, ZZ_{l−1} (+d²), MZ_{l−1} (+d).
        k[(prev_zz, 10 * l + 9)] = d * d;
        for (param, coef) in [(0, d * d), (8, d)] {
            if let Some(r) = row(l - 1, param) {
                k[(r, 10 * l + 9)] = coef;
            }
        }
    }
    k
}

/// A problem with `rows` regressor rows, noise of standard deviation `noise` (N·m) on each
/// torque, and the given seed.
pub fn seven_link(rows: usize, noise: f64, seed: u64) -> Synthetic {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x0070_4c1c);
    let params = DVector::from_iterator(
        10 * LINKS,
        (0..LINKS).flat_map(|l| random_link(&mut rng, l == LINKS - 1)),
    );
    let effects = DVector::from_fn(EFFECTS, |i, _| match (i % 3, i / 3) {
        (1, 2) => 0.0,
        (0, _) => rng.gen_range(0.05..2.0),
        (1, _) => rng.gen_range(0.1..3.0),
        _ => rng.gen_range(0.0..0.2),
    });
    let k = base_map(&mut rng);
    let nb = k.nrows();
    let ny = nb + EFFECTS;
    let scales: Vec<f64> = (0..ny)
        .map(|_| 10f64.powf(rng.gen_range(-1.5..1.5)))
        .collect();
    let a = DMatrix::from_fn(rows, ny, |_, j| gaussian(&mut rng) * scales[j]);
    let y_true = DVector::from_iterator(ny, (&k * &params).iter().chain(effects.iter()).copied());
    let tau = &a * &y_true + DVector::from_fn(rows, |_, _| noise * gaussian(&mut rng));
    let normal = a.transpose() * &a;
    let estimate = normal
        .clone()
        .cholesky()
        .map(|c| c.solve(&(a.transpose() * tau)))
        .unwrap_or_else(|| y_true.clone());
    let mut problem = ConsistentProblem::new(LINKS, EFFECTS, k, estimate, normal);
    problem.nonneg = (0..EFFECTS).filter(|i| i % 3 != 2).collect();
    problem.bounds = (0..EFFECTS)
        .filter(|i| i % 3 == 2)
        .map(|effect| EffectBound {
            effect,
            lo: 0.0,
            hi: 0.5,
        })
        .collect();
    Synthetic {
        problem,
        params,
        effects,
    }
}
