//! The payload's parameters from its rows: weighted least squares (each joint weighted by its
//! own residual noise, from an unweighted first pass), pulled into the physical set with the
//! same program `identify` uses (`physical::ConsistentProblem`, pseudo-inertia `J ⪰ 0`), and
//! a covariance widened by the residuals' correlation time (filtered residuals are not white).

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

use crate::physical::ConsistentProblem;

use super::rows::Rows;
use super::PayloadError;

/// The estimate in the last link's frame.
#[derive(Debug, Clone)]
pub struct Fit {
    /// `[XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M]` about the last link's origin (consistent).
    pub phi: [f64; 10],
    /// The same before the consistency program.
    pub ls: [f64; 10],
    /// Covariance of `phi` (10 × 10; the mass row/column zero when it was given).
    pub cov: DMatrix<f64>,
    /// RMS of `d` per joint (the fit before) and of `d − Y·φ` (after).
    pub rms_before: Vec<f64>,
    pub rms_after: Vec<f64>,
    pub samples: usize,
    /// The consistency program moved the estimate by more than its own σ in some direction.
    pub projected: bool,
}

/// Per joint, the RMS of `d − Y·x` (the first `x.len()` columns, target `d − fixed·Y[9]`).
fn residual_rms(rows: &[Rows], x: &[f64], fixed: Option<f64>) -> Vec<f64> {
    let n = rows[0].n;
    let (mut s, mut c) = (vec![0.0; n], vec![0usize; n]);
    for r in rows {
        for (i, (y, d)) in r.y.iter().zip(&r.d).enumerate() {
            let j = i % n;
            let e = target(y, *d, fixed) - y.iter().zip(x).map(|(a, b)| a * b).sum::<f64>();
            s[j] += e * e;
            c[j] += 1;
        }
    }
    s.iter()
        .zip(&c)
        .map(|(s, c)| (s / (*c).max(1) as f64).sqrt())
        .collect()
}

/// Per joint, the RMS of `d − Y·φ`.
pub(super) fn residual_rms_of(rows: &[Rows], phi: &[f64; 10]) -> Vec<f64> {
    residual_rms(rows, phi, None)
}

fn target(y: &[f64; 10], d: f64, fixed: Option<f64>) -> f64 {
    match fixed {
        Some(m) => d - m * y[9],
        None => d,
    }
}

/// Weighted normal equations over the first `p` columns: `(N, g)` with weight `1/σ_j²`.
fn normal(
    rows: &[Rows],
    p: usize,
    sigma: &[f64],
    fixed: Option<f64>,
) -> (DMatrix<f64>, DVector<f64>) {
    let n = rows[0].n;
    let mut nm = DMatrix::zeros(p, p);
    let mut g = DVector::zeros(p);
    for r in rows {
        for (i, (y, d)) in r.y.iter().zip(&r.d).enumerate() {
            let w = 1.0 / (sigma[i % n] * sigma[i % n]);
            let t = target(y, *d, fixed);
            for a in 0..p {
                g[a] += w * y[a] * t;
                for b in a..p {
                    nm[(a, b)] += w * y[a] * y[b];
                }
            }
        }
    }
    for a in 0..p {
        for b in 0..a {
            nm[(a, b)] = nm[(b, a)];
        }
    }
    (nm, g)
}

/// `N⁻¹` through its eigen-decomposition with a ridge of `1e-12·λ_max`: directions the data do
/// not see get a huge (not a zero) variance.
pub(super) fn inverse(nm: &DMatrix<f64>) -> DMatrix<f64> {
    let e = nm.clone().symmetric_eigen();
    let top = e
        .eigenvalues
        .iter()
        .cloned()
        .fold(0.0, f64::max)
        .max(1e-300);
    let inv = e.eigenvalues.map(|l| 1.0 / (l.max(0.0) + 1e-12 * top));
    &e.eigenvectors * DMatrix::from_diagonal(&inv) * e.eigenvectors.transpose()
}

