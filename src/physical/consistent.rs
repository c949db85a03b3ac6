//! Physically consistent identification: the closest parameters, in the least-squares metric,
//! whose every link is a possible rigid body.
//!
//! **Variables.** `π` (`10·n_links` standard parameters, dynid's order per link, see
//! [`super::pseudo_inertia`](mod@super::pseudo_inertia)) and `e` (`n_effects` effect coefficients). The least-squares fit
//! is over `y = [θ; e]` with base parameters `θ = K·π` (`K` = [`ConsistentProblem::base_map`]).
//!
//! **Program** (Wensing, Kim & Slotine, IEEE RA-L 2017, with the effects of the friction model):
//!
//! ```text
//! minimise   (y − ŷ)ᵀ N (y − ŷ) + λ‖π − π₀‖² + λ‖e − ê‖²      y = [Kπ; e]
//! subject to J_l(π) − E ⪰ 0                 each link l   (E = margin, 0 by default)
//!            tr(Q_l J_l(π)) ≥ 0             links with a bounding ellipsoid
//!            lo_k ≤ e_k ≤ hi_k, e_k ≥ 0      bounded / non-negative effects
//! ```
//!
//! `(y − ŷ)ᵀN(y − ŷ)` is exactly how much the (weighted) least-squares residual grows over the
//! unconstrained optimum `ŷ` (`N = AᵀWA`). The regulariser makes the program strictly convex:
//! `K` has a null space (parameters regrouped into base parameters, or not identifiable at all),
//! along which `π` is decided by the pull towards the prior `π₀` (`0` without a prior); the
//! effects are pulled towards their own estimate `ê`, which changes nothing unless an effect is
//! unexcited (`N` singular there) or bounded. The default weight is
//! `λ = 1e-6·tr(N)/dim(N)`: a millionth of the average curvature of the data cost, so it is
//! unit-free with respect to the data's scaling and moves a well-determined direction of `y`
//! by about a millionth (relative) of its value.
//!
//! **Solver**: the log-barrier interior-point method of `super::barrier` (pure Rust, dense
//! Newton steps equilibrated internally). Every link of the answer satisfies `J ⪰ E` exactly,
//! and the answer's cost is within [`SolveReport::duality_gap`] of the optimum
//! (`≤ gap_tol·ŷᵀNŷ`).

use std::time::{Duration, Instant};

use nalgebra::{DMatrix, DVector, Matrix4, SymmetricEigen};

use super::barrier::{self, Failure, Linear, Lmi, Program, Settings};
use super::program::{ConsistentError, ConsistentProblem, Ellipsoid, Margin, SolverOptions};
use super::pseudo_inertia::{
    pseudo_inertia, pseudo_inertia_basis, relative_min_eigenvalue, svec, svec_map, LinkParams,
    LinkPhysics,
};
use super::spd::ScaledCholesky;
use super::start::{effect_start, link_start};

/// A constraint that holds with equality at the answer.
///
/// "With equality" means within the solver's resolution: a scalar constraint `g = aᵀx − b ≥ 0`
/// counts as active when its slack is at most `√(2·gap·aᵀP⁻¹a)`, the change of `g` whose
/// cheapest cost under the objective's curvature `P` (`½δ²/(aᵀP⁻¹a)`) equals the duality gap —
/// below it the solver cannot tell the slack from zero; an active constraint ends far below it
/// (its slack falls like `1/t`, the resolution like `1/√t`). A link's constraint uses the same
/// rule for the smallest eigenvalue `σ` of `J − E`, whose derivative along `x` is
/// `a_k = vᵀ(∂J/∂x_k)v` (`v` its eigenvector).
#[derive(Debug, Clone, PartialEq)]
pub enum ActiveConstraint {
    /// Link `link` (0-based) is on the boundary of the physical set: the smallest eigenvalue
    /// of its `J − E` is within the solver's resolution of 0. `relative_eigenvalue` is that
    /// eigenvalue normalised as [`LinkPhysics::relative_min_eigenvalue`].
    Link {
        link: usize,
        relative_eigenvalue: f64,
    },
    /// Link `link`'s mass touches its bounding ellipsoid.
    Ellipsoid { link: usize },
    /// Effect `effect` sits at its lower limit `value`.
    Lower { effect: usize, value: f64 },
    /// Effect `effect` sits at its upper limit `value`.
    Upper { effect: usize, value: f64 },
}

