//! Integration tests (one binary, one module per area). Tests are specifications: each checks
//! numbers against an independent oracle with a justified tolerance.

mod bag;
mod cli;
mod common;
mod dynamics;
mod eval;
mod excite;
mod identify;
mod kernels;
mod loaders;
mod new_arm;
mod paper;
mod payload;
mod physical;
mod reference;
mod roundtrip;
mod simulate;
mod urdf;
