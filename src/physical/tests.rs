//! Tests of the consistent identification, each against an oracle that does not go through the
//! barrier method: closed-form least squares, a projected-gradient solver in `J` space,
//! random feasible perturbations, and the cost of the known true parameters.

use nalgebra::{DMatrix, DVector, Matrix3, SymmetricEigen, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::consistent::ActiveConstraint;
use super::program::{ConsistentError, ConsistentProblem, EffectBound, Ellipsoid, Margin};
use super::pseudo_inertia::{pseudo_inertia, smat, svec, svec_map, LinkParams};
use super::synth;

/// A solid box's parameters about the link origin.
fn body(m: f64, c: [f64; 3], sides: [f64; 3]) -> LinkParams {
    let cv = Vector3::from(c);
    let ic = Matrix3::from_diagonal(&Vector3::new(
        sides[1].powi(2) + sides[2].powi(2),
        sides[0].powi(2) + sides[2].powi(2),
        sides[0].powi(2) + sides[1].powi(2),
    )) * (m / 12.0);
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

/// `AᵀA` of a random `rows × n` Gaussian matrix (well conditioned for rows ≫ n).
fn random_spd(n: usize, rows: usize, seed: u64) -> DMatrix<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let a = DMatrix::from_fn(rows, n, |_, _| rng.gen_range(-1.0..1.0));
    a.transpose() * a
}

/// Smallest eigenvalue of each link's `J` by nalgebra, relative to the largest.
fn relative_min_eigs(params: &DVector<f64>) -> Vec<f64> {
    (0..params.len() / 10)
        .map(|l| {
            let p: LinkParams = std::array::from_fn(|k| params[10 * l + k]);
            let ev = SymmetricEigen::new(pseudo_inertia(&p)).eigenvalues;
            ev.min() / ev.amax()
        })
        .collect()
}

/// The objective of the module docs, written out independently.
fn objective(pb: &ConsistentProblem, lambda: f64, x: &DVector<f64>) -> f64 {
    let n_pi = 10 * pb.n_links;
    let pi = x.rows(0, n_pi);
    let e = x.rows(n_pi, pb.n_effects);
    let nb = pb.base_map.nrows();
    let mut r = DVector::zeros(nb + pb.n_effects);
    r.rows_mut(0, nb).copy_from(&(&pb.base_map * pi));
    r.rows_mut(nb, pb.n_effects).copy_from(&e);
    r -= &pb.estimate;
    let prior = pb.prior.clone().unwrap_or_else(|| DVector::zeros(n_pi));
    let e_hat = pb.estimate.rows(nb, pb.n_effects);
    r.dot(&(&pb.normal * &r)) + lambda * ((pi - prior).norm_squared() + (e - e_hat).norm_squared())
}

fn stack(fit_params: &DVector<f64>, fit_effects: &DVector<f64>) -> DVector<f64> {
    DVector::from_iterator(
        fit_params.len() + fit_effects.len(),
        fit_params.iter().chain(fit_effects.iter()).copied(),
    )
}

#[test]
fn physical_estimate_is_returned() {
    // (a) ŷ from two physical bodies and positive effects, K = 1, N random SPD.
    let truth: Vec<f64> = body(2.0, [0.1, 0.0, 0.2], [0.3, 0.2, 0.1])
        .into_iter()
        .chain(body(0.7, [0.0, -0.1, 0.05], [0.1, 0.1, 0.3]))
        .chain([0.4, 1.2])
        .collect();
    let n = truth.len();
    let estimate = DVector::from_vec(truth);
    let normal = random_spd(n, 80, 1);
    let mut pb = ConsistentProblem::new(
        2,
        2,
        DMatrix::identity(20, 20),
        estimate.clone(),
        normal.clone(),
    );
    pb.nonneg = vec![0, 1];
    let fit = pb.solve().unwrap();
    // Oracle: with no constraint active the answer is the regularised least squares
    // (N + λ) y = N ŷ + λ [0; ê], solved by LU.
    let lambda = fit.weight;
    let mut target = DVector::zeros(n);
    target.rows_mut(20, 2).copy_from(&estimate.rows(20, 2));
    let oracle = (&normal + DMatrix::identity(n, n) * lambda)
        .lu()
        .solve(&(&normal * &estimate + target * lambda))
        .unwrap();
    let y = stack(&fit.params, &fit.effects);
    // The barrier's guarantee, checked with the oracle: f(y) − f(oracle) = (y − o)ᵀ(N + λ)(y − o)
    // for the quadratic f, and the reported gap bounds it.
    let dy = &y - &oracle;
    let excess = dy.dot(&((&normal + DMatrix::identity(n, n) * lambda) * &dy));
    let scale = estimate.dot(&(&normal * &estimate));
    assert!(
        excess <= fit.report.duality_gap + 1e-14 * scale,
        "{excess:e} > {:e}",
        fit.report.duality_gap
    );
    assert!(dy.amax() < 1e-6 * estimate.amax(), "{:e}", dy.amax());
    // And it is ŷ up to the regulariser's pull: |Δy| ≲ λ/λ_min(N)·|ŷ|.
    let lmin = normal.symmetric_eigenvalues().min();
    assert!((&y - &estimate).norm() <= 2.0 * lambda / lmin * estimate.norm());
    assert!(fit.active.is_empty(), "{:?}", fit.active);
    assert!(fit.links.iter().all(|l| l.consistent));
    assert!(fit.data_cost < 1e-10 * scale);
}

/// An independent solver for one link with `K = 1`: accelerated projected gradient (FISTA) in
/// `v = svec(J)`, where the projection onto the PSD cone is eigenvalue clipping.
fn projected_gradient(normal: &DMatrix<f64>, estimate: &DVector<f64>, lambda: f64) -> DVector<f64> {
    let s = DMatrix::from_iterator(10, 10, svec_map().iter().copied());
    let s_inv = s.clone().try_inverse().unwrap();
    // f(v) = (S⁻¹v − ŷ)ᵀN(S⁻¹v − ŷ) + λ‖S⁻¹v‖²; ∇f = 2 S⁻ᵀ((N + λ)S⁻¹v − Nŷ).
    let h = s_inv.transpose() * (normal + DMatrix::identity(10, 10) * lambda) * &s_inv * 2.0;
    let b = s_inv.transpose() * (normal * estimate) * 2.0;
    let step = 1.0 / h.symmetric_eigenvalues().max();
    let project = |v: &DVector<f64>| {
        let j = smat(&nalgebra::SVector::<f64, 10>::from_iterator(
            v.iter().copied(),
        ));
        let eig = SymmetricEigen::new(j);
        let clipped = eig.eigenvectors
            * nalgebra::Matrix4::from_diagonal(&eig.eigenvalues.map(|x| x.max(0.0)))
            * eig.eigenvectors.transpose();
        DVector::from_iterator(10, svec(&clipped).iter().copied())
    };
    let (mut v, mut w, mut t) = (DVector::zeros(10), DVector::zeros(10), 1.0_f64);
    for _ in 0..50_000 {
        let next = project(&(&w - (&h * &w - &b) * step));
        let t_next = (1.0 + (1.0 + 4.0 * t * t).sqrt()) / 2.0;
        w = &next + (&next - &v) * ((t - 1.0) / t_next);
        v = next;
        t = t_next;
    }
    s_inv * v
}

#[test]
fn negative_mass_is_projected_optimally() {
    // (b) One link, K = 1, N random SPD, ŷ a physical body with its mass made negative.
    let mut p = body(1.5, [0.1, 0.05, -0.1], [0.2, 0.3, 0.1]);
    p[9] = -0.2;
    let estimate = DVector::from_row_slice(&p);
    let normal = random_spd(10, 40, 2);
    let pb = ConsistentProblem::new(
        1,
        0,
        DMatrix::identity(10, 10),
        estimate.clone(),
        normal.clone(),
    );
    let fit = pb.solve().unwrap();
    let lambda = fit.weight;
    // Feasible by an independent eigen-solver.
    assert!(relative_min_eigs(&fit.params)[0] >= -1e-9);
    assert!(fit.links[0].mass >= 0.0);
    assert!(matches!(
        fit.active[..],
        [ActiveConstraint::Link { link: 0, .. }]
    ));
    // Optimal: no worse than an independent projected-gradient solution …
    let x = fit.params.clone();
    let f = objective(&pb, lambda, &x);
    let scale = estimate.dot(&(&normal * &estimate));
    let oracle = projected_gradient(&normal, &estimate, lambda);
    let f_oracle = objective(&pb, lambda, &oracle);
    assert!(relative_min_eigs(&oracle)[0] >= -1e-12);
    assert!(
        f <= f_oracle + 1e-9 * scale,
        "barrier {f:e} vs projected gradient {f_oracle:e}"
    );
    assert!((&x - &oracle).amax() < 1e-4 * estimate.amax());
    // … and random feasible points don't do better along the segment towards them (convexity:
    // a lower value anywhere would show up near x).
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for _ in 0..200 {
        let b = nalgebra::Matrix4::from_fn(|_, _| rng.gen_range(-1.0..1.0));
        let z: LinkParams = super::pseudo_inertia::params_from_pseudo_inertia(&(b * b.transpose()));
        let z = DVector::from_row_slice(&z);
        for s in [1e-4, 1e-2, 0.3] {
            let y = &x * (1.0 - s) + &z * s;
            assert!(objective(&pb, lambda, &y) >= f - 1e-9 * scale);
        }
    }
    assert!((fit.data_cost + fit.regulariser_cost - f).abs() <= 1e-12 * scale);
}

#[test]
fn negative_viscous_is_clamped_and_active() {
    // (c) One well-inside body and two effects: viscous (ŷ = −0.3) and Coulomb (ŷ = 0.8).
    // A large, round body: the shift of π that clamping e₀ causes through N's coupling
    // (~0.3 in each entry) leaves it well inside the physical set.
    let truth: Vec<f64> = body(20.0, [0.0, 0.1, 0.1], [1.0, 1.0, 1.0])
        .into_iter()
        .chain([-0.3, 0.8])
        .collect();
    let estimate = DVector::from_vec(truth);
    let normal = random_spd(12, 60, 4);
    let mut pb = ConsistentProblem::new(
        1,
        2,
        DMatrix::identity(10, 10),
        estimate.clone(),
        normal.clone(),
    );
    pb.nonneg = vec![0, 1];
    let fit = pb.solve().unwrap();
    // At the barrier's end the slack of an active bound is ~gap/(ν·multiplier): here ~1e-8.
    assert!(
        fit.effects[0] >= 0.0 && fit.effects[0] < 1e-6,
        "{}",
        fit.effects[0]
    );
    assert_eq!(
        fit.active,
        vec![ActiveConstraint::Lower {
            effect: 0,
            value: 0.0
        }]
    );
    // Oracle: the equality-constrained least squares with e₀ = 0 (the body stays inside):
    // minimise over the other 11 variables, a linear system.
    let lambda = fit.weight;
    let keep: Vec<usize> = (0..12).filter(|&i| i != 10).collect();
    let mut target = DVector::zeros(12);
    target[10] = estimate[10];
    target[11] = estimate[11];
    let h = &normal + DMatrix::identity(12, 12) * lambda;
    let rhs = &normal * &estimate + &target * lambda;
    let hk = DMatrix::from_fn(11, 11, |i, j| h[(keep[i], keep[j])]);
    let rk = DVector::from_fn(11, |i, _| rhs[keep[i]]);
    let z = hk.lu().solve(&rk).unwrap();
    let y = stack(&fit.params, &fit.effects);
    for (i, &k) in keep.iter().enumerate() {
        assert!(
            (y[k] - z[i]).abs() < 1e-7 * estimate.amax(),
            "variable {k}: {} vs {}",
            y[k],
            z[i]
        );
    }
}

/// One link and one effect with the crossed bounds `[0.6, 0.5]` on it.
fn small_problem() -> ConsistentProblem {
    let estimate =
        DVector::from_row_slice(&[0.1, 0.0, 0.0, 0.1, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0, 0.2]);
    let mut pb = ConsistentProblem::new(
        1,
        1,
        DMatrix::identity(10, 10),
        estimate,
        DMatrix::identity(11, 11),
    );
    pb.bounds = vec![EffectBound {
        effect: 0,
        lo: 0.6,
        hi: 0.5,
    }];
    pb
}

#[test]
fn bad_data_is_an_error_not_a_panic() {
    // (d)
    let base = small_problem;
    let err = base().solve().unwrap_err();
    assert!(
        matches!(err, ConsistentError::InfeasibleBounds { effect: 0, .. }),
        "{err}"
    );
    assert!(err.to_string().contains("lo < hi"));

    let mut pb = base();
    pb.bounds = vec![EffectBound {
        effect: 0,
        lo: -1.0,
        hi: -0.5,
    }];
    pb.nonneg = vec![0];
    let err = pb.solve().unwrap_err();
    assert!(err.to_string().contains("non-negative"), "{err}");

    let mut pb = base();
    pb.bounds.clear();
    pb.estimate[3] = f64::NAN;
    assert!(matches!(
        pb.solve(),
        Err(ConsistentError::NonFinite {
            what: "estimate",
            index: 3,
            ..
        })
    ));

    let mut pb = base();
    pb.estimate = DVector::zeros(7);
    assert!(matches!(pb.solve(), Err(ConsistentError::Dimension { .. })));

    let mut pb = base();
    pb.bounds.clear();
    pb.nonneg = vec![5];
    assert!(matches!(
        pb.solve(),
        Err(ConsistentError::EffectIndex { index: 5, .. })
    ));

    let mut pb = base();
    pb.bounds.clear();
    pb.normal[(0, 1)] = 0.5;
    assert!(matches!(
        pb.solve(),
        Err(ConsistentError::NotSymmetric { .. })
    ));
    pb.normal[(1, 0)] = 2.0;
    pb.normal[(0, 1)] = 2.0;
    assert!(matches!(
        pb.solve(),
        Err(ConsistentError::NotSemidefinite { .. })
    ));
}

#[test]
fn bad_options_are_errors_not_panics() {
    let base = small_problem;
    let estimate = base().estimate;
    let mut pb = base();
    pb.bounds.clear();
    let mut prior = estimate.rows(0, 10).into_owned();
    prior[9] = -0.2;
    pb.prior = Some(prior);
    let err = pb.solve().unwrap_err();
    assert!(err.to_string().contains("link 1 has mass -0.2 kg"), "{err}");

    let mut pb = base();
    pb.bounds.clear();
    pb.weight = Some(0.0);
    assert!(matches!(pb.solve(), Err(ConsistentError::Weight { .. })));
    pb.weight = None;
    pb.normal = DMatrix::zeros(11, 11);
    assert!(matches!(pb.solve(), Err(ConsistentError::NoData)));

    let mut pb = base();
    pb.bounds.clear();
    pb.ellipsoids = vec![Some(Ellipsoid {
        centre: [0.0; 3],
        semi_axes: [0.1, 0.0, 0.1],
    })];
    assert!(matches!(
        pb.solve(),
        Err(ConsistentError::Ellipsoid { link: 1, .. })
    ));
    pb.ellipsoids = vec![None, None];
    assert!(matches!(pb.solve(), Err(ConsistentError::Dimension { .. })));
    pb.ellipsoids.clear();
    pb.margin = Some(Margin {
        mass: -1.0,
        length: 0.1,
    });
    assert!(matches!(pb.solve(), Err(ConsistentError::Margin { .. })));

    let mut pb = base();
    pb.bounds.clear();
    for (gap_tol, max_iterations) in [(0.0, 10), (f64::NAN, 10), (1e-10, 0)] {
        pb.options = super::SolverOptions {
            gap_tol,
            max_iterations,
        };
        assert!(matches!(pb.solve(), Err(ConsistentError::Options { .. })));
    }
    pb.options = super::SolverOptions {
        gap_tol: 1e-10,
        max_iterations: 1,
    };
    assert!(matches!(
        pb.solve(),
        Err(ConsistentError::MaxIterations { .. })
    ));

    let mut pb = base();
    pb.n_links = usize::MAX;
    assert!(matches!(pb.solve(), Err(ConsistentError::Dimension { .. })));
}

/// Checks a synthetic 7-link solve: feasible by nalgebra's eigen-solver, bounds held, and no
/// costlier than the (feasible) truth.
fn check_seven_link(syn: &synth::Synthetic, fit: &super::ConsistentFit) {
    let pb = &syn.problem;
    assert!(relative_min_eigs(&fit.params).iter().all(|&e| e >= -1e-9));
    for (k, &e) in fit.effects.iter().enumerate() {
        assert!(e >= 0.0, "effect {k} = {e}");
        if k % 3 == 2 {
            assert!(e <= 0.5, "effect {k} = {e}");
        }
    }
    let truth = stack(&syn.params, &syn.effects);
    let f = fit.data_cost + fit.regulariser_cost;
    let f_truth = objective(pb, fit.weight, &truth);
    assert!(
        f <= f_truth + fit.report.duality_gap,
        "{f:e} > truth {f_truth:e}"
    );
    assert!(
        (f - objective(pb, fit.weight, &stack(&fit.params, &fit.effects))).abs()
            <= 1e-9 * f.max(1.0)
    );
}

#[test]
fn seven_link_problem_solves() {
    // (e) nb = 49, 21 effects, 2000 rows; noise large enough to make the estimate non-physical.
    let syn = synth::seven_link(2000, 3.0, 5);
    let fit = syn.problem.solve().unwrap();
    check_seven_link(&syn, &fit);
    assert!(fit.report.iterations < 300, "{:?}", fit.report);
    assert!(
        !fit.active.is_empty(),
        "noise should push something onto a constraint"
    );
}

#[test]
fn seven_link_with_margin_ellipsoids_and_prior() {
    let mut syn = synth::seven_link(2000, 3.0, 6);
    // Each true body fits a 0.6 m sphere about its centre of mass.
    let ellipsoids = (0..7)
        .map(|l| {
            let m = syn.params[10 * l + 9];
            let c = [0, 1, 2].map(|k| syn.params[10 * l + 6 + k] / m);
            Some(Ellipsoid {
                centre: c,
                semi_axes: [0.6; 3],
            })
        })
        .collect();
    syn.problem.ellipsoids = ellipsoids;
    syn.problem.margin = Some(Margin {
        mass: 0.01,
        length: 0.001,
    });
    let prior = syn.params.map(|v| v * 1.1);
    syn.problem.prior = Some(prior);
    let fit = syn.problem.solve().unwrap();
    check_seven_link(&syn, &fit);
    let e = super::consistent::margin_matrix(Margin {
        mass: 0.01,
        length: 0.001,
    });
    for l in 0..7 {
        let p: LinkParams = std::array::from_fn(|k| fit.params[10 * l + k]);
        let j = pseudo_inertia(&p);
        assert!(SymmetricEigen::new(j - e).eigenvalues.min() >= -1e-12);
        let q = super::consistent::ellipsoid_matrix(syn.problem.ellipsoids[l].unwrap());
        assert!((q * j).trace() >= -1e-12);
    }
}

#[test]
fn ill_conditioned_normal_matrix_is_equilibrated() {
    // Column scales over twelve decades (cond(N) ~ 1e24 before scaling).
    let mut syn = synth::seven_link(2000, 3.0, 7);
    let ny = syn.problem.normal.nrows();
    let d = DVector::from_fn(ny, |i, _| 10f64.powi((i % 13) as i32 - 6));
    // y' = y / d: N' = D N D, ŷ' = ŷ / d, K' = K / d (rows), e' = e / d.
    let pb = &mut syn.problem;
    pb.normal = DMatrix::from_fn(ny, ny, |i, j| pb.normal[(i, j)] * d[i] * d[j]);
    pb.estimate = pb.estimate.component_div(&d);
    let nb = pb.base_map.nrows();
    for r in 0..nb {
        let scale = 1.0 / d[r];
        pb.base_map.row_mut(r).scale_mut(scale);
    }
    // Effects are rescaled too: their bounds move with them (keep only the signs).
    pb.bounds.clear();
    pb.nonneg = (0..21).collect();
    syn.effects = syn.effects.component_div(&d.rows(nb, 21));
    let fit = syn.problem.solve().unwrap();
    assert!(relative_min_eigs(&fit.params).iter().all(|&e| e >= -1e-9));
    assert!(fit.effects.iter().all(|&e| e >= 0.0));
    let truth = stack(&syn.params, &syn.effects);
    let f = fit.data_cost + fit.regulariser_cost;
    assert!(f <= objective(&syn.problem, fit.weight, &truth) + fit.report.duality_gap);
}

#[test]
fn centre_of_mass_is_pulled_into_its_ellipsoid() {
    // A 2 kg point-ish body estimated at c = (0.5, 0, 0); the ellipsoid allows |x| ≤ 0.3.
    let estimate = DVector::from_row_slice(&body(2.0, [0.5, 0.0, 0.0], [0.05, 0.05, 0.05]));
    let normal = random_spd(10, 40, 8);
    let mut pb = ConsistentProblem::new(1, 0, DMatrix::identity(10, 10), estimate, normal);
    pb.ellipsoids = vec![Some(Ellipsoid {
        centre: [0.0; 3],
        semi_axes: [0.3, 0.2, 0.2],
    })];
    let fit = pb.solve().unwrap();
    let com = fit.links[0].com.unwrap();
    assert!(com[0] <= 0.3 + 1e-9, "{com:?}");
    assert!(
        fit.active
            .contains(&ActiveConstraint::Ellipsoid { link: 0 }),
        "{:?}",
        fit.active
    );
}

#[test]
fn module_doc_example_holds() {
    // The example of the module docs (doctests are not part of `cargo test --lib`).
    let estimate = DVector::from_vec(vec![0.02, 0.0, 0.0, 0.02, 0.0, 0.02, 0.0, 0.0, 0.0, -0.2]);
    let pb = ConsistentProblem::new(
        1,
        0,
        DMatrix::identity(10, 10),
        estimate,
        DMatrix::identity(10, 10),
    );
    let fit = pb.solve().unwrap();
    assert!(fit.links[0].consistent && fit.links[0].mass >= 0.0);
}

#[test]
fn degenerate_but_valid_problems_solve() {
    // Effects only, no constraint at all: the regularised least squares.
    let estimate = DVector::from_row_slice(&[0.3, -0.2]);
    let normal = random_spd(2, 10, 9);
    let pb = ConsistentProblem::new(0, 2, DMatrix::zeros(0, 0), estimate.clone(), normal);
    let fit = pb.solve().unwrap();
    assert!((&fit.effects - &estimate).amax() < 1e-5);
    assert!(fit.active.is_empty());
    // ŷ = 0 with one link: the answer is the empty body (J = 0, optimal cost 0), reached to
    // within the gap, which is all a zero optimum allows.
    let pb = ConsistentProblem::new(
        1,
        0,
        DMatrix::identity(10, 10),
        DVector::zeros(10),
        DMatrix::identity(10, 10),
    );
    let fit = pb.solve().unwrap();
    assert!(fit.data_cost + fit.regulariser_cost <= fit.report.duality_gap);
    assert!(fit.params.amax() < 1e-4, "{}", fit.params);
    // Enormous but finite bounds.
    let mut pb = ConsistentProblem::new(
        0,
        1,
        DMatrix::zeros(0, 0),
        DVector::from_element(1, 2.0),
        DMatrix::identity(1, 1),
    );
    pb.bounds = vec![EffectBound {
        effect: 0,
        lo: -f64::MAX,
        hi: f64::MAX,
    }];
    let fit = pb.solve().unwrap();
    assert!((fit.effects[0] - 2.0).abs() < 1e-5);
}