/// How the solve went (a returned fit is always solved to the gap target).
#[derive(Debug, Clone, PartialEq)]
pub struct SolveReport {
    /// Newton steps.
    pub iterations: usize,
    /// Points of the central path visited.
    pub centrings: usize,
    /// Guaranteed bound on `cost − optimal cost` (same units as the costs).
    pub duality_gap: f64,
    pub solve_time: Duration,
}

/// The answer.
#[derive(Debug, Clone)]
pub struct ConsistentFit {
    /// `π`, `10·n_links`.
    pub params: DVector<f64>,
    /// `e`, `n_effects`.
    pub effects: DVector<f64>,
    /// `y = [Kπ; e]`.
    pub fitted: DVector<f64>,
    /// `(y − ŷ)ᵀN(y − ŷ)`: the least-squares residual increase.
    pub data_cost: f64,
    /// `λ‖π − π₀‖² + λ‖e − ê‖²`.
    pub regulariser_cost: f64,
    /// The `λ` used.
    pub weight: f64,
    pub links: Vec<LinkPhysics>,
    pub active: Vec<ActiveConstraint>,
    pub report: SolveReport,
}

/// The assembled program plus what the report needs.
pub(crate) struct Assembled {
    pub program: Program,
    /// Regularisation target `x₀ = [π₀; ê]`.
    pub target: DVector<f64>,
    pub lambda: f64,
    /// Per effect: `[lower, upper]` after merging `nonneg` and `bounds`.
    pub limits: Vec<(f64, f64)>,
    /// Margin matrix `E` and the ellipsoid `Q` of each link.
    pub margin: Matrix4<f64>,
    pub ellipsoid_q: Vec<Option<Matrix4<f64>>>,
    /// `ŷᵀNŷ` (objective scale).
    pub scale: f64,
}

impl ConsistentProblem {
    /// A problem with no bounds, no prior, the default weight, no margin and no ellipsoids.
    pub fn new(
        n_links: usize,
        n_effects: usize,
        base_map: DMatrix<f64>,
        estimate: DVector<f64>,
        normal: DMatrix<f64>,
    ) -> Self {
        ConsistentProblem {
            n_links,
            n_effects,
            base_map,
            estimate,
            normal,
            nonneg: Vec::new(),
            bounds: Vec::new(),
            prior: None,
            weight: None,
            margin: None,
            ellipsoids: Vec::new(),
            options: SolverOptions::default(),
        }
    }

    /// `1e-6·tr(N)/dim(N)` (0 for an empty or zero `N`).
    pub fn default_weight(&self) -> f64 {
        let dim = self.normal.nrows().max(1) as f64;
        1e-6 * self.normal.trace() / dim
    }

