//! **Hotelling's T² on block-jackknife replicates**: whether several coefficients fitted together
//! (the columns of one unit, e.g. a friction spline's three) are zero, when each alone may look
//! small because the columns share what they explain. With `x` the full fit's `p` coefficients
//! and `S` their block-jackknife covariance (`(B − 1)/B · Σ (x_b − x̄)(x_b − x̄)ᵀ` over the `B`
//! leave-one-block-out fits; honest when the residuals are correlated within a block),
//! `T² = xᵀ S⁻¹ x` and `F = (ν − p + 1) / (ν p) · T²`, `ν = B − 1`, is compared with the
//! F(p, ν − p + 1) distribution (Hotelling 1931). For one column it is the square of the
//! jackknife `z` ([`super::jackknife`]).

use nalgebra::{DMatrix, DVector};

use super::problem::Problem;
use super::residual_map::ln_gamma;
use super::RankError;

/// A joint test of several coefficients: the F statistic, its degrees of freedom and `None`
/// where the jackknife covariance is singular (fewer blocks than columns, or a column that never
/// varies).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct JointF {
    pub f: f64,
    pub d1: f64,
    pub d2: f64,
}

impl JointF {
    /// The critical value at upper-tail level `alpha`.
    pub fn critical(&self, alpha: f64) -> f64 {
        f_quantile(1.0 - alpha, self.d1, self.d2)
    }
}

/// The joint test of the coefficients of columns `cols` (all in `subset`) in the weighted fit of
/// the columns `subset` (see the module docs).
pub(super) fn joint_f(
    p: &Problem,
    subset: &[usize],
    cols: &[usize],
) -> Result<Option<JointF>, RankError> {
    let at: Vec<usize> = cols
        .iter()
        .filter_map(|c| subset.iter().position(|s| s == c))
        .collect();
    if at.len() != cols.len() || at.is_empty() {
        return Ok(None);
    }
    let w = p.weights(subset)?;
    let x = p.fit(subset, &w)?.x;
    let loo = p.loo_fits(subset, &w)?;
    let pick = |v: &[f64]| DVector::from_iterator(at.len(), at.iter().map(|&k| v[k]));
    Ok(t_squared(
        &pick(&x),
        &loo.iter().map(|v| pick(v)).collect::<Vec<_>>(),
    ))
}

/// [`joint_f`] on the full fit's coefficients `x` and the leave-one-block-out fits' `loo`.
fn t_squared(x: &DVector<f64>, loo: &[DVector<f64>]) -> Option<JointF> {
    let (pdim, b) = (x.len() as f64, loo.len() as f64);
    let nu = b - 1.0;
    if nu - pdim + 1.0 < 1.0 {
        return None;
    }
    let mean = loo.iter().fold(DVector::zeros(x.len()), |s, v| s + v) / b;
    let mut s = DMatrix::zeros(x.len(), x.len());
    for v in loo {
        let d = v - &mean;
        s += &d * d.transpose();
    }
    s *= nu / b;
    let t2 = x.dot(&s.cholesky()?.solve(x));
    Some(JointF {
        f: (nu - pdim + 1.0) / (nu * pdim) * t2,
        d1: pdim,
        d2: nu - pdim + 1.0,
    })
}