/// Solves the weighted problem over `p` columns, `sigma` per joint (`None`: from an unweighted
/// first pass); returns the estimate, `N`, and the per-joint noise used.
pub(super) fn weighted(
    rows: &[Rows],
    p: usize,
    fixed: Option<f64>,
) -> (DVector<f64>, DMatrix<f64>, Vec<f64>) {
    let n = rows[0].n;
    let ones = vec![1.0; n];
    let (n0, g0) = normal(rows, p, &ones, fixed);
    let x0 = inverse(&n0) * g0;
    let rms = residual_rms(rows, x0.as_slice(), fixed);
    let top = rms.iter().cloned().fold(0.0, f64::max);
    let sigma: Vec<f64> = rms.iter().map(|s| s.max(1e-6 * top).max(1e-12)).collect();
    let (nm, g) = normal(rows, p, &sigma, fixed);
    (inverse(&nm) * g, nm, sigma)
}

/// The integrated autocorrelation time (in samples) of the weighted residuals, `1 + 2Σρ_k`
/// summed until `ρ` first drops below 0.05: the factor by which correlated residuals carry less
/// information than white ones.
pub(super) fn correlation_time(rows: &[Rows], x: &[f64], sigma: &[f64], fixed: Option<f64>) -> f64 {
    let n = rows[0].n;
    let mut worst: f64 = 1.0;
    for (j, sj) in sigma.iter().enumerate().take(n) {
        let mut tau = 0.0;
        let mut count = 0.0;
        for r in rows {
            let e: Vec<f64> = r
                .y
                .iter()
                .zip(&r.d)
                .skip(j)
                .step_by(n)
                .map(|(y, d)| {
                    (target(y, *d, fixed) - y.iter().zip(x).map(|(a, b)| a * b).sum::<f64>()) / sj
                })
                .collect();
            let m = e.len();
            if m < 10 {
                continue;
            }
            let c0: f64 = e.iter().map(|v| v * v).sum::<f64>() / m as f64;
            if c0 <= 0.0 {
                continue;
            }
            let mut t = 1.0;
            for lag in 1..(m / 4).min(2000) {
                let c: f64 = e[..m - lag]
                    .iter()
                    .zip(&e[lag..])
                    .map(|(a, b)| a * b)
                    .sum::<f64>()
                    / m as f64;
                let rho = c / c0;
                if rho < 0.05 {
                    break;
                }
                t += 2.0 * rho;
            }
            tau += t * m as f64;
            count += m as f64;
        }
        if count > 0.0 {
            worst = worst.max(tau / count);
        }
    }
    worst
}

