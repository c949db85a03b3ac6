//! Symmetric positive (semi)definite matrices whose rows have very different scales (kg,
//! kg·m², N·m·s …): Jacobi equilibration `D A D` (`D = diag(1/√A_ii)`, unit diagonal) before
//! a Cholesky factorisation or an eigenvalue, so that the scales cost no accuracy.

use nalgebra::{Cholesky, DMatrix, DVector, Dyn, SymmetricEigen};

/// `1/√A_ii`, or 1 where the diagonal is not positive.
fn jacobi(a: &DMatrix<f64>) -> DVector<f64> {
    DVector::from_fn(a.nrows(), |i, _| {
        let v = a[(i, i)];
        if v > 0.0 && v.is_finite() {
            1.0 / v.sqrt()
        } else {
            1.0
        }
    })
}

/// `D A D`.
fn equilibrate(a: &DMatrix<f64>, d: &DVector<f64>) -> DMatrix<f64> {
    DMatrix::from_fn(a.nrows(), a.ncols(), |i, j| a[(i, j)] * d[i] * d[j])
}

/// A Cholesky factorisation of `D (A + ridge·D⁻²) D`.
pub(crate) struct ScaledCholesky {
    chol: Cholesky<f64, Dyn>,
    d: DVector<f64>,
}

impl ScaledCholesky {
    /// Factorises `A` after equilibration; the ridge (added to the unit diagonal) is tried in
    /// turn from `ridges` until a factorisation succeeds. `None` if none does.
    pub(crate) fn new(a: &DMatrix<f64>, ridges: &[f64]) -> Option<ScaledCholesky> {
        let d = jacobi(a);
        let scaled = equilibrate(a, &d);
        ridges.iter().find_map(|&ridge| {
            let mut h = scaled.clone();
            for i in 0..h.nrows() {
                h[(i, i)] += ridge;
            }
            Cholesky::new(h).map(|chol| ScaledCholesky { chol, d: d.clone() })
        })
    }

    /// `A⁻¹ b` (`None` if the result is not finite).
    pub(crate) fn solve(&self, b: &DVector<f64>) -> Option<DVector<f64>> {
        let x = self
            .chol
            .solve(&b.component_mul(&self.d))
            .component_mul(&self.d);
        x.iter().all(|v| v.is_finite()).then_some(x)
    }
}

/// Smallest eigenvalue of `A` scaled to a unit diagonal (rows with a zero diagonal left as
/// they are).
pub(crate) fn scaled_min_eigenvalue(a: &DMatrix<f64>) -> f64 {
    let scaled = equilibrate(a, &jacobi(a));
    SymmetricEigen::new(scaled)
        .eigenvalues
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn badly_scaled_system_is_solved_accurately() {
        // A = D B D with B well conditioned and D spanning twelve decades.
        let b = DMatrix::from_row_slice(3, 3, &[2.0, 0.5, 0.1, 0.5, 1.0, 0.2, 0.1, 0.2, 1.5]);
        let d = DVector::from_row_slice(&[1e6, 1.0, 1e-6]);
        let a = DMatrix::from_fn(3, 3, |i, j| b[(i, j)] * d[i] * d[j]);
        let x = DVector::from_row_slice(&[1e-6, 1.0, 1e6]);
        let rhs = &a * &x;
        let got = ScaledCholesky::new(&a, &[0.0])
            .unwrap()
            .solve(&rhs)
            .unwrap();
        assert!((0..3).all(|i| ((got[i] - x[i]) / x[i]).abs() < 1e-13));
        assert!(scaled_min_eigenvalue(&a) > 0.3);
    }
}
