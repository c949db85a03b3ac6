//! A log-barrier interior-point method (Boyd & Vandenberghe, *Convex Optimization*, §11.3) for
//! a strictly convex quadratic program whose constraints are 4×4 linear matrix inequalities in
//! the links' pseudo-inertias and scalar linear inequalities:
//!
//! ```text
//! minimise   ½ xᵀ P x + qᵀ x
//! subject to F_b(x) = J(x[s_b .. s_b+10]) − E_b ≻ 0      (each LMI block b)
//!            aᵢᵀ x − bᵢ > 0                                (each linear inequality i)
//! ```
//!
//! It follows the central path: for increasing `t` it minimises
//! `φ_t(x) = t·(½xᵀPx + qᵀx) − Σ_b log det F_b(x) − Σ_i log(aᵢᵀx − bᵢ)` by damped Newton
//! steps from a strictly feasible start, and stops when the barrier's duality-gap bound
//! `ν/t` (`ν = 4·#LMI + #linear`) is below the requested gap. Every iterate is strictly
//! feasible, so the returned point satisfies every constraint exactly (not just within a
//! solver tolerance), and its objective is within `ν/t` of the optimum.
//!
//! Numerics: each Newton system is equilibrated (symmetric Jacobi scaling to a unit diagonal)
//! before its Cholesky factorisation, so columns of very different scales (kg, kg·m², N·m·s)
//! cost no accuracy; a factorisation that still fails is retried with a tiny relative ridge.
//! The objective's change along a step is evaluated exactly from the quadratic
//! (`α gᵀd + ½α² dᵀPd`), not as a difference of two large values.
//!
//! Why not Clarabel: its positive-semidefinite cone needs the `sdp` feature, which links a
//! native BLAS/LAPACK (`blas-src`/`lapack-src`: OpenBLAS downloaded at build time, netlib built
//! with gfortran, MKL or Accelerate); none builds offline here. The problem has a strictly
//! feasible point by construction, so a primal barrier method needs no phase I and no
//! infeasibility detection, and its size (~100 variables) makes dense Newton steps cheap.

use nalgebra::{Cholesky, DMatrix, DVector, Matrix4};

use super::pseudo_inertia::{pseudo_inertia, pseudo_inertia_basis, LinkParams};
use super::spd::ScaledCholesky;

/// One LMI block: `J(x[start .. start+10]) − offset ≻ 0`.
#[derive(Debug, Clone)]
pub(crate) struct Lmi {
    pub start: usize,
    pub offset: Matrix4<f64>,
}

/// One linear inequality `Σ coef·x − rhs > 0`.
#[derive(Debug, Clone)]
pub(crate) struct Linear {
    pub coef: Vec<(usize, f64)>,
    pub rhs: f64,
}

/// The program (see the module docs). `p` must be symmetric positive definite.
#[derive(Debug, Clone)]
pub(crate) struct Program {
    pub p: DMatrix<f64>,
    pub q: DVector<f64>,
    pub lmis: Vec<Lmi>,
    pub linear: Vec<Linear>,
}

/// Stopping rules.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Settings {
    /// Absolute duality-gap target (objective units).
    pub gap: f64,
    /// Total Newton steps allowed.
    pub max_newton: usize,
}

/// A solution of [`solve`].
#[derive(Debug, Clone)]
pub(crate) struct Solution {
    pub x: DVector<f64>,
    /// The guaranteed bound on `f(x) − f*` (`ν/t` at the last centring).
    pub gap: f64,
    pub newton_steps: usize,
    pub centrings: usize,
}

/// Why [`solve`] stopped without a solution.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Failure {
    /// The start is not strictly feasible (a bug in the caller's start point).
    InfeasibleStart,
    /// `max_newton` steps were spent; `gap` is the bound reached.
    MaxIterations { steps: usize, gap: f64 },
    /// A Newton system could not be factorised or a step made no progress.
    Numerical(String),
}

/// Barrier value, gradient and Hessian at a strictly feasible point.
struct BarrierTerms {
    value: f64,
    grad: DVector<f64>,
    hess: DMatrix<f64>,
}

