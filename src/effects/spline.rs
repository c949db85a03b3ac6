//! Friction as a **natural cubic spline in the velocity** (`spline_a`, `spline_b`, `spline_c`):
//! for a joint whose friction no closed form fits (sub- or super-linear viscous friction, a
//! lubricant's shear thinning). With the velocity in units of the joint's fast training velocity
//! `u` (the 8-norm of q̇ over the training samples, `(mean q̇⁸)^(1/8)`: near the top speeds the
//! motion reaches, 0.85 of a sinusoid's amplitude, 1.8 RMS of a Gaussian, without the single
//! fastest sample's noise), `x = q̇ / u`, the knots sit at `x = −1, −½, 0, ½, 1`, so every piece
//! of the curve is fitted on speeds the motion reaches; a natural cubic spline on them is cubic
//! between knots, linear outside (so it extrapolates like viscous friction) and spans 5
//! functions: `1` (`offset`), `x` (`viscous`) and the three columns here — the truncated-power
//! basis `N_k = d_k − d_4`, `d_k(x) = ((x − ξ_k)₊³ − (x − ξ_5)₊³) / (ξ_5 − ξ_k)` (Hastie, Tibshirani
//! & Friedman, *Elements of Statistical Learning*, eq. 5.4–5.5), each scaled to 1 at `x = 1`, so
//! a coefficient is that column's torque at `q̇ = u`. The step of Coulomb friction
//! at rest is not in this space (a spline is smooth): `coulomb` stays its own column.

/// The knots, in units of the fast velocity `u`.
pub const KNOTS: [f64; 5] = [-1.0, -0.5, 0.0, 0.5, 1.0];

/// The 8-norm of a joint's velocity from its mean of `q̇⁸` (the spline's unit `u`), 1 when the
/// joint does not move.
pub fn velocity_unit(mean_dq8: f64) -> f64 {
    let u = mean_dq8.powf(0.125);
    if u.is_finite() && u > 0.0 {
        u
    } else {
        1.0
    }
}

/// Number of columns (the spline's functions beyond the constant and the line).
pub const COLUMNS: usize = KNOTS.len() - 2;

fn cube_plus(x: f64) -> f64 {
    let p = x.max(0.0);
    p * p * p
}

/// `d_k(x)` of the module docs (k from 0).
fn d(k: usize, x: f64) -> f64 {
    let last = KNOTS[KNOTS.len() - 1];
    (cube_plus(x - KNOTS[k]) - cube_plus(x - last)) / (last - KNOTS[k])
}

/// Unscaled column `k` (0-based): `d_k − d_{K−2}`.
fn raw(k: usize, x: f64) -> f64 {
    d(k, x) - d(KNOTS.len() - 2, x)
}

/// Column `k` (0 ≤ k < [`COLUMNS`]) at `x = q̇ / u`, 1 at `x = 1`.
pub fn column(k: usize, x: f64) -> f64 {
    raw(k, x) / raw(k, KNOTS[KNOTS.len() - 1])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Second difference of `f` at `x` (step `h`), an estimate of `f''`.
    fn second(f: impl Fn(f64) -> f64, x: f64, h: f64) -> f64 {
        (f(x + h) - 2.0 * f(x) + f(x - h)) / (h * h)
    }

    #[test]
    fn columns_are_natural_cubic_splines_on_the_knots() {
        for k in 0..COLUMNS {
            let f = |x: f64| column(k, x);
            // Zero left of the first knot, linear right of the last (f'' = 0 in both).
            assert_eq!(f(-1.5), 0.0);
            assert!(
                second(f, 2.0, 1e-3).abs() < 1e-6,
                "k {k}: not linear beyond 1"
            );
            assert!(second(f, -2.0, 1e-3).abs() < 1e-9);
            // Twice continuously differentiable at every knot: f'' is continuous there.
            for &xi in &KNOTS {
                let (l, r) = (second(f, xi - 2e-3, 1e-3), second(f, xi + 2e-3, 1e-3));
                assert!((l - r).abs() < 0.05, "k {k}, knot {xi}: f'' {l} vs {r}");
            }
            // Cubic between knots: the fourth difference vanishes inside a knot interval.
            let x = 0.25;
            let h = 0.05;
            let d4 = f(x + 2.0 * h) - 4.0 * f(x + h) + 6.0 * f(x) - 4.0 * f(x - h) + f(x - 2.0 * h);
            assert!(d4.abs() < 1e-12, "k {k}: not cubic between knots ({d4})");
            assert!((f(1.0) - 1.0).abs() < 1e-15);
        }
    }

    #[test]
    fn columns_with_constant_and_line_interpolate_any_knot_values() {
        // The span of {1, x, columns} is the 5-dimensional space of natural cubic splines on
        // the knots: the 5×5 matrix of their values at the knots is regular, so any values at
        // the knots are matched (here: a sublinear friction curve's).
        let target = |x: f64| x.signum() * x.abs().sqrt();
        let basis = |x: f64| [1.0, x, column(0, x), column(1, x), column(2, x)];
        let a = nalgebra::DMatrix::from_fn(5, 5, |i, j| basis(KNOTS[i])[j]);
        let b = nalgebra::DVector::from_fn(5, |i, _| target(KNOTS[i]));
        let c = a.clone().lu().solve(&b).expect("regular");
        for &xi in &KNOTS {
            let v: f64 = basis(xi).iter().zip(c.iter()).map(|(u, w)| u * w).sum();
            assert!((v - target(xi)).abs() < 1e-12);
        }
        assert!(a.determinant().abs() > 1e-3);
    }
}
