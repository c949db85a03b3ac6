//! Inertial parameters (`--params file.toml`) → the full parameter vector `p`.
//!
//! One `[[link]]` per link with `m`, `com = [x, y, z]` (link frame, m) and either
//! `inertia_com` or `inertia_origin = [ixx, ixy, ixz, iyy, iyz, izz]` (kg·m²; the off-diagonal
//! entries are those of the inertia *tensor*, i.e. `ixy = −∫xy dm`, as in URDF). An optional
//! `[effects]` table holds per-joint arrays ([`KNOWN_EFFECTS`]): the coefficients of
//! `viscous`, `coulomb`, `asym_coulomb`, `stribeck`, `armature`, `offset`, `spring`, `drift`,
//! `ripple_sin`, `ripple_cos`, `spline_a`, `spline_b`, `spline_c` and `loadcoulomb`, and the
//! friction's velocity scales `sign_velocity` (the sign is `tanh(q̇/v)`; absent or 0: exact),
//! `stribeck_velocity` (default 0.1) and `spline_velocity` (the spline's velocity unit) — the torque of each is [`crate::effects::Effect::column`].
//! `dynid identify` writes such a file (`identified.params.toml`, [`InertialParams::to_toml`]).
//!
//! `p` follows [`crate::model::PARAM_ORDER`]: per link `XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M`
//! about the link-frame origin (`XX… = inertia_com + parallel-axis term`, `MX… = m·com`).
//!
//! **Massless links.** A link may be written as just `m = 0.0` (its `com` and inertias default to
//! zero): it contributes nothing (a virtual link). A zero-mass link with non-zero inertia is not a
//! rigid body (inertia needs mass); such data (e.g. PUMA link 1 with `m = 0, Izz = 0.35` in
//! common tables) is reported as non-physical, so it needs `allow_nonphysical` — or better, give
//! the link a mass and a physically shaped inertia.
//!
//! **Physical consistency** (checked on the inertia about the centre of mass): `m ≥ 0`, the
//! tensor positive semidefinite and its principal moments satisfying the triangle inequality
//! (`I1 + I2 ≥ I3`). With `allow_nonphysical` (option or top-level key) violations become
//! [`InertialParams::warnings`] instead of errors. Non-finite numbers are always errors.
//!
//! ```
//! use dynid::params::{InertialParams, ParamsOptions};
//! let text = "[[link]]\nm = 2.0\ncom = [0.5, 0.0, 0.0]\ninertia_com = [0.0, 0.0, 0.0, 0.1, 0.0, 0.1]\n";
//! let params = InertialParams::from_str(text, "one.toml", 1, &ParamsOptions::default())?;
//! let p = params.full_vector();
//! assert_eq!(p[5], 0.1 + 2.0 * 0.25); // ZZ about the origin: parallel-axis theorem
//! assert_eq!(p[6], 1.0); // MX = m·x
//! # Ok::<(), dynid::params::ParamsError>(())
//! ```

use std::fmt;
use std::path::Path;

use nalgebra::{Matrix3, SymmetricEigen};

use crate::diag::{did_you_mean, list, Location, TomlProblem};
use crate::effects::{self, Effect, Scales};
use crate::tomlread::{Fail, Src, TableView};

/// Names of the per-joint arrays an `[effects]` table may hold: the effects' coefficients, then
/// the velocity scales of the friction terms.
pub const KNOWN_EFFECTS: [&str; 18] = [
    "viscous",
    "coulomb",
    "asym_coulomb",
    "stribeck",
    "armature",
    "offset",
    "spring",
    "drift",
    "ripple_sin",
    "ripple_cos",
    "spline_a",
    "spline_b",
    "spline_c",
    "loadcoulomb",
    "sign_velocity",
    "stribeck_velocity",
    "ripple_wavenumber",
    "spline_velocity",
];

const TOP_KEYS: [&str; 3] = ["link", "effects", "allow_nonphysical"];
const LINK_KEYS: [&str; 5] = ["m", "com", "inertia_com", "inertia_origin", "name"];

/// Loader options.
#[derive(Debug, Clone, Copy, Default)]
pub struct ParamsOptions {
    /// Turn physical-consistency errors into warnings (e.g. for identified parameters).
    pub allow_nonphysical: bool,
}

/// Inertial parameters of one link.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkInertia {
    /// Optional label.
    pub name: Option<String>,
    /// Mass (kg).
    pub m: f64,
    /// Centre of mass in the link frame (m).
    pub com: [f64; 3],
    /// Inertia tensor about the centre of mass, `[ixx, ixy, ixz, iyy, iyz, izz]`.
    pub inertia_com: [f64; 6],
    /// Inertia tensor about the link-frame origin, same layout.
    pub inertia_origin: [f64; 6],
}

