//! Block-jackknife standard deviations: a parameter's spread over its leave-one-block-out fits,
//! scaled by `(B − 1) / B`. Honest when the residuals are correlated within a block (filtered
//! torque is), which the least-squares covariance is not.

use super::problem::Problem;
use super::RankError;

/// `|x| / σ` of the coefficient of column `col` in the weighted fit of the columns `subset`
/// (`col` among them), σ from the block jackknife of that fit; 0 when σ is 0.
pub(super) fn coefficient_z(p: &Problem, subset: &[usize], col: usize) -> Result<f64, RankError> {
    let Some(k) = subset.iter().position(|&s| s == col) else {
        return Ok(0.0);
    };
    let w = p.weights(subset)?;
    let x = p.fit(subset, &w)?.x[k];
    let sd = std(&p.loo_fits(subset, &w)?, subset.len())[k];
    Ok(if sd > 0.0 { x.abs() / sd } else { 0.0 })
}

/// Standard deviations of the first `k` parameters of the leave-one-block-out fits `loo` (one
/// parameter vector per block); NaN with fewer than two blocks.
pub(super) fn std(loo: &[Vec<f64>], k: usize) -> Vec<f64> {
    let nb = loo.len() as f64;
    (0..k)
        .map(|k| {
            if loo.len() < 2 {
                return f64::NAN;
            }
            let mean = loo.iter().map(|x| x[k]).sum::<f64>() / nb;
            ((nb - 1.0) / nb * loo.iter().map(|x| (x[k] - mean).powi(2)).sum::<f64>()).sqrt()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_jackknife_of_a_mean_is_the_standard_error() {
        // Leave-one-out means of x: (S − xᵢ)/(n − 1). Their jackknife variance is exactly
        // s²/n, s² the sample variance (Efron & Stein): the closed form to rounding.
        let x = [0.3, -1.2, 2.5, 0.7, 0.1, -0.4, 1.9, 3.3];
        let n = x.len() as f64;
        let sum: f64 = x.iter().sum();
        let loo: Vec<Vec<f64>> = x.iter().map(|xi| vec![(sum - xi) / (n - 1.0)]).collect();
        let mean = sum / n;
        let s2 = x.iter().map(|xi| (xi - mean).powi(2)).sum::<f64>() / (n - 1.0);
        let sd = super::std(&loo, 1)[0];
        assert!((sd - (s2 / n).sqrt()).abs() < 1e-12, "{sd}");
        assert!(super::std(&loo[..1], 1)[0].is_nan());
    }
}