    /// Solves the program (see the module docs). Never panics on bad input: every problem is an
    /// [`ConsistentError`] saying what to change.
    pub fn solve(&self) -> Result<ConsistentFit, ConsistentError> {
        let clock = Instant::now();
        super::validate::validate(self)?;
        let asm = self.assemble()?;
        let n_pi = 10 * self.n_links;
        let x_start = self.start(&asm)?;
        let (data_start, reg_start) = self.cost(&asm, &x_start);
        let f_start = data_start + reg_start;
        // Objective scale: ŷᵀNŷ, or the start's cost (or λ) when ŷ = 0.
        let gap = self.options.gap_tol * asm.scale.max(f_start).max(asm.lambda);
        let nu = barrier::barrier_degree(&asm.program).max(1.0);
        let settings = Settings {
            gap,
            max_newton: self.options.max_iterations,
        };
        let sol = barrier::solve(&asm.program, x_start, nu / f_start.max(gap), settings).map_err(
            |f| match f {
                Failure::MaxIterations {
                    steps,
                    gap: reached,
                } => ConsistentError::MaxIterations {
                    iterations: steps,
                    gap: reached,
                    target: gap,
                },
                Failure::Numerical(detail) => ConsistentError::Numerical { detail },
                Failure::InfeasibleStart => ConsistentError::Numerical {
                    detail: "the start point is not strictly feasible (data of extreme scale?)"
                        .into(),
                },
            },
        )?;
        let (data_cost, regulariser_cost) = self.cost(&asm, &sol.x);
        let params = sol.x.rows(0, n_pi).into_owned();
        let effects = sol.x.rows(n_pi, self.n_effects).into_owned();
        let links = (0..self.n_links)
            .map(|l| LinkPhysics::from_params(&link_params(&sol.x, l)))
            .collect();
        let active = self.active_constraints(&asm, &sol.x, sol.gap);
        Ok(ConsistentFit {
            fitted: self.fitted(&params, &effects),
            params,
            effects,
            data_cost,
            regulariser_cost,
            weight: asm.lambda,
            links,
            active,
            report: SolveReport {
                iterations: sol.newton_steps,
                centrings: sol.centrings,
                duality_gap: sol.gap,
                solve_time: clock.elapsed(),
            },
        })
    }

    /// `y = [Kπ; e]`.
    pub fn fitted(&self, params: &DVector<f64>, effects: &DVector<f64>) -> DVector<f64> {
        let theta = &self.base_map * params;
        DVector::from_iterator(
            theta.len() + effects.len(),
            theta.iter().chain(effects.iter()).copied(),
        )
    }

    /// `(data cost, regulariser cost)` of `x = [π; e]`, computed from the residual (no
    /// cancellation between large terms).
    pub(crate) fn cost(&self, asm: &Assembled, x: &DVector<f64>) -> (f64, f64) {
        let n_pi = 10 * self.n_links;
        let y = self.fitted(
            &x.rows(0, n_pi).into_owned(),
            &x.rows(n_pi, self.n_effects).into_owned(),
        );
        let r = y - &self.estimate;
        let data = r.dot(&(&self.normal * &r)).max(0.0);
        let reg = asm.lambda * (x - &asm.target).norm_squared();
        (data, reg)
    }

    /// The program's `P`, `q`, constraints, and the scales the report uses.
    fn assemble(&self) -> Result<Assembled, ConsistentError> {
        let n_pi = 10 * self.n_links;
        let nb = self.base_map.nrows();
        let n = n_pi + self.n_effects;
        let normal = (&self.normal + self.normal.transpose()) * 0.5;
        let lambda = match self.weight {
            Some(w) => w,
            None => self.default_weight(),
        };
        if !(lambda.is_finite() && lambda > 0.0) {
            return Err(match self.weight {
                Some(value) => ConsistentError::Weight { value },
                None => ConsistentError::NoData,
            });
        }
        // G = blockdiag(K, I): y = G x. P = 2(GᵀNG + λI), q = −2(GᵀNŷ + λx₀).
        let mut g = DMatrix::zeros(nb + self.n_effects, n);
        g.view_mut((0, 0), (nb, n_pi)).copy_from(&self.base_map);
        for k in 0..self.n_effects {
            g[(nb + k, n_pi + k)] = 1.0;
        }
        let gt_n = g.transpose() * &normal;
        let mut p = &gt_n * &g * 2.0;
        for i in 0..n {
            p[(i, i)] += 2.0 * lambda;
        }
        let mut target = DVector::zeros(n);
        if let Some(prior) = &self.prior {
            target.rows_mut(0, n_pi).copy_from(prior);
        }
        target
            .rows_mut(n_pi, self.n_effects)
            .copy_from(&self.estimate.rows(nb, self.n_effects));
        let q = -(&gt_n * &self.estimate + &target * lambda) * 2.0;
        let limits = self.limits()?;
        let margin = match self.margin {
            Some(m) => margin_matrix(m),
            None => Matrix4::zeros(),
        };
        let ellipsoid_q: Vec<Option<Matrix4<f64>>> = (0..self.n_links)
            .map(|l| {
                self.ellipsoids
                    .get(l)
                    .copied()
                    .flatten()
                    .map(ellipsoid_matrix)
            })
            .collect();
        let program = Program {
            p,
            q,
            lmis: (0..self.n_links)
                .map(|l| Lmi {
                    start: 10 * l,
                    offset: margin,
                })
                .collect(),
            linear: linear_constraints(&limits, &ellipsoid_q, n_pi),
        };
        let scale = self.estimate.dot(&(&normal * &self.estimate));
        Ok(Assembled {
            program,
            target,
            lambda,
            limits,
            margin,
            ellipsoid_q,
            scale,
        })
    }