/// Fits `φ` (or, with `mass`, its nine other entries) to `rows`.
pub fn fit(rows: &[Rows], mass: Option<f64>) -> Result<Fit, PayloadError> {
    let samples: usize = rows.iter().map(Rows::len).sum();
    let p = if mass.is_some() { 9 } else { 10 };
    if samples < 4 * p {
        return Err(PayloadError::Input(format!(
            "{samples} usable rows in the loaded runs — too few for {p} payload parameters (use longer runs)"
        )));
    }
    let (x, nm, sigma) = weighted(rows, p, mass);
    let chi2: f64 = {
        let rms = residual_rms(rows, x.as_slice(), mass);
        let n = rows[0].n;
        let mut per = vec![0usize; n];
        for r in rows {
            for i in 0..r.len() {
                per[i % n] += 1;
            }
        }
        rms.iter()
            .zip(&sigma)
            .zip(&per)
            .map(|((r, s), c)| (r / s).powi(2) * *c as f64)
            .sum::<f64>()
            / (samples - p).max(1) as f64
    };
    let tau = correlation_time(rows, x.as_slice(), &sigma, mass);
    let cov_p = inverse(&nm) * (chi2.max(1e-300) * tau);
    let mut ls = [0.0; 10];
    ls[..p].copy_from_slice(&x.as_slice()[..p]);
    let mut n10 = DMatrix::zeros(10, 10);
    n10.view_mut((0, 0), (p, p)).copy_from(&nm);
    if let Some(m) = mass {
        ls[9] = m;
        // A known mass: an observation of it a million times stiffer than anything else.
        n10[(9, 9)] = 1e6 * nm.diagonal().max().max(1e-300);
    }
    let problem = ConsistentProblem::new(
        1,
        0,
        DMatrix::identity(10, 10),
        DVector::from_row_slice(&ls),
        n10,
    );
    // Already a physical body: least squares is the answer (the program's regulariser would
    // only pull it by ~1e-6 of the data's weight).
    let mut phi = ls;
    let (m0, _, i0) = physical(&ls);
    let strictly = crate::params::check_physical(m0, &i0).is_ok()
        && crate::physical::LinkPhysics::from_params(&ls).relative_min_eigenvalue > 0.0;
    if !strictly {
        let solved = problem.solve().map_err(|e| {
            PayloadError::Numerical(format!("the physical-consistency program: {e}"))
        })?;
        phi.copy_from_slice(solved.params.as_slice());
    }
    if let Some(m) = mass {
        phi[9] = m;
    }
    let mut cov = DMatrix::zeros(10, 10);
    cov.view_mut((0, 0), (p, p)).copy_from(&cov_p);
    let dx = DVector::from_iterator(p, (0..p).map(|i| phi[i] - ls[i]));
    let projected = (dx.transpose() * &inverse(&cov_p) * &dx)[(0, 0)] > 1.0;
    let after = residual_rms(rows, &phi, None);
    let before = residual_rms(rows, &[0.0; 10], None);
    Ok(Fit {
        phi,
        ls,
        cov,
        rms_before: before,
        rms_after: after,
        samples,
        projected,
    })
}

/// `(mass, centre of mass, inertia about it [xx, xy, xz, yy, yz, zz])` of `φ`.
pub fn physical(phi: &[f64; 10]) -> (f64, [f64; 3], [f64; 6]) {
    let m = phi[9];
    let c = if m.abs() > 0.0 {
        Vector3::new(phi[6], phi[7], phi[8]) / m
    } else {
        Vector3::zeros()
    };
    let io = Matrix3::new(
        phi[0], phi[1], phi[2], phi[1], phi[3], phi[4], phi[2], phi[4], phi[5],
    );
    let ic = io - m * (Matrix3::identity() * c.norm_squared() - c * c.transpose());
    (
        m,
        [c.x, c.y, c.z],
        [
            ic[(0, 0)],
            ic[(0, 1)],
            ic[(0, 2)],
            ic[(1, 1)],
            ic[(1, 2)],
            ic[(2, 2)],
        ],
    )
}

/// σ of `(mass, com, inertia)` from `cov` by the delta method (central differences of
/// [`physical`]).
pub fn sigma(phi: &[f64; 10], cov: &DMatrix<f64>) -> [f64; 10] {
    let flat = |p: &[f64; 10]| {
        let (m, c, i) = physical(p);
        let mut v = [0.0; 10];
        v[0] = m;
        v[1..4].copy_from_slice(&c);
        v[4..].copy_from_slice(&i);
        v
    };
    let mut jac = DMatrix::zeros(10, 10);
    for a in 0..10 {
        let h = 1e-6 * (phi[a].abs() + 1e-3 * phi[9].abs().max(1e-3));
        let (mut up, mut dn) = (*phi, *phi);
        up[a] += h;
        dn[a] -= h;
        let (fu, fd) = (flat(&up), flat(&dn));
        for r in 0..10 {
            jac[(r, a)] = (fu[r] - fd[r]) / (2.0 * h);
        }
    }
    let c = &jac * cov * jac.transpose();
    let mut s = [0.0; 10];
    for (r, v) in s.iter_mut().enumerate() {
        *v = c[(r, r)].max(0.0).sqrt();
    }
    s
}
