//! Modified (Craig) Denavit–Hartenberg tables: the one input the generator and the reference
//! dynamics are built from.
//!
//! Row `i` holds `α_{i-1}, a_{i-1}, d_i, θ_i` (metres, radians); frame `i` is reached from frame
//! `i-1` by `RotX(α_{i-1})·TransX(a_{i-1})·RotZ(θ_i)·TransZ(d_i)`, where `θ_i = q_i + theta` for a
//! revolute joint and `d_i = q_i + d` for a prismatic one.
//!
//! ```
//! let table = dynid::dh::DhTable::from_str(
//!     r#"
//! name = "planar2"
//! convention = "modified"
//! gravity = [0.0, -9.81, 0.0]
//! [[joint]]
//! kind = "revolute"
//! alpha = 0.0
//! a = 0.0
//! d = 0.0
//! theta = 0.0
//! [[joint]]
//! kind = "revolute"
//! alpha = 0.0
//! a = 1.0
//! d = 0.0
//! theta = 0.0
//! "#,
//!     "planar2.toml",
//! )?;
//! assert_eq!(table.dof(), 2);
//! # Ok::<(), dynid::dh::DhError>(())
//! ```

use std::f64::consts::TAU;
use std::fmt;
use std::path::Path;

use crate::diag::{Location, TomlProblem};
use crate::tomlread::{Fail, Src, TableView};

/// Most joints a table may have (the generator's unrolled kernels grow as O(n²)–O(n³)).
pub const MAX_JOINTS: usize = 12;

/// `source`: the URDF `import-urdf` read (see `crate::urdf::roundtrip::UrdfSource`).
const TOP_KEYS: [&str; 5] = ["name", "convention", "gravity", "joint", "source"];
const JOINT_KEYS: [&str; 11] = [
    "name", "kind", "alpha", "a", "d", "theta", "q_min", "q_max", "dq_max", "ddq_max", "tau_max",
];

/// Joint type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    Revolute,
    Prismatic,
}

/// One row of the table plus optional limits (SI units: rad or m, per second, N·m or N).
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// The joint's name as the robot's software calls it (e.g. the URDF joint, the `name[]` of
    /// a ROS `JointState`): how recorded bags are matched to the table (see [`crate::bag`]).
    /// Optional; when given, non-empty, without commas or surrounding spaces, and unique.
    pub name: Option<String>,
    pub kind: JointKind,
    /// `α_{i-1}`: twist about the previous frame's x axis (rad).
    pub alpha: f64,
    /// `a_{i-1}`: distance along the previous frame's x axis (m).
    pub a: f64,
    /// `d_i`: offset along z (m); for a prismatic joint added to `q_i`.
    pub d: f64,
    /// `θ_i` offset (rad); for a prismatic joint the fixed angle.
    pub theta: f64,
    pub q_min: Option<f64>,
    pub q_max: Option<f64>,
    pub dq_max: Option<f64>,
    pub ddq_max: Option<f64>,
    pub tau_max: Option<f64>,
}

/// A modified D-H table (`arms/<arm>.toml`).
#[derive(Debug, Clone, PartialEq)]
pub struct DhTable {
    pub name: String,
    /// Always `"modified"` (the only convention supported).
    pub convention: String,
    /// Gravitational acceleration in the base frame (m/s²), e.g. `[0, 0, -9.81]`.
    pub gravity: [f64; 3],
    pub joints: Vec<Joint>,
}

/// A D-H table that cannot be used, with where and how to fix it.
#[derive(Debug, thiserror::Error)]
#[error("{loc}: {kind}")]
pub struct DhError {
    pub loc: Location,
    /// Boxed: errors travel through `Result`s of hot-ish loader code; keep them small.
    pub kind: Box<DhErrorKind>,
}