    /// Per effect `[lower, upper]`: the intersection of `nonneg` and `bounds`.
    fn limits(&self) -> Result<Vec<(f64, f64)>, ConsistentError> {
        let mut limits = vec![(f64::NEG_INFINITY, f64::INFINITY); self.n_effects];
        let mut is_nonneg = vec![false; self.n_effects];
        for &k in &self.nonneg {
            limits[k].0 = limits[k].0.max(0.0);
            is_nonneg[k] = true;
        }
        for b in &self.bounds {
            let l = &mut limits[b.effect];
            *l = (l.0.max(b.lo), l.1.min(b.hi));
        }
        for (k, &(lo, hi)) in limits.iter().enumerate() {
            if lo >= hi {
                let nn = is_nonneg[k];
                return Err(ConsistentError::InfeasibleBounds {
                    effect: k,
                    lo,
                    hi,
                    nonneg: if nn {
                        ", with the effect also non-negative"
                    } else {
                        ""
                    },
                    drop_nonneg: if nn { " or its non-negativity" } else { "" },
                });
            }
        }
        Ok(limits)
    }

    /// A strictly feasible start near the regularised unconstrained minimiser.
    fn start(&self, asm: &Assembled) -> Result<DVector<f64>, ConsistentError> {
        let p = &asm.program.p;
        let unconstrained = super::start::unconstrained(p, &asm.program.q).ok_or_else(|| {
            ConsistentError::Numerical {
                detail: "the regularised normal matrix cannot be factorised".into(),
            }
        })?;
        let n_pi = 10 * self.n_links;
        let mut x = unconstrained.clone();
        for l in 0..self.n_links {
            let p0 = link_params(&unconstrained, l);
            let start = link_start(&p0, &asm.margin, asm.ellipsoid_q[l].as_ref());
            x.rows_mut(10 * l, 10).copy_from_slice(&start);
        }
        for (k, &limits) in asm.limits.iter().enumerate() {
            let i = n_pi + k;
            // Natural scale of e_k: the change that costs as much as the whole data.
            let natural = (2.0 * asm.scale.max(f64::MIN_POSITIVE) / p[(i, i)]).sqrt();
            x[i] = effect_start(unconstrained[i], limits, natural);
        }
        Ok(x)
    }

