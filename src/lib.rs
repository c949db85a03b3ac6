//! dynid: from a robot arm's modified Denavit–Hartenberg table to generated, unrolled dynamics
//! kernels, and from measured or simulated data to identified dynamic parameters.
//!
//! Layout: [`model`] is the contract every generated arm implements, [`arms`] the registry of
//! generated arms, [`reference`](mod@reference) the hand-written recursive Newton–Euler oracle; [`dh`],
//! [`params`] and [`data`] load user files with errors that say where and how to fix ([`log`]
//! streams a data file for identification, spilling a long one to disk; [`bag`] reads ROS 2
//! bags into one); [`io`]
//! writes outputs atomically; [`pack`] runs every kernel on four samples at once (SIMD across
//! samples). [`app`] is the layer the front ends call: the `dynid` command line (its own crate,
//! `cli/`) and the Python bindings (`python/`) build its requests and present its results.

pub mod app;
pub mod arms;
pub mod bag;
pub mod bench;
pub mod cholesky;
pub mod control;
pub mod data;
pub mod derivative;
pub mod dh;
pub mod diag;
pub mod dynamics;
pub mod effects;
pub mod excitation;
pub mod identify;
pub mod io;
pub mod log;
pub mod measurement;
pub mod model;
pub mod pack;
pub mod paper;
pub mod params;
pub mod payload;
pub mod physical;
pub mod progress;
pub mod reference;
pub mod report;
pub mod signal;
pub mod sim;
pub mod trajectory;
pub mod trig;
pub mod urdf;

mod tomlread;
