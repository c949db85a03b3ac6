//! Input checks of a [`ConsistentProblem`], before anything is computed: sizes, finite
//! numbers, a symmetric positive semidefinite `N`, effect indices and bounds, the weight, the
//! prior's physical consistency, the margin and the ellipsoids. Each failure is a
//! [`ConsistentError`] that says what to change.

use nalgebra::{DMatrix, DVector};

use super::program::{ConsistentError, ConsistentProblem};
use super::pseudo_inertia::{LinkParams, LinkPhysics};
use super::spd::scaled_min_eigenvalue;

/// `N` counts as symmetric when `|N_ij − N_ji| ≤ SYMMETRY_TOL·max|N|`: a normal matrix
/// accumulated in floating point in a different order for each triangle differs at ~1e-16
/// relative per term; 1e-9 leaves room for long sums and flags real mistakes.
const SYMMETRY_TOL: f64 = 1e-9;

/// `N` (scaled to a unit diagonal) counts as positive semidefinite when its smallest eigenvalue
/// is at least `−PSD_TOL`: rounding in `AᵀWA` of a rank-deficient `A` leaves eigenvalues of
/// ~`dim·1e-16` either side of zero in the scaled matrix.
const PSD_TOL: f64 = 1e-8;

/// Runs every check (see the module docs).
pub(crate) fn validate(pb: &ConsistentProblem) -> Result<(), ConsistentError> {
    sizes(pb)?;
    finite("base_map", pb.base_map.as_slice())?;
    finite("estimate", pb.estimate.as_slice())?;
    finite("normal", pb.normal.as_slice())?;
    normal_matrix(&pb.normal)?;
    effects(pb)?;
    let opts = pb.options;
    if !(opts.gap_tol.is_finite() && opts.gap_tol > 0.0) || opts.max_iterations == 0 {
        return Err(ConsistentError::Options {
            detail: format!(
                "gap_tol = {}, max_iterations = {}",
                opts.gap_tol, opts.max_iterations
            ),
        });
    }
    if let Some(w) = pb.weight {
        if !(w.is_finite() && w > 0.0) {
            return Err(ConsistentError::Weight { value: w });
        }
    }
    if let Some(prior) = &pb.prior {
        prior_physical(prior)?;
    }
    if let Some(m) = pb.margin {
        let ok = |v: f64| v.is_finite() && v >= 0.0;
        if !(ok(m.mass) && ok(m.length)) {
            return Err(ConsistentError::Margin {
                mass: m.mass,
                length: m.length,
            });
        }
    }
    ellipsoids(pb)
}

fn dim_err(
    what: &'static str,
    expected: String,
    found: String,
    hint: &'static str,
) -> ConsistentError {
    ConsistentError::Dimension {
        what,
        expected,
        found,
        hint,
    }
}

fn sizes(pb: &ConsistentProblem) -> Result<(), ConsistentError> {
    // Sizes that overflow are impossible (the matrices could not be allocated): report them
    // as a mismatch rather than overflow.
    let too_big = || {
        dim_err(
            "n_links or n_effects",
            "a size the matrices can have".into(),
            format!("{} links, {} effects", pb.n_links, pb.n_effects),
            "n_links counts links (10 parameters each), n_effects the effect coefficients",
        )
    };
    let n_pi = pb.n_links.checked_mul(10).ok_or_else(too_big)?;
    let nb = pb.base_map.nrows();
    let ny = nb.checked_add(pb.n_effects).ok_or_else(too_big)?;
    n_pi.checked_add(pb.n_effects).ok_or_else(too_big)?;
    if n_pi + pb.n_effects == 0 {
        return Err(dim_err(
            "the problem",
            "at least one link or effect".into(),
            "empty (0 links, 0 effects)".into(),
            "give n_links and/or n_effects",
        ));
    }
    if pb.base_map.ncols() != n_pi {
        return Err(dim_err(
            "base_map's column count",
            format!("10·n_links = {n_pi}"),
            pb.base_map.ncols().to_string(),
            "K maps the 10 standard parameters of every link to the base parameters",
        ));
    }
    if pb.estimate.len() != ny {
        return Err(dim_err(
            "estimate's length",
            format!("base parameters + effects = {nb} + {} = {ny}", pb.n_effects),
            pb.estimate.len().to_string(),
            "ŷ stacks the base parameters (one per row of K) and then the effects",
        ));
    }
    if pb.normal.nrows() != ny || pb.normal.ncols() != ny {
        return Err(dim_err(
            "normal's shape",
            format!("{ny} × {ny}"),
            format!("{} × {}", pb.normal.nrows(), pb.normal.ncols()),
            "N is over y = [θ; e], the same variables as the estimate",
        ));
    }
    if let Some(prior) = &pb.prior {
        if prior.len() != n_pi {
            return Err(dim_err(
                "the prior's length",
                format!("10·n_links = {n_pi}"),
                prior.len().to_string(),
                "the prior holds the standard parameters of every link",
            ));
        }
    }
    if !pb.ellipsoids.is_empty() && pb.ellipsoids.len() != pb.n_links {
        return Err(dim_err(
            "the ellipsoid list's length",
            format!("0 or n_links = {}", pb.n_links),
            pb.ellipsoids.len().to_string(),
            "give one entry per link (None for a link without one)",
        ));
    }
    Ok(())
}