impl LinkInertia {
    /// This link's 10 parameters in [`crate::model::PARAM_ORDER`].
    pub fn standard_params(&self) -> [f64; 10] {
        let [xx, xy, xz, yy, yz, zz] = self.inertia_origin;
        let [x, y, z] = self.com;
        let m = self.m;
        [xx, xy, xz, yy, yz, zz, m * x, m * y, m * z, m]
    }
}

/// Per-joint effects (each array has one entry per joint), applied by [`Effects::torque`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Effects {
    /// Viscous friction `Fv`: `τ += Fv·q̇`.
    pub viscous: Option<Vec<f64>>,
    /// Coulomb friction `Fc`: `τ += Fc·sign(q̇)` (sign(0) = 0; smoothed to `tanh(q̇/v)` by
    /// [`Effects::sign_velocity`]).
    pub coulomb: Option<Vec<f64>>,
    /// Asymmetric Coulomb friction `Fa = ½(Fc⁺ − Fc⁻)`: `τ += Fa·|sign(q̇)|` (smoothed like
    /// `coulomb`), so that with `coulomb` = `½(Fc⁺ + Fc⁻)` the friction is `Fc⁺` moving forward and
    /// `−Fc⁻` moving back.
    pub asym_coulomb: Option<Vec<f64>>,
    /// Stribeck friction `Fs` (extra breakaway friction at low speed):
    /// `τ += Fs·sign(q̇)·exp(−(q̇/vs)²)`, `vs` from [`Effects::stribeck_velocity`].
    pub stribeck: Option<Vec<f64>>,
    /// Armature (rotor) inertia `Ia`: `τ += Ia·q̈`.
    pub armature: Option<Vec<f64>>,
    /// Constant torque offset: `τ += τ0`.
    pub offset: Option<Vec<f64>>,
    /// Linear spring `k` about q = 0 (a spring about another rest angle is a spring plus an
    /// offset): `τ += k·q`.
    pub spring: Option<Vec<f64>>,
    /// Slow drift `c` over a run: `τ += c·t`, `t` the time since the start of the run (s). Not in
    /// [`Effects::torque`], which has no time: a simulation starts without it.
    pub drift: Option<Vec<f64>>,
    /// Position ripple `a`, `b`: `τ += a·sin(k·q) + b·cos(k·q)`, `k` from
    /// [`Effects::ripple_wavenumber`].
    pub ripple_sin: Option<Vec<f64>>,
    pub ripple_cos: Option<Vec<f64>>,
    /// Friction as a natural cubic spline in `q̇ / r` ([`crate::effects::spline`]):
    /// `τ += a·N₁ + b·N₂ + c·N₃`, `u` from [`Effects::spline_velocity`].
    pub spline_a: Option<Vec<f64>>,
    pub spline_b: Option<Vec<f64>>,
    pub spline_c: Option<Vec<f64>>,
    /// Load-dependent Coulomb friction `μ` (gear friction growing with the transmitted torque):
    /// `τ = u + μ·sign(q̇)·|u|`, `u` the rigid-body torque plus the other effects
    /// ([`Effects::load`]; `μ < 1`).
    pub loadcoulomb: Option<Vec<f64>>,
    /// Velocity `v` of the smoothed friction sign `tanh(q̇/v)` (Coulomb, Stribeck and
    /// asymmetric and load-dependent friction; identification fits with one). Absent or 0: the
    /// exact sign.
    pub sign_velocity: Option<Vec<f64>>,
    /// Stribeck velocity `vs` (default 0.1 rad/s or m/s).
    pub stribeck_velocity: Option<Vec<f64>>,
    /// Wavenumber `k` of the position ripple (rad⁻¹ or m⁻¹; required with `ripple_sin` or
    /// `ripple_cos`).
    pub ripple_wavenumber: Option<Vec<f64>>,
    /// Velocity unit `u` of the friction spline (rad/s or m/s; required with its coefficients).
    pub spline_velocity: Option<Vec<f64>>,
}

impl Effects {
    /// True when no effect is given.
    pub fn is_empty(&self) -> bool {
        self.viscous.is_none()
            && self.coulomb.is_none()
            && self.asym_coulomb.is_none()
            && self.armature.is_none()
            && self.offset.is_none()
            && self.spring.is_none()
            && self.drift.is_none()
            && self.ripple_sin.is_none()
            && self.ripple_cos.is_none()
            && self.spline_a.is_none()
            && self.spline_b.is_none()
            && self.spline_c.is_none()
            && self.loadcoulomb.is_none()
            && self.stribeck.is_none()
    }