/// `log det F` of every LMI and `log` of every slack at `x`, or `None` when `x` is not strictly
/// feasible (a Cholesky factorisation fails or a slack is not positive).
fn barrier_value(prog: &Program, x: &DVector<f64>) -> Option<f64> {
    let mut value = 0.0;
    for lmi in &prog.lmis {
        let f = lmi_matrix(lmi, x);
        let chol = Cholesky::new(f)?;
        let l = chol.l_dirty();
        value -= 2.0 * (0..4).map(|k| l[(k, k)].ln()).sum::<f64>();
    }
    for lin in &prog.linear {
        let g = slack(lin, x);
        if g.is_nan() || g <= 0.0 {
            return None;
        }
        value -= g.ln();
    }
    value.is_finite().then_some(value)
}

fn lmi_matrix(lmi: &Lmi, x: &DVector<f64>) -> Matrix4<f64> {
    let p: LinkParams = std::array::from_fn(|k| x[lmi.start + k]);
    pseudo_inertia(&p) - lmi.offset
}

fn slack(lin: &Linear, x: &DVector<f64>) -> f64 {
    lin.coef.iter().map(|&(i, a)| a * x[i]).sum::<f64>() - lin.rhs
}

/// Value, gradient and Hessian of the barrier at a strictly feasible `x`.
fn barrier_terms(
    prog: &Program,
    x: &DVector<f64>,
    basis: &[Matrix4<f64>; 10],
) -> Option<BarrierTerms> {
    let n = x.len();
    let mut grad = DVector::zeros(n);
    let mut hess = DMatrix::zeros(n, n);
    let value = barrier_value(prog, x)?;
    for lmi in &prog.lmis {
        let finv = Cholesky::new(lmi_matrix(lmi, x))?.inverse();
        // ∂(−log det F)/∂x_k = −tr(F⁻¹A_k); ∂²/∂x_k∂x_l = tr(F⁻¹A_k F⁻¹A_l).
        let c: [Matrix4<f64>; 10] = std::array::from_fn(|k| finv * basis[k]);
        for k in 0..10 {
            grad[lmi.start + k] -= c[k].trace();
            for l in k..10 {
                let h = (c[k] * c[l]).trace();
                hess[(lmi.start + k, lmi.start + l)] += h;
                if l != k {
                    hess[(lmi.start + l, lmi.start + k)] += h;
                }
            }
        }
    }
    for lin in &prog.linear {
        let g = slack(lin, x);
        for &(i, a) in &lin.coef {
            grad[i] -= a / g;
            for &(j, b) in &lin.coef {
                hess[(i, j)] += a * b / (g * g);
            }
        }
    }
    Some(BarrierTerms { value, grad, hess })
}

/// Solves `H d = −g` for symmetric positive (semi)definite `H`, equilibrated to a unit
/// diagonal; retries with a growing relative ridge when the factorisation fails.
fn newton_direction(hess: &DMatrix<f64>, grad: &DVector<f64>) -> Result<DVector<f64>, Failure> {
    const RIDGES: [f64; 5] = [0.0, 1e-14, 1e-12, 1e-10, 1e-8];
    ScaledCholesky::new(hess, &RIDGES)
        .and_then(|chol| chol.solve(&-grad))
        .ok_or_else(|| {
            Failure::Numerical(
                "the Newton system is not positive definite even with a ridge".into(),
            )
        })
}

/// Barrier parameter `ν`: the sum of the constraints' degrees (4 per LMI, 1 per inequality).
pub(crate) fn barrier_degree(prog: &Program) -> f64 {
    (4 * prog.lmis.len() + prog.linear.len()) as f64
}

/// Solves the program from the strictly feasible `x0` (see the module docs). `t0` is the first
/// barrier weight (`ν / t0` should be about the start's sub-optimality).
pub(crate) fn solve(
    prog: &Program,
    x0: DVector<f64>,
    t0: f64,
    settings: Settings,
) -> Result<Solution, Failure> {
    /// Barrier weight growth between centrings (B&V recommend 10–20; fewer centrings for more
    /// Newton steps each).
    const MU: f64 = 20.0;
    let basis = pseudo_inertia_basis();
    if barrier_value(prog, &x0).is_none() {
        return Err(Failure::InfeasibleStart);
    }
    let nu = barrier_degree(prog);
    // ν = 0 (no constraint): one Newton step is exact, any t will do.
    let t_final = nu.max(1.0) / settings.gap;
    if !(t_final.is_finite() && t_final > 0.0) {
        return Err(Failure::Numerical(format!(
            "the duality-gap target {:e} is not a positive number",
            settings.gap
        )));
    }
    let mut t = if t0.is_finite() && t0 > 0.0 {
        t0.min(t_final)
    } else {
        t_final
    };
    let mut x = x0;
    let mut steps = 0;
    let mut centrings = 0;
    loop {
        steps += centre(
            prog,
            &mut x,
            t,
            &basis,
            settings.max_newton - steps.min(settings.max_newton),
        )
        .map_err(|f| match f {
            Failure::MaxIterations { .. } => Failure::MaxIterations {
                steps: settings.max_newton,
                gap: nu / t,
            },
            other => other,
        })?;
        centrings += 1;
        if t >= t_final {
            return Ok(Solution {
                x,
                gap: nu / t,
                newton_steps: steps,
                centrings,
            });
        }
        t = (t * MU).min(t_final);
    }
}

