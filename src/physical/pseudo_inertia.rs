//! The 4×4 pseudo-inertia matrix of one link and what it says about the link's physics.
//!
//! **Parameters.** One link's 10 standard parameters in dynid's order
//! ([`crate::model::PARAM_ORDER`]) `XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M`: the inertia tensor
//! `I` about the **link-frame origin** (kg·m²; off-diagonals are tensor entries, `XY = −∫xy dm`),
//! the first moment `h = (MX, MY, MZ) = m·c` (kg·m, `c` the centre of mass in the link frame)
//! and the mass `M` (kg).
//!
//! **Pseudo-inertia** (Wensing, Kim & Slotine, "Linear matrix inequalities for physically
//! consistent inertial parameter identification", IEEE RA-L 2017):
//! `J = ∫ [p; 1][p; 1]ᵀ dm = [[Σ, h], [hᵀ, m]]` with `Σ = ∫ p pᵀ dm = ½·tr(I)·1₃ − I`
//! (kg·m²), so `I = tr(Σ)·1₃ − Σ`. A parameter vector is realisable by a non-negative mass
//! density exactly when `J ⪰ 0`; this implies `m ≥ 0`, the inertia about the centre of mass
//! positive semidefinite and its principal moments satisfying the triangle inequalities.
//!
//! **svec** (the vector form the conic constraint is written in): the upper triangle of `J`
//! stacked column by column — `(0,0), (0,1), (1,1), (0,2), (1,2), (2,2), (0,3), (1,3), (2,3),
//! (3,3)` — with the off-diagonal entries multiplied by `√2`, so that
//! `svec(A)·svec(B) = tr(A B)` for symmetric `A`, `B`. This is the layout of Clarabel's
//! `PSDTriangleConeT` (clarabel 0.11.1, `src/algebra/dense/matrix_math.rs`, `mat_to_svec` /
//! `svec_to_mat`: `for col { for row in 0..=col { … x[idx] = (M[(row,col)] + M[(col,row)])/√2
//! off the diagonal } }`). The map from the 10 parameters to `svec(J)` is linear and invertible
//! ([`svec_map`], [`params_from_pseudo_inertia`]).

use nalgebra::{Matrix3, Matrix4, SMatrix, SVector, SymmetricEigen, Vector3};

/// One link's standard parameters, `XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M`.
pub type LinkParams = [f64; 10];

/// Length of `svec` of a 4×4 symmetric matrix (its upper triangle).
pub const SVEC_LEN: usize = 10;

/// A link is called physically consistent when the smallest eigenvalue of its normalised
/// pseudo-inertia (see [`LinkPhysics::relative_min_eigenvalue`]) is at least `−CONSISTENT_TOL`.
///
/// Why `1e-9`: the normalised matrix has largest eigenvalue 1, so f64 rounding of its entries
/// and of the eigen-solver is ~`1e-15`; parameters from a file (a few significant digits of a
/// CAD export) or from an interior-point solution stopped at a relative gap near `1e-10` sit on
/// the boundary only to ~`1e-10`. `1e-9` accepts such boundary points (a point mass, a thin rod)
/// and rejects any violation large enough to matter in a dynamics model.
pub const CONSISTENT_TOL: f64 = 1e-9;

const SQRT2: f64 = std::f64::consts::SQRT_2;

/// `(row, col)` of each `svec` entry: the upper triangle, column by column.
pub const SVEC_INDEX: [(usize, usize); SVEC_LEN] = [
    (0, 0),
    (0, 1),
    (1, 1),
    (0, 2),
    (1, 2),
    (2, 2),
    (0, 3),
    (1, 3),
    (2, 3),
    (3, 3),
];

/// The inertia tensor about the link-frame origin from the first six parameters.
pub fn inertia_tensor(p: &LinkParams) -> Matrix3<f64> {
    let [xx, xy, xz, yy, yz, zz] = [p[0], p[1], p[2], p[3], p[4], p[5]];
    Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz)
}