    /// The friction velocity scales of joint `j`.
    pub fn scales(&self, j: usize) -> Scales {
        let at = |v: &Option<Vec<f64>>, default: f64| v.as_ref().map_or(default, |v| v[j]);
        Scales {
            coulomb_v: at(&self.sign_velocity, Scales::EXACT.coulomb_v),
            stribeck_v: at(&self.stribeck_velocity, Scales::EXACT.stribeck_v),
            ripple_k: at(&self.ripple_wavenumber, 0.0),
            spline_v: at(&self.spline_velocity, Scales::EXACT.spline_v),
        }
    }

    /// Joint `j`'s torque with load-dependent friction, from `u` (rigid body + other effects):
    /// `u + μ·sign(q̇)·|u|` ([`effects::load`]).
    pub fn load(&self, j: usize, dq: f64, u: f64) -> f64 {
        let mu = self.loadcoulomb.as_ref().map_or(0.0, |v| v[j]);
        effects::load(mu, dq, u, &self.scales(j))
    }

    /// The inverse of [`Effects::load`] ([`effects::unload`]).
    pub fn unload(&self, j: usize, dq: f64, tau: f64) -> f64 {
        let mu = self.loadcoulomb.as_ref().map_or(0.0, |v| v[j]);
        effects::unload(mu, dq, tau, &self.scales(j))
    }

