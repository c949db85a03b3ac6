//! Physically consistent identification: least-squares estimates pulled into the set of
//! parameters that real rigid bodies can have.
//!
//! | file | what |
//! |---|---|
//! | [`pseudo_inertia`](mod@pseudo_inertia) | one link's 4×4 pseudo-inertia `J`, its `svec`, and [`LinkPhysics`] (mass, centre of mass, principal moments, consistency) |
//! | [`consistent`] | the program — closest parameters in the least-squares metric with every `J ⪰ 0`, effect signs and bounds — its answer |
//! | `barrier.rs` | the solver: a log-barrier interior-point method with dense, equilibrated Newton steps |
//! | `start.rs` | its strictly feasible start |
//! | `spd.rs` | equilibrated Cholesky and eigenvalue of badly scaled SPD matrices |
//! | [`program`] | its inputs (problem, bounds, margin, ellipsoids, solver options) and errors |
//! | `validate.rs` | input checks, each error saying what to change |
//! | [`synth`] | 7-link-sized synthetic problems with a known answer (tests, benchmark) |
//!
//! ```
//! use dynid::physical::ConsistentProblem;
//! use nalgebra::{DMatrix, DVector};
//! // One link observed directly (K = 1), an estimate with a negative mass.
//! let estimate = DVector::from_vec(vec![0.02, 0.0, 0.0, 0.02, 0.0, 0.02, 0.0, 0.0, 0.0, -0.2]);
//! let pb = ConsistentProblem::new(1, 0, DMatrix::identity(10, 10), estimate, DMatrix::identity(10, 10));
//! let fit = pb.solve()?;
//! assert!(fit.links[0].consistent && fit.links[0].mass >= 0.0);
//! # Ok::<(), dynid::physical::ConsistentError>(())
//! ```

pub mod consistent;
pub mod program;
pub mod pseudo_inertia;
pub mod synth;

mod barrier;
mod spd;
mod start;
mod validate;

#[cfg(test)]
mod tests;

pub use consistent::{ActiveConstraint, ConsistentFit, SolveReport};
pub use program::{
    ConsistentError, ConsistentProblem, EffectBound, Ellipsoid, Margin, SolverOptions,
};
pub use pseudo_inertia::{pseudo_inertia, svec_map, LinkPhysics};