/// Newton's method on `φ_t` from the strictly feasible `x` (updated in place); returns the
/// number of steps taken, at most `budget`.
fn centre(
    prog: &Program,
    x: &mut DVector<f64>,
    t: f64,
    basis: &[Matrix4<f64>; 10],
    budget: usize,
) -> Result<usize, Failure> {
    /// Centring stops when half the squared Newton decrement (`φ_t(x) − min φ_t` to second
    /// order) is below this: far below the gap target's ν/t once multiplied out.
    const DECREMENT: f64 = 1e-10;
    /// Armijo sufficient-decrease fraction and step shrink factor (B&V §9.2).
    const ARMIJO: f64 = 0.25;
    const SHRINK: f64 = 0.5;
    let mut steps = 0;
    loop {
        let terms = barrier_terms(prog, x, basis).ok_or(Failure::InfeasibleStart)?;
        let obj_grad = &prog.p * &*x + &prog.q;
        let grad = &obj_grad * t + &terms.grad;
        let hess = &prog.p * t + &terms.hess;
        let d = newton_direction(&hess, &grad)?;
        let slope = grad.dot(&d);
        if -slope / 2.0 <= DECREMENT {
            return Ok(steps);
        }
        if steps >= budget {
            return Err(Failure::MaxIterations { steps, gap: 0.0 });
        }
        let obj_slope = obj_grad.dot(&d);
        let curvature = d.dot(&(&prog.p * &d));
        let mut alpha = 1.0;
        loop {
            let trial = &*x + &d * alpha;
            if let Some(b) = barrier_value(prog, &trial) {
                let change =
                    t * (alpha * obj_slope + 0.5 * alpha * alpha * curvature) + (b - terms.value);
                if change <= ARMIJO * alpha * slope {
                    *x = trial;
                    break;
                }
            }
            alpha *= SHRINK;
            if alpha < 1e-16 {
                // No decrease along a descent direction: the decrement is at rounding level.
                if -slope / 2.0 <= 1e-6 {
                    return Ok(steps);
                }
                return Err(Failure::Numerical(format!(
                    "line search failed (Newton decrement² {:.3e})",
                    -slope
                )));
            }
        }
        steps += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// min ½(x − 2)² s.t. x > 1 (an inactive bound) and min ½(x + 2)² s.t. x > 1 (active).
    #[test]
    fn scalar_bound_active_and_inactive() {
        for (target, expect) in [(2.0, 2.0), (-2.0, 1.0)] {
            let prog = Program {
                p: DMatrix::from_element(1, 1, 1.0),
                q: DVector::from_element(1, -target),
                lmis: vec![],
                linear: vec![Linear {
                    coef: vec![(0, 1.0)],
                    rhs: 1.0,
                }],
            };
            let settings = Settings {
                gap: 1e-12,
                max_newton: 200,
            };
            let sol = solve(&prog, DVector::from_element(1, 1.5), 1.0, settings).unwrap();
            assert!((sol.x[0] - expect).abs() < 1e-6, "{} vs {expect}", sol.x[0]);
            assert!(sol.x[0] > 1.0);
        }
    }

    #[test]
    fn infeasible_start_is_reported() {
        let prog = Program {
            p: DMatrix::identity(10, 10),
            q: DVector::zeros(10),
            lmis: vec![Lmi {
                start: 0,
                offset: Matrix4::zeros(),
            }],
            linear: vec![],
        };
        let settings = Settings {
            gap: 1e-9,
            max_newton: 10,
        };
        let err = solve(&prog, DVector::zeros(10), 1.0, settings).unwrap_err();
        assert_eq!(err, Failure::InfeasibleStart);
    }
}
