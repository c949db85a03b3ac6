//! Physically consistent identification: least-squares estimates pulled into the set of
//! parameters that real rigid bodies can have.
//!
//! | file | what |
//! |---|---|
//! | [`pseudo_inertia`] | one link's 4×4 pseudo-inertia `J`, its `svec`, and [`LinkPhysics`] (mass, centre of mass, principal moments, consistency) |
//! | `barrier.rs` | the solver: a log-barrier interior-point method with dense, equilibrated Newton steps |
//! | `spd.rs` | equilibrated Cholesky and eigenvalue of badly scaled SPD matrices |

pub mod pseudo_inertia;

mod barrier;
mod spd;

pub use pseudo_inertia::{pseudo_inertia, svec_map, LinkPhysics};