/// What is wrong with a D-H table.
#[derive(Debug)]
pub enum DhErrorKind {
    /// The file could not be read.
    Io(std::io::Error),
    /// A TOML-level problem (syntax, unknown key, type, missing key, non-finite, length).
    Toml(TomlProblem),
    /// `|α|` or `|θ|` larger than 2π: almost certainly degrees.
    LooksLikeDegrees { value: f64 },
    /// No `[[joint]]` tables.
    NoJoints,
    /// More than [`MAX_JOINTS`] joints.
    TooManyJoints { count: usize },
    /// `convention` is not `"modified"`.
    Convention { found: String },
    /// `kind` is not `"revolute"` or `"prismatic"`.
    JointKind { found: String },
    /// `name` is empty.
    EmptyName,
    /// A limit that must be positive is not, or `q_min >= q_max`.
    BadLimit { what: &'static str },
    /// A joint `name` that is empty, has a comma or surrounding spaces.
    BadJointName { name: String },
    /// Two joints with the same `name` (`first`: the other joint, 1-based).
    DuplicateJointName { name: String, first: usize },
}

impl fmt::Display for DhErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DhErrorKind::Io(e) => write!(f, "cannot read the file: {e} — check the path and permissions"),
            DhErrorKind::Toml(p) => write!(f, "{p}"),
            DhErrorKind::LooksLikeDegrees { value } => write!(
                f,
                "{value} is larger than 2π in magnitude: looks like degrees — use radians, e.g. 1.5707963 for 90°"
            ),
            DhErrorKind::NoJoints => write!(
                f,
                "the table has no joints — add one `[[joint]]` table per joint (kind, alpha, a, d, theta)"
            ),
            DhErrorKind::TooManyJoints { count } => write!(
                f,
                "{count} joints; at most {MAX_JOINTS} are supported — split the chain or remove fixed joints"
            ),
            DhErrorKind::Convention { found } => write!(
                f,
                "convention `{found}` is not supported — only modified (Craig) D-H: write `convention = \"modified\"` and convert the table (α_{{i-1}}, a_{{i-1}}, d_i, θ_i)"
            ),
            DhErrorKind::JointKind { found } => write!(
                f,
                "joint kind `{found}` is not supported — use `\"revolute\"` or `\"prismatic\"` (fixed joints: merge them into the neighbouring rows)"
            ),
            DhErrorKind::EmptyName => write!(f, "the name is empty — give the arm a name, e.g. `name = \"my_arm\"`"),
            DhErrorKind::BadLimit { what } => write!(f, "{what} — fix or remove the limit"),
            DhErrorKind::BadJointName { name } => write!(
                f,
                "joint name `{name}` is empty, has a comma or surrounding spaces — give the name the robot's software uses (e.g. `name = \"shoulder_pan_joint\"`) or remove the key"
            ),
            DhErrorKind::DuplicateJointName { name, first } => write!(
                f,
                "joint name `{name}` is already used by joint {first} — joint names must be unique (they match recorded joint states to joints)"
            ),
        }
    }
}

impl From<Fail> for DhError {
    fn from(fail: Fail) -> Self {
        let (loc, problem) = *fail;
        DhError {
            loc,
            kind: Box::new(DhErrorKind::Toml(problem)),
        }
    }
}

