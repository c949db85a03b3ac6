//! URDF in and out: [`import_file`] converts a URDF serial chain to a modified D-H table plus
//! inertial parameters (the files of DESIGN.md, so the generator and every command can use a real
//! robot); [`export`] writes a D-H arm back as a URDF (small; for round-trip tests and viewers).
//!
//! ```
//! use dynid::urdf::{import_str, ImportOptions};
//! let urdf = r#"<robot name="pendulum">
//!   <link name="base"/>
//!   <link name="bob">
//!     <inertial><origin xyz="0 0 -0.5"/><mass value="2"/>
//!       <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
//!   </link>
//!   <joint name="swing" type="continuous">
//!     <parent link="base"/><child link="bob"/><origin xyz="0 0 1"/><axis xyz="0 1 0"/>
//!   </joint>
//! </robot>"#;
//! let arm = import_str(urdf, "pendulum.urdf", &ImportOptions::default())?;
//! assert_eq!(arm.table.dof(), 1);
//! assert_eq!(arm.params.links[0].m, 2.0);
//! # Ok::<(), dynid::urdf::UrdfError>(())
//! ```
//!
//! # The conversion
//! * **Chain.** From `--base` (default: the URDF root) to `--tip`. Without `--tip`: the path to the
//!   leaf with the most movable joints; paths that differ only below their last movable joint
//!   are the same chain, and two different chains with equally many joints are refused (name one
//!   with `--tip`). Joints coupled by `<mimic>` (follower and master) do not count, so a gripper
//!   whose fingers mimic each other stays off the chain. The tip is the link moved by the last
//!   movable joint; bodies fixed below it are lumped into it (a given `--tip` may be any link).
//! * **Axes.** `z_i` lies on joint `i`'s axis, pointing where the URDF `<axis>` points, so
//!   positive `q_i` is the same motion; `θ`/`d` offsets make `q = 0` the URDF's zero pose.
//!   A prismatic joint's axis line is taken through its URDF joint origin.
//! * **Common normals.** `x_i` lies on the common normal from axis `i` to axis `i+1` (Craig).
//!   Where that leaves a choice, the D-H frame is taken as close as possible to the URDF link
//!   frame: the *sign* of `x_i` (and so of `a_{i}`, which may be negative) makes `x_i` point
//!   along the URDF link's x axis where it can; for *intersecting* axes `x_i = ±z_i × z_{i+1}`;
//!   for *parallel* axes and for the *last* joint the origin is the URDF link origin projected
//!   onto the axis; for *collinear* axes and the last joint `x_i` is the URDF link's x axis
//!   projected onto the plane normal to `z_i`. Axes within [`PARALLEL_TOL`] of parallel are
//!   treated as parallel (D-H is ill-conditioned there).
//! * **Frame 0** is frame 1 at `q_1 = 0` (so `α_0 = a_0 = 0` and joint 1's offsets are 0);
//!   gravity (default 9.81 m/s² along −z of the URDF root link) is re-expressed in it.
//! * **Bodies.** Each D-H link carries its URDF link plus every body attached to it through
//!   fixed joints or through movable joints off the chain, which are locked at 0 (listed in
//!   [`Imported::notes`]). Lumping is exact: total mass, centre of mass, and the inertia about
//!   it by the parallel-axis theorem. Bodies fixed to the base — and the base link's own
//!   inertia — do not move and are dropped (the base is fixed).
//! * **Refused:** floating, planar and spherical joints and `<mimic>` joints (or the joints they
//!   follow) on the chain, links with two parents (closed loops), several root links, missing
//!   links, negative mass, non-finite numbers, unknown joint types, xacro files, more than
//!   [`crate::dh::MAX_JOINTS`] joints. **Warned** ([`Imported::warnings`]): inertias that are not
//!   positive semidefinite or break the triangle inequality (kept as given; the params file then
//!   says `allow_nonphysical = true`), a D-H link with no mass at all, nearly parallel axes.
//!   **Noted** ([`Imported::notes`]): the chain, locked joints, massless links (no `<inertial>`),
//!   what the fixed base drops, `<dynamics>` friction that is not imported.
//!
//! Checked against Pinocchio's RNEA on 22 robots of example-robot-data (UR, Panda, Kinova,
//! xArm, Z1, SO-100, TIAGo, PR2, Baxter, ...): `tests/pinocchio/check_urdf.py`.

pub mod attach;
mod export;
mod frames;
mod geom;
mod import;
mod lump;
pub mod roundtrip;
mod tree;

use std::fmt;
use std::path::{Path, PathBuf};