    /// Every `[effects]` array with its key, in [`KNOWN_EFFECTS`] order (the file's order).
    pub fn arrays(&self) -> [(&'static str, &Option<Vec<f64>>); 18] {
        [
            ("viscous", &self.viscous),
            ("coulomb", &self.coulomb),
            ("asym_coulomb", &self.asym_coulomb),
            ("stribeck", &self.stribeck),
            ("armature", &self.armature),
            ("offset", &self.offset),
            ("spring", &self.spring),
            ("drift", &self.drift),
            ("ripple_sin", &self.ripple_sin),
            ("ripple_cos", &self.ripple_cos),
            ("spline_a", &self.spline_a),
            ("spline_b", &self.spline_b),
            ("spline_c", &self.spline_c),
            ("loadcoulomb", &self.loadcoulomb),
            ("sign_velocity", &self.sign_velocity),
            ("stribeck_velocity", &self.stribeck_velocity),
            ("ripple_wavenumber", &self.ripple_wavenumber),
            ("spline_velocity", &self.spline_velocity),
        ]
    }

    /// The coefficients of `effect` (one per joint, when given). A per-run offset has no array
    /// of its own: a model predicts a new run with the mean of the training runs' offsets, which
    /// is part of `offset` (see [`crate::effects::Run::Unseen`]).
    pub fn coefficients_mut(&mut self, effect: Effect) -> &mut Option<Vec<f64>> {
        match effect {
            Effect::Viscous => &mut self.viscous,
            Effect::Coulomb => &mut self.coulomb,
            Effect::AsymCoulomb => &mut self.asym_coulomb,
            Effect::Stribeck => &mut self.stribeck,
            Effect::Offset | Effect::RunOffset => &mut self.offset,
            Effect::Armature => &mut self.armature,
            Effect::Spring => &mut self.spring,
            Effect::Drift => &mut self.drift,
            Effect::RippleSin => &mut self.ripple_sin,
            Effect::RippleCos => &mut self.ripple_cos,
            Effect::SplineA => &mut self.spline_a,
            Effect::SplineB => &mut self.spline_b,
            Effect::SplineC => &mut self.spline_c,
            Effect::LoadCoulomb => &mut self.loadcoulomb,
        }
    }

    /// The additive effects and their coefficients, in summation order.
    fn additive(&self) -> [(Effect, &Option<Vec<f64>>); 11] {
        [
            (Effect::Viscous, &self.viscous),
            (Effect::Coulomb, &self.coulomb),
            (Effect::AsymCoulomb, &self.asym_coulomb),
            (Effect::Armature, &self.armature),
            (Effect::Offset, &self.offset),
            (Effect::Spring, &self.spring),
            (Effect::RippleSin, &self.ripple_sin),
            (Effect::RippleCos, &self.ripple_cos),
            (Effect::SplineA, &self.spline_a),
            (Effect::SplineB, &self.spline_b),
            (Effect::SplineC, &self.spline_c),
        ]
    }

    /// Torque of the additive effects at joint `j` for position `q`, velocity `dq` and
    /// acceleration `ddq` (all but [`Effects::loadcoulomb`], see [`Effects::load`]): each
    /// effect's [`Effect::column`] with the joint's [`Effects::scales`].
    pub fn torque(&self, j: usize, q: f64, dq: f64, ddq: f64) -> f64 {
        let s = self.scales(j);
        let mut terms = self
            .additive()
            .into_iter()
            .map(|(e, c)| c.as_ref().map_or(0.0, |v| v[j]) * e.column(q, dq, ddq, 0.0, &s));
        let first = terms.next().unwrap_or(0.0);
        let sum = terms.fold(first, |sum, t| sum + t);
        match &self.stribeck {
            Some(v) => sum + v[j] * Effect::Stribeck.column(q, dq, ddq, 0.0, &s),
            None => sum,
        }
    }
}

/// A parameter file: links and effects, validated against the arm's DOF.
#[derive(Debug, Clone)]
pub struct InertialParams {
    pub links: Vec<LinkInertia>,
    pub effects: Effects,
    /// Physical-consistency violations accepted because of `allow_nonphysical`.
    pub warnings: Vec<ParamsError>,
}

/// A parameter file that cannot be used, with where and how to fix it.
#[derive(Debug, thiserror::Error)]
#[error("{loc}: {kind}")]
pub struct ParamsError {
    pub loc: Location,
    /// Boxed: errors travel through `Result`s of hot-ish loader code; keep them small.
    pub kind: Box<ParamsErrorKind>,
}

// `std::io::Error` is not `Clone`; warnings never hold one, so clone through its message.
impl Clone for ParamsError {
    fn clone(&self) -> Self {
        let kind = match &*self.kind {
            ParamsErrorKind::Io(e) => {
                ParamsErrorKind::Io(std::io::Error::new(e.kind(), e.to_string()))
            }
            ParamsErrorKind::Toml(p) => ParamsErrorKind::Toml(p.clone()),
            ParamsErrorKind::LinkCount { expected, found } => ParamsErrorKind::LinkCount {
                expected: *expected,
                found: *found,
            },
            ParamsErrorKind::NonPhysical(n) => ParamsErrorKind::NonPhysical(*n),
            ParamsErrorKind::BothInertias => ParamsErrorKind::BothInertias,
            ParamsErrorKind::RippleWithoutWavenumber => ParamsErrorKind::RippleWithoutWavenumber,
            ParamsErrorKind::SplineWithoutVelocity => ParamsErrorKind::SplineWithoutVelocity,
            ParamsErrorKind::LoadFrictionRange { joint, value } => {
                ParamsErrorKind::LoadFrictionRange {
                    joint: *joint,
                    value: *value,
                }
            }
            ParamsErrorKind::Velocity {
                key,
                joint,
                zero_ok,
            } => ParamsErrorKind::Velocity {
                key: key.clone(),
                joint: *joint,
                zero_ok: *zero_ok,
            },
            ParamsErrorKind::UnknownEffect { name, suggestion } => ParamsErrorKind::UnknownEffect {
                name: name.clone(),
                suggestion: *suggestion,
            },
        };
        ParamsError {
            loc: self.loc.clone(),
            kind: Box::new(kind),
        }
    }
}

/// What is wrong with a parameter file.
#[derive(Debug)]
pub enum ParamsErrorKind {
    Io(std::io::Error),
    Toml(TomlProblem),
    /// Number of `[[link]]` tables differs from the arm's DOF.
    LinkCount {
        expected: usize,
        found: usize,
    },
    /// Not a physically possible rigid body.
    NonPhysical(NonPhysical),
    /// Both `inertia_com` and `inertia_origin` given.
    BothInertias,
    /// An `[effects]` entry that is not in [`KNOWN_EFFECTS`].
    UnknownEffect {
        name: String,
        suggestion: Option<&'static str>,
    },
    /// A load-dependent friction coefficient outside `[0, 1)`.
    LoadFrictionRange {
        joint: usize,
        value: f64,
    },
    /// Ripple coefficients without their wavenumber.
    RippleWithoutWavenumber,
    /// Friction spline coefficients without its velocity unit.
    SplineWithoutVelocity,
    /// A friction velocity scale that is negative (or zero where it divides).
    Velocity {
        key: String,
        joint: usize,
        zero_ok: bool,
    },
}

/// Why a link's parameters are not physically possible.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NonPhysical {
    NegativeMass {
        m: f64,
    },
    MasslessWithInertia,
    /// Smallest principal moment about the COM.
    NotPositiveSemidefinite {
        min_eigenvalue: f64,
    },
    /// Principal moments `[i1, i2, i3]` with `i1 + i2 < i3`.
    TriangleInequality {
        moments: [f64; 3],
    },
}