/// The pseudo-inertia `J = [[½·tr(I)·1₃ − I, h], [hᵀ, m]]` (see the module docs).
pub fn pseudo_inertia(p: &LinkParams) -> Matrix4<f64> {
    let inertia = inertia_tensor(p);
    let sigma = Matrix3::identity() * (0.5 * inertia.trace()) - inertia;
    let mut j = Matrix4::zeros();
    j.fixed_view_mut::<3, 3>(0, 0).copy_from(&sigma);
    for k in 0..3 {
        j[(k, 3)] = p[6 + k];
        j[(3, k)] = p[6 + k];
    }
    j[(3, 3)] = p[9];
    j
}

/// The parameters of a pseudo-inertia (the inverse of [`pseudo_inertia()`]; only the upper
/// triangle of `j` is read).
pub fn params_from_pseudo_inertia(j: &Matrix4<f64>) -> LinkParams {
    let sym = |r: usize, c: usize| j[(r.min(c), r.max(c))];
    let sigma = Matrix3::from_fn(sym);
    let inertia = Matrix3::identity() * sigma.trace() - sigma;
    [
        inertia[(0, 0)],
        inertia[(0, 1)],
        inertia[(0, 2)],
        inertia[(1, 1)],
        inertia[(1, 2)],
        inertia[(2, 2)],
        sym(0, 3),
        sym(1, 3),
        sym(2, 3),
        sym(3, 3),
    ]
}

/// `svec` of a symmetric 4×4 matrix (upper triangle, column-major, off-diagonals × √2).
pub fn svec(a: &Matrix4<f64>) -> SVector<f64, SVEC_LEN> {
    SVector::from_fn(|k, _| {
        let (r, c) = SVEC_INDEX[k];
        if r == c {
            a[(r, c)]
        } else {
            SQRT2 * a[(r, c)]
        }
    })
}

/// The symmetric matrix of an `svec` (the inverse of [`svec`]).
pub fn smat(v: &SVector<f64, SVEC_LEN>) -> Matrix4<f64> {
    let mut a = Matrix4::zeros();
    for (k, &(r, c)) in SVEC_INDEX.iter().enumerate() {
        let x = if r == c { v[k] } else { v[k] / SQRT2 };
        a[(r, c)] = x;
        a[(c, r)] = x;
    }
    a
}

/// The linear map `S` with `svec(J(p)) = S·p` (rows: `svec` entries, columns: parameters).
///
/// Row by row: `Σ₀₀ = ½(−XX+YY+ZZ)`, `√2·Σ₀₁ = −√2·XY`, `Σ₁₁ = ½(XX−YY+ZZ)`, `√2·Σ₀₂ = −√2·XZ`,
/// `√2·Σ₁₂ = −√2·YZ`, `Σ₂₂ = ½(XX+YY−ZZ)`, `√2·MX`, `√2·MY`, `√2·MZ`, `M`.
pub fn svec_map() -> SMatrix<f64, SVEC_LEN, 10> {
    let mut s = SMatrix::<f64, SVEC_LEN, 10>::zeros();
    // Diagonal of Σ from XX (0), YY (3), ZZ (5).
    for (row, own) in [(0usize, 0usize), (2, 3), (5, 5)] {
        for col in [0usize, 3, 5] {
            s[(row, col)] = if col == own { -0.5 } else { 0.5 };
        }
    }
    s[(1, 1)] = -SQRT2; // XY
    s[(3, 2)] = -SQRT2; // XZ
    s[(4, 4)] = -SQRT2; // YZ
    s[(6, 6)] = SQRT2; // MX
    s[(7, 7)] = SQRT2; // MY
    s[(8, 8)] = SQRT2; // MZ
    s[(9, 9)] = 1.0; // M
    s
}