pub use export::{export, ExportError};
pub use import::{import_file, import_str};

use crate::dh::DhTable;
use crate::params::InertialParams;

/// Consecutive axes whose directions differ by less than this (sine of the angle) are treated
/// as parallel. Near parallel, the common normal runs far away and the D-H offsets lose
/// precision in proportion; treating them as parallel instead changes the geometry by at most
/// this angle.
pub const PARALLEL_TOL: f64 = 1e-8;

/// Default gravity, in the URDF root frame (m/s²).
pub const DEFAULT_GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];

/// How to convert (the options of `dynid import-urdf`).
#[derive(Debug, Clone, Default)]
pub struct ImportOptions {
    /// First link of the chain (fixed to the ground); default: the URDF root link.
    pub base: Option<String>,
    /// Last link of the chain; default: see the module docs.
    pub tip: Option<String>,
    /// Gravitational acceleration in the URDF root frame; default [`DEFAULT_GRAVITY`].
    pub gravity: Option<[f64; 3]>,
    /// Arm name; default: the file stem (or the `<robot name>`), made a valid identifier.
    pub name: Option<String>,
}

/// A converted robot: the D-H table and parameters, the file texts to write, and what the user
/// should know about the conversion.
#[derive(Debug, Clone)]
pub struct Imported {
    pub table: DhTable,
    pub params: InertialParams,
    /// `NAME.toml` (the D-H table, with comments naming the URDF joints).
    pub dh_toml: String,
    /// `NAME.params.toml`.
    pub params_toml: String,
    /// URDF joint names of the chain, in order.
    pub chain: Vec<String>,
    /// What was done (locked joints, lumped bodies, ignored base bodies).
    pub notes: Vec<String>,
    /// Suspicious input that was accepted (massless links, non-physical inertias).
    pub warnings: Vec<String>,
    /// Per D-H link, where it sits in the URDF (for [`roundtrip`]).
    pub(crate) placement: Vec<Placement>,
}

/// D-H link `k` in URDF terms: the link its joint moves, D-H frame `k` in that link's frame,
/// and the other URDF bodies lumped into it (fixed below it, or on locked joints), in D-H frame
/// `k`.
#[derive(Debug, Clone)]
pub(crate) struct Placement {
    pub link: String,
    pub dh_in_link: geom::Pose,
    pub others: Vec<(String, lump::Body)>,
}

impl Imported {
    /// Writes `DIR/NAME.toml` and `DIR/NAME.params.toml` (each atomically; `dir` is created if
    /// missing) and returns their paths.
    pub fn write(&self, dir: &Path) -> Result<(PathBuf, PathBuf), crate::io::WriteError> {
        std::fs::create_dir_all(dir).map_err(|cause| crate::io::WriteError {
            path: dir.to_path_buf(),
            cause,
        })?;
        let dh = dir.join(format!("{}.toml", self.table.name));
        let params = dir.join(format!("{}.params.toml", self.table.name));
        crate::io::atomic_write(&dh, |w| w.write_all(self.dh_toml.as_bytes()))?;
        crate::io::atomic_write(&params, |w| w.write_all(self.params_toml.as_bytes()))?;
        Ok((dh, params))
    }
}

/// A URDF that cannot be converted, with the file and the element.
#[derive(Debug, thiserror::Error)]
#[error("{file}: {kind}")]
pub struct UrdfError {
    pub file: String,
    pub kind: UrdfErrorKind,
}

/// What is wrong with a URDF (or with the options for it).
#[derive(Debug)]
pub enum UrdfErrorKind {
    Io(std::io::Error),
    /// A xacro macro file, not a URDF.
    Xacro,
    /// The XML or the URDF schema is broken (message from the parser).
    Parse(String),
    UnknownJointType {
        joint: String,
        found: String,
    },
    Duplicate {
        element: &'static str,
        name: String,
    },
    MissingLink {
        joint: String,
        role: &'static str,
        link: String,
    },
    /// A link that is the child of several joints.
    ClosedLoop {
        link: String,
        joints: Vec<String>,
    },
    /// Every link is some joint's child.
    NoRoot,
    SeveralRoots {
        roots: Vec<String>,
    },
    /// `--base` / `--tip` names no link.
    UnknownOptionLink {
        option: &'static str,
        name: String,
        suggestion: Option<String>,
    },
    TipNotBelowBase {
        base: String,
        tip: String,
    },
    NoMovableJoint {
        base: String,
        tip: Option<String>,
    },
    AmbiguousChain {
        joints: usize,
        tips: Vec<String>,
    },
    /// A floating, planar or spherical joint on the chain.
    UnsupportedJoint {
        joint: String,
        kind: &'static str,
    },
    /// A `<mimic>` joint, or the joint it follows, on the chain.
    Mimic {
        joint: String,
        follower: String,
        master: String,
    },
    ZeroAxis {
        joint: String,
    },
    NonFinite {
        element: String,
        what: &'static str,
    },
    NegativeMass {
        link: String,
        m: f64,
    },
    TooManyJoints {
        count: usize,
    },
    BadName {
        name: String,
    },
    /// The conversion produced a table that does not reproduce the URDF (a bug).
    Internal(String),
}