impl fmt::Display for NonPhysical {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NonPhysical::NegativeMass { m } => write!(f, "mass {m} is negative — masses must be ≥ 0 (kg)"),
            NonPhysical::MasslessWithInertia => write!(
                f,
                "massless link with non-zero inertia is not a rigid body — give the link its mass, or zero inertias for a virtual link (or pass --allow-nonphysical)"
            ),
            NonPhysical::NotPositiveSemidefinite { min_eigenvalue } => write!(
                f,
                "inertia about the centre of mass is not positive semidefinite (principal moment {min_eigenvalue:e}) — check signs: off-diagonals are tensor entries (ixy = −∫xy dm), diagonals must be ≥ 0 (or pass --allow-nonphysical)"
            ),
            NonPhysical::TriangleInequality { moments: [a, b, c] } => write!(
                f,
                "principal moments {a:e}, {b:e}, {c:e} break the triangle inequality ({a:e} + {b:e} < {c:e}) — no mass distribution has them; check the values (or pass --allow-nonphysical)"
            ),
        }
    }
}

impl fmt::Display for ParamsErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamsErrorKind::Io(e) => write!(f, "cannot read the file: {e} — check the path and permissions"),
            ParamsErrorKind::Toml(p) => write!(f, "{p}"),
            ParamsErrorKind::LinkCount { expected, found } => write!(
                f,
                "{found} `[[link]]` tables but the arm has {expected} joints — give exactly one `[[link]]` per joint, in joint order"
            ),
            ParamsErrorKind::NonPhysical(n) => write!(f, "{n}"),
            ParamsErrorKind::BothInertias => write!(
                f,
                "both `inertia_com` and `inertia_origin` given — keep exactly one of them"
            ),
            ParamsErrorKind::LoadFrictionRange { joint, value } => write!(
                f,
                "joint {joint}: {value} is not a load-dependent friction coefficient — it is a fraction of the transmitted torque, 0 <= mu < 1"
            ),
            ParamsErrorKind::RippleWithoutWavenumber => write!(
                f,
                "ripple coefficients without `ripple_wavenumber` — give each joint's k (rad^-1), the ripple is a·sin(k·q) + b·cos(k·q)"
            ),
            ParamsErrorKind::SplineWithoutVelocity => write!(
                f,
                "friction spline coefficients without `spline_velocity` — give each joint's velocity unit u (rad/s or m/s, > 0; the knots are at q̇/u = 0, ±0.5, ±1)"
            ),
            ParamsErrorKind::Velocity { key, joint, zero_ok } => write!(
                f,
                "joint {joint}: `{key}` must be {} — it is a velocity in rad/s or m/s",
                if *zero_ok { "0 (exact sign) or positive" } else { "positive" }
            ),
            ParamsErrorKind::UnknownEffect { name, suggestion } => {
                write!(f, "unknown effect `{name}` — ")?;
                if let Some(s) = suggestion {
                    write!(f, "did you mean `{s}`? ")?;
                }
                write!(f, "known effects: {}", list(&KNOWN_EFFECTS))
            }
        }
    }
}

impl From<Fail> for ParamsError {
    fn from(fail: Fail) -> Self {
        let (loc, problem) = *fail;
        ParamsError {
            loc,
            kind: Box::new(ParamsErrorKind::Toml(problem)),
        }
    }
}

impl InertialParams {
    /// Reads a parameter file for an arm with `dof` joints.
    pub fn from_path(path: &Path, dof: usize, opts: &ParamsOptions) -> Result<Self, ParamsError> {
        let file = path.display().to_string();
        let io_err = |e| ParamsError {
            loc: Location::file(&file),
            kind: Box::new(ParamsErrorKind::Io(e)),
        };
        let bytes = std::fs::read(path).map_err(io_err)?;
        let text = String::from_utf8(bytes)
            .map_err(|e| io_err(std::io::Error::new(std::io::ErrorKind::InvalidData, e)))?;
        Self::from_str(&text, &file, dof, opts)
    }

