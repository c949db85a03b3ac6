//! The consistent fit's inputs — the problem, its bounds, margin, ellipsoids and solver options —
//! and the errors that say what to change in them. Checked by `validate.rs`, solved by
//! [`super::consistent`].

use nalgebra::{DMatrix, DVector};

/// Bounds on one effect coefficient (either side may be infinite).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EffectBound {
    /// Index into `e`.
    pub effect: usize,
    pub lo: f64,
    pub hi: f64,
}

/// A margin inside the physical set: `J ⪰ mass·diag(length², length², length², 1)`, i.e. the
/// link is at least a body of `mass` kg spread over `±length` m about its frame origin, plus a
/// physical remainder. Both must be finite and `≥ 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Margin {
    /// kg.
    pub mass: f64,
    /// m.
    pub length: f64,
}

/// A bounding ellipsoid in the link frame, axis-aligned: the link's mass must lie within
/// `Σ_k ((p_k − centre_k)/semi_axes_k)² ≤ 1` (as a density, Wensing et al.'s necessary condition
/// `tr(Q J) ≥ 0`, `Q = [[−R⁻², R⁻²c], [cᵀR⁻², 1 − cᵀR⁻²c]]`, `R = diag(semi_axes)`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ellipsoid {
    /// m.
    pub centre: [f64; 3],
    /// m, each finite and `> 0`.
    pub semi_axes: [f64; 3],
}

/// Stopping rules of the interior-point method.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverOptions {
    /// Target duality gap relative to `ŷᵀNŷ` (the data cost of `y = 0`; the start's cost if
    /// that is larger, e.g. for `ŷ = 0`). Finite and `> 0`; default `1e-10`.
    pub gap_tol: f64,
    /// Newton steps allowed in total. Default 500 (problems of 7 links take ~60–120).
    pub max_iterations: usize,
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions {
            gap_tol: 1e-10,
            max_iterations: 500,
        }
    }
}

/// The inputs (see the module docs). Build with [`ConsistentProblem::new`], then set the
/// optional fields.
#[derive(Debug, Clone)]
pub struct ConsistentProblem {
    pub n_links: usize,
    pub n_effects: usize,
    /// `K`, `nb × 10·n_links`: `θ = K·π`.
    pub base_map: DMatrix<f64>,
    /// `ŷ = [θ̂; ê]`, length `nb + n_effects`.
    pub estimate: DVector<f64>,
    /// `N = AᵀWA` over `y`, `(nb + n_effects)²`, symmetric positive semidefinite.
    pub normal: DMatrix<f64>,
    /// Effects constrained `≥ 0` (viscous, Coulomb, rotor inertia).
    pub nonneg: Vec<usize>,
    /// Effects with bounds (e.g. load-dependent friction `[0, 0.5]`).
    pub bounds: Vec<EffectBound>,
    /// `π₀`, length `10·n_links`; must be physically consistent. `None`: pull towards 0.
    pub prior: Option<DVector<f64>>,
    /// `λ`; `None`: [`ConsistentProblem::default_weight`].
    pub weight: Option<f64>,
    pub margin: Option<Margin>,
    /// Empty, or one entry per link.
    pub ellipsoids: Vec<Option<Ellipsoid>>,
    pub options: SolverOptions,
}

/// Why a problem cannot be solved, with what to change.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConsistentError {
    #[error("{what} is {found} but the problem needs {expected} — {hint}")]
    Dimension {
        what: &'static str,
        expected: String,
        found: String,
        hint: &'static str,
    },
    #[error("{what}[{index}] is {value} — every input must be a finite number; check the data or file that produced it")]
    NonFinite {
        what: &'static str,
        index: usize,
        value: f64,
    },
    #[error("the normal matrix is not symmetric (N[{row}][{col}] = {a:e} but N[{col}][{row}] = {b:e}) — pass N = AᵀWA itself, not a factor or a partly updated copy")]
    NotSymmetric {
        row: usize,
        col: usize,
        a: f64,
        b: f64,
    },
    #[error("the normal matrix is not positive semidefinite (eigenvalue {eigenvalue:e} after scaling to a unit diagonal) — it must be AᵀWA with non-negative weights W; rebuild it from the regressor")]
    NotSemidefinite { eigenvalue: f64 },
    #[error(
        "the normal matrix is zero — there is no data to fit; check that the regressor has rows"
    )]
    NoData,
    #[error("effect index {index} in {which} is out of range — the problem has {n_effects} effects (indices 0..{n_effects})")]
    EffectIndex {
        which: &'static str,
        index: usize,
        n_effects: usize,
    },
    #[error("effect {effect}: the bounds leave no room (lower limit {lo}, upper limit {hi}{nonneg}) — give lo < hi, or drop the bound{drop_nonneg}")]
    InfeasibleBounds {
        effect: usize,
        lo: f64,
        hi: f64,
        nonneg: &'static str,
        drop_nonneg: &'static str,
    },
    #[error("regularisation weight {value} is not usable — it must be finite and > 0 (leave it unset for the default 1e-6·tr(N)/dim)")]
    Weight { value: f64 },
    #[error("the prior is not physically consistent: link {link} {detail}; fix the prior or drop it (--prior)")]
    PriorNotPhysical { link: usize, detail: String },
    #[error("solver option {detail} — gap_tol must be finite and > 0 (default 1e-10), max_iterations >= 1 (default 500)")]
    Options { detail: String },
    #[error(
        "margin (mass {mass} kg, length {length} m) is not usable — both must be finite and >= 0"
    )]
    Margin { mass: f64, length: f64 },
    #[error("link {link}: bounding ellipsoid {detail} — the centre must be finite and each semi-axis finite and > 0 (m)")]
    Ellipsoid { link: usize, detail: String },
    #[error("the interior-point method did not converge in {iterations} Newton steps (duality gap {gap:e}, target {target:e}) — raise options.max_iterations or options.gap_tol; if it persists, N is too ill-conditioned: drop unexcited columns or raise the weight")]
    MaxIterations {
        iterations: usize,
        gap: f64,
        target: f64,
    },
    #[error("numerical failure in the interior-point method ({detail}) — N is too ill-conditioned even after equilibration: drop unexcited columns, or raise the regularisation weight")]
    Numerical { detail: String },
}
