//! The [`Model`] trait: what every arm's generated kernels offer.
//!
//! Each `arms/<arm>.toml` becomes, through `codegen/` → `generated/<arm>.rs` → `dynid_macros::arm!`,
//! a module `dynid::arms::<arm>` holding fixed-size, allocation-free kernels
//! (`regressor(&[f64; DOF], ...)`) and a unit struct implementing this trait with slices, so that the
//! CLI can pick an arm by name at run time (`&'static dyn Model`).
//!
//! Conventions (one source of truth):
//! - Full inertial parameters `p` (length `NP = 10·DOF`), per link in Khalil/Gautier order
//!   `XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M`, about the link-frame origin (see [`PARAM_ORDER`]).
//! - Matrices are row-major: the regressor is `DOF × NP`, `out[i * NP + k]`; the base regressor
//!   `DOF × NB`; the mass matrix `DOF × DOF`.
//! - Base parameters `θ = base_params(p)` (length `NB`), so that `Y(q,q̇,q̈)·p = Yb(q,q̇,q̈)·θ`.
//! - Gravity is the arm's own (from its TOML) and is included in `bias`, `gravity` and
//!   `inverse_dynamics`: `τ = M(q)·q̈ + bias(q,q̇)`, `bias(q,0) = gravity(q)`.
//!
//! - The kernel kinds are the generator's list (`codegen/kernels.py` → `generated/kernels.toml`);
//!   [`Kernel`] enumerates them.
//! - The `*_lanes` methods run the same kernels on [`crate::pack::LANES`] samples at once
//!   (structure of arrays: `q[j]` holds joint `j` of every sample; see [`crate::pack`]); each lane
//!   equals the scalar method's result for that sample bit for bit.
//!
//! The slice methods panic if a slice has the wrong length: that is a programming error, never a
//! user-input error (user input is validated before it reaches a kernel).

/// Per-link parameter order (Khalil/Gautier), about the link-frame origin.
pub const PARAM_ORDER: [&str; 10] = ["XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M"];

/// Operation counts of one generated kernel, as printed by the generator
/// (binary `*` and `/` counted as mul, binary `+` and `-` as add; negations are free).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OpCount {
    pub kernel: &'static str,
    pub mul: u32,
    pub add: u32,
}

/// Generated dynamics kernels of one arm.
pub trait Model: Send + Sync {
    /// Arm name (the TOML file stem, e.g. `puma560`).
    fn name(&self) -> &'static str;
    /// Degrees of freedom.
    fn dof(&self) -> usize;
    /// Number of full inertial parameters, `10 · dof`.
    fn np(&self) -> usize {
        10 * self.dof()
    }
    /// Number of base parameters.
    fn nb(&self) -> usize;
    /// Names of the full parameters, e.g. `ZZ1`, `M2`.
    fn param_names(&self) -> &'static [&'static str];
    /// Names of the base parameters, e.g. `ZZR1`.
    fn base_param_names(&self) -> &'static [&'static str];
    /// Human-readable grouped expressions, e.g. `ZZ1 + a1²·M2`.
    fn base_param_exprs(&self) -> &'static [&'static str];
    /// The D-H table the kernels were generated from (the text of `arms/<arm>.toml`).
    fn arm_toml(&self) -> &'static str;
    /// Operation counts per kernel.
    fn op_counts(&self) -> &'static [OpCount];

    // The kernels, one pair of methods per kernel kind of `generated/kernels.toml` (the list the
    // generator writes from `codegen/kernels.py`, the only place the kinds are listed):
    // `fn <kernel>(&self, <inputs>: &[f64], out: &mut [f64])`, e.g.
    // `fn mass_matrix(&self, q: &[f64], theta: &[f64], out: &mut [f64])`, and
    // `fn <kernel>_lanes(&self, <inputs>: &[Pack], out: &mut [Pack])` running it on `LANES`
    // samples. Each arm's impl is expanded from the same list by `dynid_macros::arm!`, so the trait
    // and every generated arm cannot disagree; see `cargo doc` for the expanded methods.
    dynid_macros::kernel_methods!();

    /// Base parameters from full parameters: `θ = B·p`.
    fn base_params(&self, p: &[f64], out: &mut [f64]);
}

// `Kernel`: one variant per kernel kind, with `ALL`, `name`, `out_len`, `call`, `call_lanes` and
// `with` (a kind fixed at compile time: `KernelCall`, `KernelVisitor`, `kernel_calls`).
dynid_macros::kernel_enum!();