fn finite(what: &'static str, values: &[f64]) -> Result<(), ConsistentError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(ConsistentError::NonFinite {
            what,
            index,
            value: values[index],
        }),
        None => Ok(()),
    }
}

fn normal_matrix(n: &DMatrix<f64>) -> Result<(), ConsistentError> {
    let big = n.amax();
    if big == 0.0 {
        return Err(ConsistentError::NoData);
    }
    for row in 0..n.nrows() {
        for col in row + 1..n.ncols() {
            let (a, b) = (n[(row, col)], n[(col, row)]);
            if (a - b).abs() > SYMMETRY_TOL * big {
                return Err(ConsistentError::NotSymmetric { row, col, a, b });
            }
        }
    }
    let sym = (n + n.transpose()) * 0.5;
    let eigenvalue = scaled_min_eigenvalue(&sym);
    if eigenvalue < -PSD_TOL || n.diagonal().iter().any(|&d| d < 0.0) {
        return Err(ConsistentError::NotSemidefinite {
            eigenvalue: eigenvalue.min(n.diagonal().min()),
        });
    }
    Ok(())
}

fn effects(pb: &ConsistentProblem) -> Result<(), ConsistentError> {
    let out_of_range = |which, index| ConsistentError::EffectIndex {
        which,
        index,
        n_effects: pb.n_effects,
    };
    if let Some(&k) = pb.nonneg.iter().find(|&&k| k >= pb.n_effects) {
        return Err(out_of_range("nonneg", k));
    }
    for b in &pb.bounds {
        if b.effect >= pb.n_effects {
            return Err(out_of_range("bounds", b.effect));
        }
        // ±∞ are allowed (one-sided bounds), NaN is not.
        if b.lo.is_nan() || b.hi.is_nan() || b.lo == f64::INFINITY || b.hi == f64::NEG_INFINITY {
            return Err(ConsistentError::InfeasibleBounds {
                effect: b.effect,
                lo: b.lo,
                hi: b.hi,
                nonneg: "",
                drop_nonneg: "",
            });
        }
    }
    Ok(())
}

fn prior_physical(prior: &DVector<f64>) -> Result<(), ConsistentError> {
    finite("prior", prior.as_slice())?;
    for link in 0..prior.len() / 10 {
        let p: LinkParams = std::array::from_fn(|k| prior[10 * link + k]);
        let phys = LinkPhysics::from_params(&p);
        if phys.consistent {
            continue;
        }
        let detail = if phys.mass < 0.0 {
            format!("has mass {} kg", phys.mass)
        } else {
            format!(
                "has a pseudo-inertia eigenvalue {:.3e} (relative {:.3e}): no mass distribution has these inertias",
                phys.min_eigenvalue, phys.relative_min_eigenvalue
            )
        };
        return Err(ConsistentError::PriorNotPhysical {
            link: link + 1,
            detail,
        });
    }
    Ok(())
}

fn ellipsoids(pb: &ConsistentProblem) -> Result<(), ConsistentError> {
    for (l, e) in pb.ellipsoids.iter().enumerate() {
        let Some(e) = e else { continue };
        let bad_centre = e.centre.iter().any(|v| !v.is_finite());
        let bad_axis = e.semi_axes.iter().any(|v| !(v.is_finite() && *v > 0.0));
        if bad_centre || bad_axis {
            return Err(ConsistentError::Ellipsoid {
                link: l + 1,
                detail: format!("centre {:?}, semi-axes {:?}", e.centre, e.semi_axes),
            });
        }
    }
    Ok(())
}