impl fmt::Display for UrdfErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use UrdfErrorKind as K;
        match self {
            K::Io(e) => write!(f, "cannot read the file: {e} — check the path and permissions"),
            K::Xacro => write!(
                f,
                "this is a xacro file, not a URDF — expand it first: `xacro robot.urdf.xacro > robot.urdf`"
            ),
            K::Parse(msg) => write!(f, "not a valid URDF: {msg}"),
            K::UnknownJointType { joint, found } => write!(
                f,
                "<joint name=\"{joint}\">: unknown type `{found}` — URDF joint types are revolute, continuous, prismatic, fixed, floating, planar"
            ),
            K::Duplicate { element, name } => {
                write!(f, "two <{element}> elements are named `{name}` — names must be unique")
            }
            K::MissingLink { joint, role, link } => write!(
                f,
                "<joint name=\"{joint}\">: <{role} link=\"{link}\"> names no <link> — add the link or fix the name"
            ),
            K::ClosedLoop { link, joints } => write!(
                f,
                "<link name=\"{link}\"> is the child of {} joints ({}): a closed loop — dynid converts serial chains (a URDF must be a tree)",
                joints.len(),
                joints.join(", ")
            ),
            K::NoRoot => write!(
                f,
                "every link is the child of a joint, so the joints form a loop — a URDF must be a tree with one root link"
            ),
            K::SeveralRoots { roots } => write!(
                f,
                "{} root links ({}): the URDF is not one connected tree — connect them with joints",
                roots.len(),
                roots.join(", ")
            ),
            K::UnknownOptionLink { option, name, suggestion } => {
                write!(f, "{option} {name}: no such <link>")?;
                if let Some(s) = suggestion {
                    write!(f, " — did you mean `{s}`?")?;
                }
                Ok(())
            }
            K::TipNotBelowBase { base, tip } => write!(
                f,
                "--tip {tip} is not below --base {base} in the kinematic tree — pick a tip that descends from the base"
            ),
            K::NoMovableJoint { base, tip } => match tip {
                Some(tip) => write!(f, "no movable joint between `{base}` and `{tip}` — pick another --base/--tip"),
                None => write!(f, "no movable joint below `{base}` — nothing to convert"),
            },
            K::AmbiguousChain { joints, tips } => write!(
                f,
                "{} different chains have {joints} movable joints (ending at {}) — choose one with --tip LINK (and --base LINK)",
                tips.len(),
                tips.join(", ")
            ),
            K::UnsupportedJoint { joint, kind } => write!(
                f,
                "<joint name=\"{joint}\" type=\"{kind}\"> is on the chain: dynid converts fixed-base serial chains of revolute, continuous and prismatic joints — start the chain after it with --base LINK, or end it before it with --tip LINK"
            ),
            K::Mimic { joint, follower, master } => write!(
                f,
                "<joint name=\"{joint}\"> is on the chain but `{follower}` mimics `{master}`: a coupled joint is not an independent D-H joint — end the chain before it with --tip LINK"
            ),
            K::ZeroAxis { joint } => {
                write!(f, "<joint name=\"{joint}\">: <axis xyz=\"0 0 0\"> has no direction — give a non-zero axis")
            }
            K::NonFinite { element, what } => write!(f, "{element}: {what} is not a finite number"),
            K::NegativeMass { link, m } => {
                write!(f, "<link name=\"{link}\"> <inertial> <mass value=\"{m}\">: masses must be ≥ 0 kg")
            }
            K::TooManyJoints { count } => write!(
                f,
                "the chain has {count} movable joints; dynid handles at most {} — shorten it with --base/--tip",
                crate::dh::MAX_JOINTS
            ),
            K::BadName { name } => write!(
                f,
                "--name {name}: an arm name must start with a lowercase letter and contain only a-z, 0-9 and _"
            ),
            K::Internal(msg) => write!(f, "internal error in the D-H conversion (a bug in dynid — please report it): {msg}"),
        }
    }
}