impl DhTable {
    /// Reads and validates a table from a file; errors name the path as given.
    pub fn from_path(path: &Path) -> Result<Self, DhError> {
        let file = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|e| DhError {
            loc: Location::file(&file),
            kind: Box::new(DhErrorKind::Io(e)),
        })?;
        let text = String::from_utf8(bytes).map_err(|e| DhError {
            loc: Location::file(&file),
            kind: Box::new(DhErrorKind::Io(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                e,
            ))),
        })?;
        Self::from_str(&text, &file)
    }

    /// Parses and validates a table; `origin` names it in errors (usually the file path).
    #[allow(clippy::should_implement_trait)] // `FromStr` cannot take the origin name.
    pub fn from_str(text: &str, origin: &str) -> Result<Self, DhError> {
        let src = Src {
            file: origin,
            text: text.strip_prefix('\u{feff}').unwrap_or(text),
        };
        let doc = src.parse()?;
        let root = src.root(&doc);
        root.check_keys(&TOP_KEYS)?;

        let name = root.str_req("name")?.trim().to_string();
        if name.is_empty() {
            return Err(DhError {
                loc: root.loc_of("name"),
                kind: Box::new(DhErrorKind::EmptyName),
            });
        }
        let convention = root.str_req("convention")?.to_string();
        if convention != "modified" {
            return Err(DhError {
                loc: root.loc_of("convention"),
                kind: Box::new(DhErrorKind::Convention { found: convention }),
            });
        }
        let g = root.f64_array_req("gravity", Some(3))?;
        let gravity = [g[0], g[1], g[2]];

        let tables = root.tables("joint")?;
        if tables.is_empty() {
            return Err(DhError {
                loc: root.loc_of("joint"),
                kind: Box::new(DhErrorKind::NoJoints),
            });
        }
        if tables.len() > MAX_JOINTS {
            return Err(DhError {
                loc: tables[MAX_JOINTS].loc(),
                kind: Box::new(DhErrorKind::TooManyJoints {
                    count: tables.len(),
                }),
            });
        }
        let joints = tables
            .iter()
            .map(read_joint)
            .collect::<Result<Vec<_>, _>>()?;
        for (k, j) in joints.iter().enumerate() {
            let Some(name) = &j.name else { continue };
            if let Some(first) = joints[..k]
                .iter()
                .position(|o| o.name.as_ref() == Some(name))
            {
                return Err(DhError {
                    loc: tables[k].loc_of("name"),
                    kind: Box::new(DhErrorKind::DuplicateJointName {
                        name: name.clone(),
                        first: first + 1,
                    }),
                });
            }
        }
        Ok(DhTable {
            name,
            convention,
            gravity,
            joints,
        })
    }

    /// Degrees of freedom (number of joints).
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// Every joint's `name`, if all joints have one.
    pub fn joint_names(&self) -> Option<Vec<String>> {
        self.joints.iter().map(|j| j.name.clone()).collect()
    }
}

fn read_joint(t: &TableView<'_>) -> Result<Joint, DhError> {
    t.check_keys(&JOINT_KEYS)?;
    let name = match t.str_opt("name")? {
        Some(n) if n.is_empty() || n.contains(',') || n.trim() != n => {
            return Err(DhError {
                loc: t.loc_of("name"),
                kind: Box::new(DhErrorKind::BadJointName {
                    name: n.to_string(),
                }),
            })
        }
        n => n.map(str::to_string),
    };
    let kind = match t.str_req("kind")? {
        "revolute" => JointKind::Revolute,
        "prismatic" => JointKind::Prismatic,
        other => {
            return Err(DhError {
                loc: t.loc_of("kind"),
                kind: Box::new(DhErrorKind::JointKind {
                    found: other.to_string(),
                }),
            })
        }
    };
    let angle = |key: &str| -> Result<f64, DhError> {
        let v = t.f64_req(key)?;
        if v.abs() > TAU + 1e-9 {
            return Err(DhError {
                loc: t.loc_of(key),
                kind: Box::new(DhErrorKind::LooksLikeDegrees { value: v }),
            });
        }
        Ok(v)
    };
    let alpha = angle("alpha")?;
    let theta = angle("theta")?;
    let a = t.f64_req("a")?;
    let d = t.f64_req("d")?;
    let q_min = t.f64_opt("q_min")?;
    let q_max = t.f64_opt("q_max")?;
    if let (Some(lo), Some(hi)) = (q_min, q_max) {
        if lo >= hi {
            return Err(DhError {
                loc: t.loc_of("q_max"),
                kind: Box::new(DhErrorKind::BadLimit {
                    what: "q_max must be greater than q_min",
                }),
            });
        }
    }
    let positive = |key: &'static str, what: &'static str| -> Result<Option<f64>, DhError> {
        match t.f64_opt(key)? {
            Some(v) if v <= 0.0 => Err(DhError {
                loc: t.loc_of(key),
                kind: Box::new(DhErrorKind::BadLimit { what }),
            }),
            v => Ok(v),
        }
    };
    let dq_max = positive("dq_max", "dq_max must be positive")?;
    let ddq_max = positive("ddq_max", "ddq_max must be positive")?;
    let tau_max = positive("tau_max", "tau_max must be positive")?;
    Ok(Joint {
        name,
        kind,
        alpha,
        a,
        d,
        theta,
        q_min,
        q_max,
        dq_max,
        ddq_max,
        tau_max,
    })
}
