//! A strictly feasible start for the barrier method of [`super::barrier`], as close as cheaply
//! possible to the answer: the regularised unconstrained minimiser, with each link's
//! pseudo-inertia lifted into the interior of the physical set and each bounded effect moved
//! just inside its limits.
//!
//! The lifted links keep their own scale: eigenvalues of `J − E` below a hundredth of the
//! largest are raised to that hundredth, so a link whose estimate is nearly physical starts
//! nearly where it is, and a wildly non-physical one starts as a plausible body of the same size.

use nalgebra::{DMatrix, DVector, Matrix4, SymmetricEigen};

use super::pseudo_inertia::{params_from_pseudo_inertia, pseudo_inertia, LinkParams};
use super::spd::ScaledCholesky;

/// Eigenvalues of a link's `J − E` are raised to at least this fraction of the largest.
const LIFT: f64 = 1e-2;

/// `x = −P⁻¹q` for symmetric positive definite `P` (`None` if it cannot be factorised).
pub(crate) fn unconstrained(p: &DMatrix<f64>, q: &DVector<f64>) -> Option<DVector<f64>> {
    ScaledCholesky::new(p, &[0.0])?.solve(&-q)
}

/// A start for one link from its unconstrained parameters `p0`: `J − E ≻ 0` (`E` the margin
/// matrix) and, with an ellipsoid `Q`, `tr(QJ) > 0` with room to spare.
pub(crate) fn link_start(
    p0: &LinkParams,
    margin: &Matrix4<f64>,
    q: Option<&Matrix4<f64>>,
) -> LinkParams {
    let finite = p0.iter().all(|v| v.is_finite());
    let f = if finite {
        pseudo_inertia(p0) - margin
    } else {
        Matrix4::identity()
    };
    let eig = SymmetricEigen::new(f);
    let top = eig.eigenvalues.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    let floor = if top > 0.0 && top.is_finite() {
        LIFT * top
    } else {
        1.0
    };
    let lifted = eig.eigenvalues.map(|v| v.max(floor));
    let mut j =
        eig.eigenvectors * Matrix4::from_diagonal(&lifted) * eig.eigenvectors.transpose() + margin;
    j = (j + j.transpose()) * 0.5;
    if let Some(q) = q {
        // tr(QJ) = ∫(1 − ‖R⁻¹(p − c)‖²) dm ≤ m: ask for a hundredth of the mass inside.
        if (q * j).trace() <= LIFT * j[(3, 3)].abs() {
            j = sphere_start(q, margin, j[(3, 3)].max(floor));
        }
    }
    params_from_pseudo_inertia(&j)
}

/// `E + s·J_sphere`: a solid sphere at the ellipsoid's centre, radius half its smallest
/// semi-axis, with mass `s ≥ mass` large enough that `tr(Q(E + s·J_sphere)) > 0`.
fn sphere_start(q: &Matrix4<f64>, margin: &Matrix4<f64>, mass: f64) -> Matrix4<f64> {
    // Q's Σ block is −R⁻²: the semi-axes are 1/√(−Q_kk), the centre c = R²·Q_k3.
    let semi: [f64; 3] = std::array::from_fn(|k| 1.0 / (-q[(k, k)]).sqrt());
    let centre: [f64; 3] = std::array::from_fn(|k| q[(k, 3)] * semi[k] * semi[k]);
    let radius = 0.5 * semi.iter().copied().fold(f64::INFINITY, f64::min);
    let mut js = Matrix4::zeros();
    for r in 0..3 {
        for c in 0..3 {
            js[(r, c)] = centre[r] * centre[c];
        }
        js[(r, r)] += radius * radius / 5.0;
        js[(r, 3)] = centre[r];
        js[(3, r)] = centre[r];
    }
    js[(3, 3)] = 1.0;
    // tr(Q J_sphere) = 1 − (ρ²/5)·Σ 1/r_k² ≥ 1 − 3/20.
    let per_kg = (q * js).trace();
    let deficit = (-(q * margin).trace()).max(0.0);
    let s = mass.max(2.0 * deficit / per_kg);
    margin + js * s
}

/// A start for one effect from its unconstrained value `u`, strictly inside `[lo, hi]`:
/// a hundredth of the interval's width inside a two-sided limit, or a hundredth of the effect's
/// scale (`max(|u|, |limit|, natural)`) inside a one-sided one.
pub(crate) fn effect_start(u: f64, (lo, hi): (f64, f64), natural: f64) -> f64 {
    let u = if u.is_finite() { u } else { 0.0 };
    if lo.is_finite() && hi.is_finite() {
        // Halves first: hi − lo may overflow.
        let pad = 2.0 * LIFT * (0.5 * hi - 0.5 * lo);
        return u.max(lo + pad).min(hi - pad);
    }
    let bound = if lo.is_finite() { lo } else { hi };
    let mut pad = LIFT * u.abs().max(bound.abs()).max(natural);
    if !(pad > 0.0 && pad.is_finite()) {
        pad = LIFT;
    }
    if lo.is_finite() {
        u.max(lo + pad)
    } else if hi.is_finite() {
        u.min(hi - pad)
    } else {
        u
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physical::consistent::{ellipsoid_matrix, margin_matrix};
    use crate::physical::program::{Ellipsoid, Margin};
    use crate::physical::pseudo_inertia::sorted_eigenvalues4;

    #[test]
    fn nonphysical_link_is_lifted_inside_margin_and_ellipsoid() {
        let p0: LinkParams = [0.1, 0.0, 0.0, 0.1, 0.0, 0.5, 0.3, 0.0, 0.0, -0.4];
        let margin = margin_matrix(Margin {
            mass: 0.1,
            length: 0.05,
        });
        let q = ellipsoid_matrix(Ellipsoid {
            centre: [3.0, 0.0, 0.0],
            semi_axes: [0.2, 0.1, 0.1],
        });
        let j = pseudo_inertia(&link_start(&p0, &margin, Some(&q)));
        assert!(sorted_eigenvalues4(&(j - margin))[0] > 0.0);
        assert!((q * j).trace() > 0.0);
    }

    #[test]
    fn effects_start_strictly_inside() {
        assert!(effect_start(-0.3, (0.0, f64::INFINITY), 1.0) > 0.0);
        let e = effect_start(0.9, (0.0, 0.5), 1.0);
        assert!(e > 0.0 && e < 0.5);
        assert!(effect_start(5.0, (f64::NEG_INFINITY, 1.0), 0.0) < 1.0);
        assert_eq!(effect_start(0.2, (0.0, f64::INFINITY), 1.0), 0.2);
        let wide = effect_start(0.0, (-f64::MAX, f64::MAX), 1.0);
        assert!(wide > -f64::MAX && wide < f64::MAX);
    }
}