    /// Parses a parameter file; `origin` names it in errors.
    #[allow(clippy::should_implement_trait)] // `FromStr` cannot take the origin and DOF.
    pub fn from_str(
        text: &str,
        origin: &str,
        dof: usize,
        opts: &ParamsOptions,
    ) -> Result<Self, ParamsError> {
        let src = Src {
            file: origin,
            text: text.strip_prefix('\u{feff}').unwrap_or(text),
        };
        let doc = src.parse()?;
        let root = src.root(&doc);
        root.check_keys(&TOP_KEYS)?;
        let allow = opts.allow_nonphysical || root.bool_opt("allow_nonphysical")?.unwrap_or(false);

        let tables = root.tables("link")?;
        if tables.len() != dof {
            let loc = match tables.get(dof) {
                Some(extra) => extra.loc(),
                None => root.loc_of("link"),
            };
            return Err(ParamsError {
                loc,
                kind: Box::new(ParamsErrorKind::LinkCount {
                    expected: dof,
                    found: tables.len(),
                }),
            });
        }
        let mut warnings = Vec::new();
        let mut links = Vec::with_capacity(dof);
        for t in &tables {
            let link = read_link(t)?;
            if let Err(n) = check_physical(link.m, &link.inertia_com) {
                let err = ParamsError {
                    loc: t.loc(),
                    kind: Box::new(ParamsErrorKind::NonPhysical(n)),
                };
                if !allow {
                    return Err(err);
                }
                warnings.push(err);
            }
            links.push(link);
        }
        let effects = match root.subtable("effects")? {
            Some(t) => read_effects(&t, dof)?,
            None => Effects::default(),
        };
        Ok(InertialParams {
            links,
            effects,
            warnings,
        })
    }

    /// The parameter file of these parameters (read back by [`InertialParams::from_str`] to the
    /// same numbers: floats are written in their shortest round-trip form). `header` lines
    /// become `#` comments at the top. Links are written with `inertia_origin`, the form the
    /// full parameter vector holds.
    pub fn to_toml(&self, header: &[String]) -> String {
        use std::fmt::Write as _;
        let nums = |v: &[f64]| {
            let items: Vec<String> = v.iter().map(|x| format!("{x:?}")).collect();
            format!("[{}]", items.join(", "))
        };
        let mut s = String::new();
        for h in header {
            let _ = writeln!(s, "# {h}");
        }
        if self
            .links
            .iter()
            .any(|l| check_physical(l.m, &l.inertia_com).is_err())
        {
            s.push_str("allow_nonphysical = true\n");
        }
        for l in &self.links {
            s.push_str("\n[[link]]\n");
            if let Some(n) = &l.name {
                let _ = writeln!(s, "name = {n:?}");
            }
            let _ = writeln!(s, "m = {:?}", l.m);
            let _ = writeln!(s, "com = {}", nums(&l.com));
            let _ = writeln!(s, "inertia_origin = {}", nums(&l.inertia_origin));
        }
        let arrays = self.effects.arrays();
        if arrays.iter().any(|(_, v)| v.is_some()) {
            s.push_str("\n[effects]\n");
            for (k, v) in arrays {
                if let Some(v) = v {
                    let _ = writeln!(s, "{k} = {}", nums(v));
                }
            }
        }
        s
    }

    /// Parameters from a full parameter vector `p` ([`crate::model::PARAM_ORDER`] per link, about
    /// the link-frame origin) and effects. A link with `M = 0` gets its centre of mass at the
    /// origin.
    pub fn from_full_vector(p: &[f64], effects: Effects) -> Self {
        let links = p
            .chunks_exact(10)
            .map(|c| {
                let m = c[9];
                let com = if m != 0.0 {
                    [c[6] / m, c[7] / m, c[8] / m]
                } else {
                    [0.0; 3]
                };
                let shift = parallel_axis(m, com);
                let inertia_origin = [c[0], c[1], c[2], c[3], c[4], c[5]];
                LinkInertia {
                    name: None,
                    m,
                    com,
                    inertia_com: std::array::from_fn(|k| inertia_origin[k] - shift[k]),
                    inertia_origin,
                }
            })
            .collect();
        InertialParams {
            links,
            effects,
            warnings: Vec::new(),
        }
    }

    /// Degrees of freedom (number of links).
    pub fn dof(&self) -> usize {
        self.links.len()
    }

    /// The full parameter vector `p` (length `10·dof`, [`crate::model::PARAM_ORDER`] per link).
    pub fn full_vector(&self) -> Vec<f64> {
        self.links
            .iter()
            .flat_map(LinkInertia::standard_params)
            .collect()
    }
}