/// The `prob` quantile of the F(d1, d2) distribution (bisection on its CDF, the regularized
/// incomplete beta function `I_{d1 f / (d1 f + d2)}(d1/2, d2/2)`).
pub fn f_quantile(prob: f64, d1: f64, d2: f64) -> f64 {
    let cdf = |f: f64| beta_inc(d1 / 2.0, d2 / 2.0, d1 * f / (d1 * f + d2));
    let mut hi = 1.0;
    while cdf(hi) < prob && hi < 1e12 {
        hi *= 2.0;
    }
    let mut lo = 0.0;
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if cdf(mid) < prob {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-14 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// The regularized incomplete beta function `I_x(a, b)` (continued fraction by the modified
/// Lentz method, on the side where it converges fast; Numerical Recipes §6.4).
fn beta_inc(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let front =
        (ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln()).exp();
    if x < (a + 1.0) / (a + b + 2.0) {
        front * beta_fraction(a, b, x) / a
    } else {
        1.0 - front * beta_fraction(b, a, 1.0 - x) / b
    }
}

fn beta_fraction(a: f64, b: f64, x: f64) -> f64 {
    let tiny = 1e-300;
    let clamp = |v: f64| if v.abs() < tiny { tiny } else { v };
    let mut c = 1.0;
    let mut d = 1.0 / clamp(1.0 - (a + b) * x / (a + 1.0));
    let mut h = d;
    for m in 1..1000 {
        let m = m as f64;
        let even = m * (b - m) * x / ((a + 2.0 * m - 1.0) * (a + 2.0 * m));
        d = 1.0 / clamp(1.0 + even * d);
        c = clamp(1.0 + even / c);
        h *= d * c;
        let odd = -(a + m) * (a + b + m) * x / ((a + 2.0 * m) * (a + 2.0 * m + 1.0));
        d = 1.0 / clamp(1.0 + odd * d);
        c = clamp(1.0 + odd / c);
        let delta = d * c;
        h *= delta;
        if (delta - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f_quantiles_match_closed_forms_and_tables() {
        // F(2, d2) has the closed-form quantile d2/2 · ((1 − p)^(−2/d2) − 1).
        for d2 in [3.0, 8.0, 17.0, 40.0] {
            for p in [0.5f64, 0.95, 0.99, 0.9997] {
                let exact = d2 / 2.0 * ((1.0 - p).powf(-2.0 / d2) - 1.0);
                let got = f_quantile(p, 2.0, d2);
                assert!(
                    (got - exact).abs() < 1e-9 * exact,
                    "F(2,{d2}) at {p}: {got} vs {exact}"
                );
            }
        }
        // F(1, ν) is t(ν)²: t_{0.995}(10) = 3.169273 (tables).
        assert!((f_quantile(0.99, 1.0, 10.0).sqrt() - 3.169_273).abs() < 1e-5);
        // Tables (Abramowitz & Stegun 26.9): F_{0.95}(3, 17) = 3.20, F_{0.99}(3, 17) = 5.18.
        assert!((f_quantile(0.95, 3.0, 17.0) - 3.197).abs() < 2e-3);
        assert!((f_quantile(0.99, 3.0, 17.0) - 5.185).abs() < 2e-3);
    }

    #[test]
    fn one_column_t_squared_is_the_squared_jackknife_z() {
        let loo: Vec<DVector<f64>> = [0.9, 1.3, 1.1, 0.7, 1.0, 1.2]
            .iter()
            .map(|&v| DVector::from_element(1, v))
            .collect();
        let x = DVector::from_element(1, 1.05);
        let sd =
            super::super::jackknife::std(&loo.iter().map(|v| vec![v[0]]).collect::<Vec<_>>(), 1)[0];
        let f = t_squared(&x, &loo).expect("regular");
        assert_eq!((f.d1, f.d2), (1.0, 5.0));
        assert!((f.f - (1.05 / sd).powi(2)).abs() < 1e-12 * f.f);
    }

    #[test]
    fn t_squared_is_invariant_to_a_change_of_basis() {
        // The test is about the span of the columns, not their scaling or mixing: x → A x for
        // any regular A leaves T² unchanged.
        let loo: Vec<DVector<f64>> = (0..12)
            .map(|b| {
                let s = b as f64;
                DVector::from_vec(vec![
                    1.0 + 0.1 * (s * 1.7).sin(),
                    0.5 + 0.2 * (s * 0.9).cos(),
                    -0.3 + 0.05 * s.sin(),
                ])
            })
            .collect();
        let x = DVector::from_vec(vec![1.02, 0.48, -0.29]);
        let a = DMatrix::from_row_slice(3, 3, &[2.0, 1.0, 0.0, 0.0, 1.0, -3.0, 1.0, 0.0, 0.5]);
        let f1 = t_squared(&x, &loo).expect("regular").f;
        let f2 = t_squared(&(&a * &x), &loo.iter().map(|v| &a * v).collect::<Vec<_>>())
            .expect("regular")
            .f;
        assert!((f1 - f2).abs() < 1e-9 * f1, "{f1} vs {f2}");
    }
}
