//! Physically consistent identification: least-squares estimates pulled into the set of
//! parameters that real rigid bodies can have.
//!
//! | file | what |
//! |---|---|
//! | [`pseudo_inertia`] | one link's 4×4 pseudo-inertia `J`, its `svec`, and [`LinkPhysics`] (mass, centre of mass, principal moments, consistency) |

pub mod pseudo_inertia;

pub use pseudo_inertia::{pseudo_inertia, svec_map, LinkPhysics};