fn read_link(t: &TableView<'_>) -> Result<LinkInertia, ParamsError> {
    t.check_keys(&LINK_KEYS)?;
    let name = t.str_opt("name")?.map(str::to_string);
    let m = t.f64_req("m")?;
    let massless = m == 0.0;
    let com = match t.f64_array_opt("com", Some(3))? {
        Some(c) => [c[0], c[1], c[2]],
        None if massless => [0.0; 3],
        None => return Err(t.missing_key("com").into()),
    };
    let ic = t.f64_array_opt("inertia_com", Some(6))?;
    let io = t.f64_array_opt("inertia_origin", Some(6))?;
    let six = |v: Vec<f64>| [v[0], v[1], v[2], v[3], v[4], v[5]];
    let shift = parallel_axis(m, com);
    let (inertia_com, inertia_origin) = match (ic, io) {
        (Some(_), Some(_)) => {
            return Err(ParamsError {
                loc: t.loc_of("inertia_origin"),
                kind: Box::new(ParamsErrorKind::BothInertias),
            })
        }
        (Some(c), None) => {
            let c = six(c);
            (c, std::array::from_fn(|k| c[k] + shift[k]))
        }
        (None, Some(o)) => {
            let o = six(o);
            (std::array::from_fn(|k| o[k] - shift[k]), o)
        }
        (None, None) if massless => ([0.0; 6], [0.0; 6]),
        (None, None) => return Err(t.missing_key("inertia_com").into()),
    };
    Ok(LinkInertia {
        name,
        m,
        com,
        inertia_com,
        inertia_origin,
    })
}

/// The parallel-axis term `m (|c|² 1 − c cᵀ)` as `[ixx, ixy, ixz, iyy, iyz, izz]`: the inertia
/// about the link origin is the one about the centre of mass `c` plus this.
fn parallel_axis(m: f64, [x, y, z]: [f64; 3]) -> [f64; 6] {
    [
        m * (y * y + z * z),
        -m * x * y,
        -m * x * z,
        m * (x * x + z * z),
        -m * y * z,
        m * (x * x + y * y),
    ]
}

fn read_effects(t: &TableView<'_>, dof: usize) -> Result<Effects, ParamsError> {
    for key in t.keys() {
        if !KNOWN_EFFECTS.contains(&key) {
            return Err(ParamsError {
                loc: t.loc_of(key),
                kind: Box::new(ParamsErrorKind::UnknownEffect {
                    name: key.to_string(),
                    suggestion: did_you_mean(key, &KNOWN_EFFECTS),
                }),
            });
        }
    }
    let loadcoulomb = t.f64_array_opt("loadcoulomb", Some(dof))?;
    if let Some(v) = &loadcoulomb {
        if let Some(j) = v.iter().position(|m| !(0.0..1.0).contains(m)) {
            return Err(ParamsError {
                loc: t.loc_of("loadcoulomb"),
                kind: Box::new(ParamsErrorKind::LoadFrictionRange {
                    joint: j + 1,
                    value: v[j],
                }),
            });
        }
    }
    let (ripple_sin, ripple_cos) = (
        t.f64_array_opt("ripple_sin", Some(dof))?,
        t.f64_array_opt("ripple_cos", Some(dof))?,
    );
    let ripple_wavenumber = t.f64_array_opt("ripple_wavenumber", Some(dof))?;
    if ripple_wavenumber.is_none() {
        if let Some(key) = [("ripple_sin", &ripple_sin), ("ripple_cos", &ripple_cos)]
            .into_iter()
            .find_map(|(k, v)| v.is_some().then_some(k))
        {
            return Err(ParamsError {
                loc: t.loc_of(key),
                kind: Box::new(ParamsErrorKind::RippleWithoutWavenumber),
            });
        }
    }
    let velocity = |key: &str, zero_ok: bool| -> Result<Option<Vec<f64>>, ParamsError> {
        let v = t.f64_array_opt(key, Some(dof))?;
        if let Some(j) = v
            .iter()
            .flatten()
            .position(|&x| x < 0.0 || (x == 0.0 && !zero_ok))
        {
            return Err(ParamsError {
                loc: t.loc_of(key),
                kind: Box::new(ParamsErrorKind::Velocity {
                    key: key.to_string(),
                    joint: j + 1,
                    zero_ok,
                }),
            });
        }
        Ok(v)
    };
    let spline = [
        t.f64_array_opt("spline_a", Some(dof))?,
        t.f64_array_opt("spline_b", Some(dof))?,
        t.f64_array_opt("spline_c", Some(dof))?,
    ];
    let spline_velocity = velocity("spline_velocity", false)?;
    if spline_velocity.is_none() {
        if let Some(key) = ["spline_a", "spline_b", "spline_c"]
            .into_iter()
            .zip(&spline)
            .find_map(|(k, v)| v.is_some().then_some(k))
        {
            return Err(ParamsError {
                loc: t.loc_of(key),
                kind: Box::new(ParamsErrorKind::SplineWithoutVelocity),
            });
        }
    }
    let [spline_a, spline_b, spline_c] = spline;
    Ok(Effects {
        viscous: t.f64_array_opt("viscous", Some(dof))?,
        coulomb: t.f64_array_opt("coulomb", Some(dof))?,
        asym_coulomb: t.f64_array_opt("asym_coulomb", Some(dof))?,
        stribeck: t.f64_array_opt("stribeck", Some(dof))?,
        armature: t.f64_array_opt("armature", Some(dof))?,
        offset: t.f64_array_opt("offset", Some(dof))?,
        spring: t.f64_array_opt("spring", Some(dof))?,
        drift: t.f64_array_opt("drift", Some(dof))?,
        ripple_sin,
        ripple_cos,
        spline_a,
        spline_b,
        spline_c,
        loadcoulomb,
        sign_velocity: velocity("sign_velocity", true)?,
        stribeck_velocity: velocity("stribeck_velocity", false)?,
        ripple_wavenumber,
        spline_velocity,
    })
}