    /// The constraints that hold with equality at `x` (see [`ActiveConstraint`]).
    fn active_constraints(
        &self,
        asm: &Assembled,
        x: &DVector<f64>,
        gap: f64,
    ) -> Vec<ActiveConstraint> {
        let n_pi = 10 * self.n_links;
        // P is positive definite (λ > 0): this succeeds whenever the solve did.
        let Some(chol) = ScaledCholesky::new(&asm.program.p, &[0.0, 1e-12]) else {
            return Vec::new();
        };
        let resolution = |coef: &[(usize, f64)]| {
            let mut a = DVector::zeros(x.len());
            for &(i, v) in coef {
                a[i] += v;
            }
            chol.solve(&a)
                .map_or(0.0, |w| (2.0 * gap * a.dot(&w)).max(0.0).sqrt())
        };
        let basis = pseudo_inertia_basis();
        let mut active = Vec::new();
        for l in 0..self.n_links {
            let j = pseudo_inertia(&link_params(x, l));
            let f = j - asm.margin;
            let eig = SymmetricEigen::new(f);
            let (imin, sigma) = eig.eigenvalues.argmin();
            let v = eig.eigenvectors.column(imin);
            let coef: Vec<(usize, f64)> = (0..10)
                .map(|k| (10 * l + k, (v.transpose() * basis[k] * v)[(0, 0)]))
                .collect();
            if sigma <= resolution(&coef) {
                active.push(ActiveConstraint::Link {
                    link: l,
                    relative_eigenvalue: relative_min_eigenvalue(&f),
                });
            }
            if let Some(q) = &asm.ellipsoid_q[l] {
                if (q * j).trace() <= resolution(&ellipsoid_coef(q, l)) {
                    active.push(ActiveConstraint::Ellipsoid { link: l });
                }
            }
        }
        for (k, &(lo, hi)) in asm.limits.iter().enumerate() {
            let i = n_pi + k;
            let res = resolution(&[(i, 1.0)]);
            if x[i] - lo <= res {
                active.push(ActiveConstraint::Lower {
                    effect: k,
                    value: lo,
                });
            }
            if hi - x[i] <= res {
                active.push(ActiveConstraint::Upper {
                    effect: k,
                    value: hi,
                });
            }
        }
        active
    }
}

/// Link `l`'s 10 parameters from `x = [π; e]`.
pub(crate) fn link_params(x: &DVector<f64>, l: usize) -> LinkParams {
    std::array::from_fn(|k| x[10 * l + k])
}

/// `E = mass·diag(length², length², length², 1)`.
pub(crate) fn margin_matrix(m: Margin) -> Matrix4<f64> {
    let l2 = m.length * m.length;
    Matrix4::from_diagonal(&nalgebra::Vector4::new(l2, l2, l2, 1.0)) * m.mass
}

/// `Q = [[−R⁻², R⁻²c], [cᵀR⁻², 1 − cᵀR⁻²c]]` (see [`Ellipsoid`]).
pub(crate) fn ellipsoid_matrix(e: Ellipsoid) -> Matrix4<f64> {
    let mut q = Matrix4::zeros();
    let mut quad = 0.0;
    for k in 0..3 {
        let w = 1.0 / (e.semi_axes[k] * e.semi_axes[k]);
        q[(k, k)] = -w;
        q[(k, 3)] = w * e.centre[k];
        q[(3, k)] = w * e.centre[k];
        quad += w * e.centre[k] * e.centre[k];
    }
    q[(3, 3)] = 1.0 - quad;
    q
}

/// The scalar inequalities: effect limits and ellipsoids (`tr(QJ) = svec(Q)ᵀ S π ≥ 0`).
fn linear_constraints(
    limits: &[(f64, f64)],
    ellipsoid_q: &[Option<Matrix4<f64>>],
    n_pi: usize,
) -> Vec<Linear> {
    let mut linear = Vec::new();
    for (k, &(lo, hi)) in limits.iter().enumerate() {
        if lo.is_finite() {
            linear.push(Linear {
                coef: vec![(n_pi + k, 1.0)],
                rhs: lo,
            });
        }
        if hi.is_finite() {
            linear.push(Linear {
                coef: vec![(n_pi + k, -1.0)],
                rhs: -hi,
            });
        }
    }
    for (l, q) in ellipsoid_q.iter().enumerate() {
        if let Some(q) = q {
            linear.push(Linear {
                coef: ellipsoid_coef(q, l),
                rhs: 0.0,
            });
        }
    }
    linear
}

/// `tr(Q J_l) = svec(Q)ᵀ S π_l` as coefficients on `x` (`S` = [`svec_map`]).
fn ellipsoid_coef(q: &Matrix4<f64>, l: usize) -> Vec<(usize, f64)> {
    let a = svec_map().transpose() * svec(q);
    (0..10).map(|k| (10 * l + k, a[k])).collect()
}