/// The pseudo-inertia's derivative with respect to each parameter, `∂J/∂p_k` (constant:
/// `J` is linear in `p`).
pub fn pseudo_inertia_basis() -> [Matrix4<f64>; 10] {
    std::array::from_fn(|k| {
        let mut unit = [0.0; 10];
        unit[k] = 1.0;
        pseudo_inertia(&unit)
    })
}

/// `diag(1/ℓ, 1/ℓ, 1/ℓ, 1)` with `ℓ = √(tr Σ / m)`, the link's radius of gyration about the
/// frame origin (1 m when it is undefined: `m ≤ 0` or `tr Σ ≤ 0`). `D J D` has its mass and its
/// second moments in the same unit (kg), so its eigenvalues compare fairly; being congruent to
/// `J` it has the same number of negative eigenvalues (Sylvester's law of inertia).
pub fn normalising_scale(j: &Matrix4<f64>) -> Matrix4<f64> {
    let m = j[(3, 3)];
    let tr = j[(0, 0)] + j[(1, 1)] + j[(2, 2)];
    let ell = if m > 0.0 && tr > 0.0 && (tr / m).is_finite() {
        (tr / m).sqrt()
    } else {
        1.0
    };
    Matrix4::from_diagonal(&nalgebra::Vector4::new(
        1.0 / ell,
        1.0 / ell,
        1.0 / ell,
        1.0,
    ))
}

/// Sorted eigenvalues (ascending) of a symmetric 4×4 matrix.
pub fn sorted_eigenvalues4(a: &Matrix4<f64>) -> [f64; 4] {
    let eig = SymmetricEigen::new(*a).eigenvalues;
    let mut ev: [f64; 4] = std::array::from_fn(|k| eig[k]);
    ev.sort_by(f64::total_cmp);
    ev
}

/// What one link's parameters say physically.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkPhysics {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass in the link frame (m); `None` when the mass is not positive.
    pub com: Option<[f64; 3]>,
    /// Principal moments of the inertia about the centre of mass (kg·m²), ascending; `None` when
    /// the mass is not positive.
    pub principal_moments: Option<[f64; 3]>,
    /// Smallest eigenvalue of `J` itself (mixed units: kg·m² for the `Σ` block, kg for `m`).
    pub min_eigenvalue: f64,
    /// Smallest eigenvalue of the normalised `D J D` ([`normalising_scale`]) divided by its
    /// largest (dimensionless; 0 for an all-zero, virtual link).
    pub relative_min_eigenvalue: f64,
    /// `relative_min_eigenvalue ≥ −CONSISTENT_TOL` ([`CONSISTENT_TOL`]).
    pub consistent: bool,
}

impl LinkPhysics {
    /// Summarises one link's parameters. Non-finite parameters give a non-consistent summary
    /// with NaN eigenvalues (callers validate input first).
    pub fn from_params(p: &LinkParams) -> LinkPhysics {
        if p.iter().any(|v| !v.is_finite()) {
            return LinkPhysics {
                mass: p[9],
                com: None,
                principal_moments: None,
                min_eigenvalue: f64::NAN,
                relative_min_eigenvalue: f64::NAN,
                consistent: false,
            };
        }
        let j = pseudo_inertia(p);
        let min_eigenvalue = sorted_eigenvalues4(&j)[0];
        let relative_min_eigenvalue = relative_min_eigenvalue(&j);
        let m = p[9];
        let (com, principal_moments) = if m > 0.0 {
            let c = Vector3::new(p[6], p[7], p[8]) / m;
            // Parallel-axis theorem, tensor form: I_C = I_O − m (|c|² 1 − c cᵀ).
            let ic = inertia_tensor(p)
                - (Matrix3::identity() * c.norm_squared() - c * c.transpose()) * m;
            let eig = SymmetricEigen::new(ic).eigenvalues;
            let mut moments: [f64; 3] = std::array::from_fn(|k| eig[k]);
            moments.sort_by(f64::total_cmp);
            (Some([c.x, c.y, c.z]), Some(moments))
        } else {
            (None, None)
        };
        LinkPhysics {
            mass: m,
            com,
            principal_moments,
            min_eigenvalue,
            relative_min_eigenvalue,
            consistent: relative_min_eigenvalue >= -CONSISTENT_TOL,
        }
    }
}