/// Checks that `m` and the inertia about the centre of mass `[ixx, ixy, ixz, iyy, iyz, izz]`
/// describe a possible rigid body (see the module docs). Semidefinite is accepted (point
/// masses, thin rods); the tolerance is relative to the largest principal moment.
pub fn check_physical(m: f64, inertia_com: &[f64; 6]) -> Result<(), NonPhysical> {
    if m < 0.0 {
        return Err(NonPhysical::NegativeMass { m });
    }
    if m == 0.0 {
        return if inertia_com.iter().all(|&v| v == 0.0) {
            Ok(())
        } else {
            Err(NonPhysical::MasslessWithInertia)
        };
    }
    let [xx, xy, xz, yy, yz, zz] = *inertia_com;
    let tensor = Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
    let mut moments: Vec<f64> = SymmetricEigen::new(tensor)
        .eigenvalues
        .iter()
        .copied()
        .collect();
    moments.sort_by(f64::total_cmp);
    let tol = 1e-9 * moments[2].abs().max(f64::MIN_POSITIVE);
    if moments[0] < -tol {
        return Err(NonPhysical::NotPositiveSemidefinite {
            min_eigenvalue: moments[0],
        });
    }
    if moments[0] + moments[1] < moments[2] - tol {
        return Err(NonPhysical::TriangleInequality {
            moments: [moments[0], moments[1], moments[2]],
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const LINK: &str = "[[link]]\nm = 0.0\n";

    /// The ripple in a params file is `a·sin(k·q) + b·cos(k·q)` (closed form), and a ripple
    /// without its wavenumber is an error that names the key.
    #[test]
    fn ripple_round_trips_through_a_params_file() {
        let text = format!(
            "{LINK}[effects]\nripple_sin = [0.2]\nripple_cos = [-0.1]\nripple_wavenumber = [7.0]\n"
        );
        let p = InertialParams::from_str(&text, "r.toml", 1, &ParamsOptions::default()).unwrap();
        let q = 0.3f64;
        let want = 0.2 * (7.0 * q).sin() - 0.1 * (7.0 * q).cos();
        assert!((p.effects.torque(0, q, 0.0, 0.0) - want).abs() < 1e-15);
        let again =
            InertialParams::from_str(&p.to_toml(&[]), "again.toml", 1, &ParamsOptions::default())
                .unwrap();
        assert_eq!(again.effects, p.effects);
        let bad = format!("{LINK}[effects]\nripple_cos = [0.1]\n");
        let e = InertialParams::from_str(&bad, "bad.toml", 1, &ParamsOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("bad.toml") && e.contains("ripple_wavenumber"),
            "{e}"
        );
    }

    #[test]
    fn friction_spline_round_trips_through_a_params_file() {
        let text = format!(
            "{LINK}[effects]\nspline_a = [0.2]\nspline_c = [-0.1]\nspline_velocity = [2.0]\n"
        );
        let p = InertialParams::from_str(&text, "s.toml", 1, &ParamsOptions::default()).unwrap();
        // At q̇ = u (2 rad/s) each column is 1; at q̇ = −2u every column is 0 (left of the knots).
        assert!((p.effects.torque(0, 0.0, 2.0, 0.0) - 0.1).abs() < 1e-15);
        assert_eq!(p.effects.torque(0, 0.0, -4.0, 0.0), 0.0);
        let again =
            InertialParams::from_str(&p.to_toml(&[]), "again.toml", 1, &ParamsOptions::default())
                .unwrap();
        assert_eq!(again.effects, p.effects);
        let bad = format!("{LINK}[effects]\nspline_b = [0.1]\n");
        let e = InertialParams::from_str(&bad, "bad.toml", 1, &ParamsOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("bad.toml") && e.contains("spline_velocity"),
            "{e}"
        );
    }
}