/// Smallest over largest eigenvalue of the normalised pseudo-inertia (see [`LinkPhysics`]).
pub fn relative_min_eigenvalue(j: &Matrix4<f64>) -> f64 {
    let d = normalising_scale(j);
    let ev = sorted_eigenvalues4(&(d * j * d));
    let norm = ev[0].abs().max(ev[3].abs());
    if norm > 0.0 {
        ev[0] / norm
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Standard parameters about the link origin of a body with mass `m`, centre of mass `c` and
    /// inertia about the centre of mass `ic` (tensor), by the parallel-axis theorem.
    fn shifted(m: f64, c: [f64; 3], ic: Matrix3<f64>) -> LinkParams {
        let cv = Vector3::from(c);
        let io = ic + (Matrix3::identity() * cv.norm_squared() - cv * cv.transpose()) * m;
        [
            io[(0, 0)],
            io[(0, 1)],
            io[(0, 2)],
            io[(1, 1)],
            io[(1, 2)],
            io[(2, 2)],
            m * c[0],
            m * c[1],
            m * c[2],
            m,
        ]
    }

    #[test]
    fn solid_box_matches_its_second_moments() {
        // Box a × b × d, mass m, centred at c: Σ about the CoM is m/12·diag(a², b², d²).
        let (m, a, b, d) = (3.0, 0.4, 0.2, 0.1);
        let c = [0.1, -0.2, 0.3];
        let ic = Matrix3::from_diagonal(&Vector3::new(
            m / 12.0 * (b * b + d * d),
            m / 12.0 * (a * a + d * d),
            m / 12.0 * (a * a + b * b),
        ));
        let p = shifted(m, c, ic);
        let j = pseudo_inertia(&p);
        // Independent oracle: J = ∫[p;1][p;1]ᵀ dm = [[Σ_C + m c cᵀ, m c], [m cᵀ, m]].
        let cv = Vector3::from(c);
        let sigma = Matrix3::from_diagonal(&Vector3::new(a * a, b * b, d * d)) * (m / 12.0)
            + cv * cv.transpose() * m;
        for r in 0..3 {
            for k in 0..3 {
                assert!((j[(r, k)] - sigma[(r, k)]).abs() < 1e-14);
            }
            assert!((j[(r, 3)] - m * c[r]).abs() < 1e-14);
        }
        let phys = LinkPhysics::from_params(&p);
        assert!(phys.consistent && phys.min_eigenvalue > 0.0);
        let pm = phys.principal_moments.unwrap();
        assert!((pm[0] - m / 12.0 * (b * b + d * d)).abs() < 1e-12);
        assert!((pm[2] - m / 12.0 * (a * a + b * b)).abs() < 1e-12);
        let com = phys.com.unwrap();
        assert!((0..3).all(|k| (com[k] - c[k]).abs() < 1e-12));
    }

    #[test]
    fn solid_cylinder_is_consistent_and_round_trips() {
        // Cylinder radius r, height h along z: Izz = m r²/2, Ixx = Iyy = m(3r² + h²)/12.
        let (m, r, h) = (1.7, 0.05, 0.6);
        let ixx = m * (3.0 * r * r + h * h) / 12.0;
        let ic = Matrix3::from_diagonal(&Vector3::new(ixx, ixx, m * r * r / 2.0));
        let p = shifted(m, [0.0, 0.02, 0.3], ic);
        let phys = LinkPhysics::from_params(&p);
        assert!(phys.consistent && phys.relative_min_eigenvalue > 1e-4);
        let back = params_from_pseudo_inertia(&pseudo_inertia(&p));
        assert!((0..10).all(|k| (back[k] - p[k]).abs() < 1e-14));
    }

    #[test]
    fn point_mass_is_rank_one() {
        let (m, c) = (2.0, [0.5, 0.0, -0.25]);
        let p = shifted(m, c, Matrix3::zeros());
        let j = pseudo_inertia(&p);
        let ev = sorted_eigenvalues4(&j);
        // J = m·[c;1][c;1]ᵀ: one eigenvalue m(|c|²+1), three zeros.
        assert!((ev[3] - m * (0.25 + 0.0625 + 1.0)).abs() < 1e-12);
        assert!(ev[..3].iter().all(|e| e.abs() < 1e-12));
        let phys = LinkPhysics::from_params(&p);
        assert!(phys.consistent);
        assert!(phys.relative_min_eigenvalue.abs() < 1e-12);
    }

    #[test]
    fn triangle_inequality_violation_is_inconsistent() {
        // About the CoM: Ixx + Iyy < Izz, all positive (the tensor itself is positive definite).
        let ic = Matrix3::from_diagonal(&Vector3::new(0.1, 0.1, 0.3));
        let p = shifted(1.0, [0.2, 0.1, 0.0], ic);
        let phys = LinkPhysics::from_params(&p);
        assert!(phys.principal_moments.unwrap()[0] > 0.0);
        assert!(!phys.consistent);
        // Σ_C = ½tr(I)1 − I = diag(0.15, 0.15, −0.05): the negative second moment shows.
        assert!(phys.min_eigenvalue < -0.04);
        assert!(crate::params::check_physical(1.0, &[0.1, 0.0, 0.0, 0.1, 0.0, 0.3]).is_err());
    }

    #[test]
    fn negative_mass_is_inconsistent() {
        let mut p = shifted(1.0, [0.0; 3], Matrix3::identity() * 0.01);
        p[9] = -0.2;
        let phys = LinkPhysics::from_params(&p);
        assert!(!phys.consistent && phys.com.is_none() && phys.min_eigenvalue < 0.0);
    }

    #[test]
    fn svec_map_reproduces_j_entries() {
        let p: LinkParams = [0.3, -0.02, 0.01, 0.25, 0.03, 0.1, 0.4, -0.1, 0.2, 2.5];
        let j = pseudo_inertia(&p);
        let v = svec_map() * SVector::<f64, 10>::from(p);
        for (k, &(r, c)) in SVEC_INDEX.iter().enumerate() {
            let scale = if r == c { 1.0 } else { SQRT2 };
            assert!((v[k] - scale * j[(r, c)]).abs() < 1e-15, "svec entry {k}");
        }
        assert!((smat(&v) - j).abs().max() < 1e-15);
        assert!((svec(&j) - v).abs().max() < 1e-15);
        // Isometry: svec(A)·svec(B) = tr(AB).
        let b = pseudo_inertia(&[1.0, 0.2, -0.3, 2.0, 0.1, 0.5, 0.3, 0.2, 0.1, 1.0]);
        assert!((svec(&j).dot(&svec(&b)) - (j * b).trace()).abs() < 1e-13);
        // The map is invertible (10 parameters ↔ 10 entries of a symmetric 4×4).
        assert!(svec_map().try_inverse().is_some());
    }

    #[test]
    fn basis_is_the_derivative() {
        let p: LinkParams = [0.3, -0.02, 0.01, 0.25, 0.03, 0.1, 0.4, -0.1, 0.2, 2.5];
        let basis = pseudo_inertia_basis();
        let sum = (0..10).fold(Matrix4::zeros(), |acc, k| acc + basis[k] * p[k]);
        assert!((sum - pseudo_inertia(&p)).abs().max() < 1e-15);
        let s = svec_map();
        for (k, b) in basis.iter().enumerate() {
            assert!((svec(b) - s.column(k)).abs().max() < 1e-15);
        }
    }
}
