//! The limits an excitation must respect, per joint: position range, peak velocity, peak
//! acceleration and (optionally) peak torque, and the rest posture `q0` the motion starts and
//! ends at.
//!
//! Sources, later ones overriding earlier ones field by field: the arm's table (for a URDF the
//! `<limit lower upper velocity effort>` of each joint, tightened by `<safety_controller>`'s soft
//! limits where present), a limits TOML ([`LimitsFile`]), then explicit per-joint lists (the
//! CLI's `--q-min` … flags). A joint that none of these gives an acceleration limit takes one
//! derived from the arm's effort limit and inertia where it can ([`super::derived`], the lowest
//! priority source). A joint left without a position, velocity or acceleration limit is an error
//! naming it.
//!
//! ```
//! use dynid::excitation::limits::{LimitSources, Overrides};
//! let src = LimitSources {
//!     names: vec!["j1".into()],
//!     overrides: Overrides {
//!         q_min: Some(vec![-1.0]), q_max: Some(vec![2.0]),
//!         dq_max: Some(vec![1.0]), ddq_max: Some(vec![5.0]), ..Overrides::default()
//!     },
//!     ..LimitSources::default()
//! };
//! let l = src.resolve().unwrap();
//! assert_eq!(l.q0, vec![0.5]); // the middle of the range by default
//! ```

use std::path::Path;

use serde::Serialize;

use crate::dh::DhTable;
use crate::diag::Location;
use crate::tomlread::{Fail, Src};

/// Limits of one joint, as used by the design.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JointLimits {
    /// Joint name (the URDF's or the table's), or `joint N`.
    pub name: String,
    pub q_min: f64,
    pub q_max: f64,
    pub dq_max: f64,
    pub ddq_max: f64,
    /// Peak torque (N·m or N); checked only when inertial parameters are given.
    pub tau_max: Option<f64>,
    /// Where each value came from, e.g. `q: urdf safety_controller, dq: urdf, ddq: --ddq-max`.
    pub source: String,
}

/// The limits of every joint and the rest posture.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Limits {
    pub joints: Vec<JointLimits>,
    /// Start and end posture.
    pub q0: Vec<f64>,
    /// Where limits were derived rather than given, and which model the torques are checked
    /// with (printed by the CLI, kept in `excitation.json`).
    pub notes: Vec<String>,
}

/// One joint's partial limits from one source.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Partial {
    pub q_min: Option<f64>,
    pub q_max: Option<f64>,
    pub dq_max: Option<f64>,
    pub ddq_max: Option<f64>,
    pub tau_max: Option<f64>,
}

/// Per-joint lists that override every file (the CLI flags); each has one value per joint.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides {
    pub q_min: Option<Vec<f64>>,
    pub q_max: Option<Vec<f64>>,
    pub dq_max: Option<Vec<f64>>,
    pub ddq_max: Option<Vec<f64>>,
    pub tau_max: Option<Vec<f64>>,
    pub q0: Option<Vec<f64>>,
}

/// Everything the limits are resolved from.
#[derive(Debug, Clone, Default)]
pub struct LimitSources {
    /// Joint names, one per joint (defines the number of joints).
    pub names: Vec<String>,
    /// From the arm (table / URDF), labelled e.g. `urdf`.
    pub arm: Vec<Partial>,
    pub arm_label: String,
    /// URDF `<safety_controller>` soft position limits per joint (tighten the arm's range).
    pub soft: Vec<(Option<f64>, Option<f64>)>,
    /// A limits TOML and its path (for the source labels).
    pub file: Option<(String, Vec<Partial>)>,
    pub overrides: Overrides,
    /// Last resort for a joint no other source gives an acceleration limit: a value derived from
    /// the arm's model ([`super::derived`]) or why there is none, per joint, and its label.
    /// Empty: none derived.
    pub derived_ddq: Vec<Result<f64, String>>,
    pub derived_label: String,
}

/// One joint's values after merging the sources, each with the label of the source it came from.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Merged {
    pub q_min: (Option<f64>, String),
    pub q_max: (Option<f64>, String),
    pub dq_max: (Option<f64>, String),
    pub ddq_max: (Option<f64>, String),
    pub tau_max: (Option<f64>, String),
}

/// Bad or missing limits; every message names the joint (or file, line and field).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LimitError {
    #[error("joint {joint} ({name}) has no {what}{why} — give it in the URDF, in --limits FILE ({key} = …) or with {flag}")]
    Missing {
        joint: usize,
        name: String,
        what: &'static str,
        key: &'static str,
        flag: &'static str,
        /// Why none could be derived (`", and none can be derived: …"`), or empty.
        why: String,
    },
    #[error("joint {joint} ({name}): {problem}")]
    Bad {
        joint: usize,
        name: String,
        problem: String,
    },
    #[error("{flag}: {problem}")]
    Flag { flag: &'static str, problem: String },
    #[error("{loc}: {problem}")]
    File { loc: Location, problem: String },
}

impl From<Fail> for LimitError {
    fn from(f: Fail) -> Self {
        let (loc, problem) = *f;
        LimitError::File {
            loc,
            problem: problem.to_string(),
        }
    }
}

/// What a limits TOML holds: `[[joint]]` tables in joint order, each with any of `name`,
/// `q_min`, `q_max`, `dq_max`, `ddq_max`, `tau_max` (rad, rad/s, rad/s², N·m).
pub struct LimitsFile;

const FILE_KEYS: [&str; 6] = ["name", "q_min", "q_max", "dq_max", "ddq_max", "tau_max"];

impl LimitsFile {
    /// Reads a limits TOML for `dof` joints (errors name the file, line and field).
    pub fn read(path: &Path, dof: usize) -> Result<Vec<Partial>, LimitError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| LimitError::File {
            loc: Location::file(&file),
            problem: format!("cannot read: {e}"),
        })?;
        Self::parse(&text, &file, dof)
    }

    /// Parses the text of a limits TOML; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str, dof: usize) -> Result<Vec<Partial>, LimitError> {
        let src = Src { file: origin, text };
        let doc = src.parse()?;
        let root = src.root(&doc);
        root.check_keys(&["joint"])?;
        let tables = root.tables("joint")?;
        if tables.len() != dof {
            return Err(LimitError::File {
                loc: root.loc_of("joint"),
                problem: format!(
                    "{} [[joint]] tables for an arm of {dof} joints (one per joint, in order)",
                    tables.len()
                ),
            });
        }
        let mut out = Vec::with_capacity(dof);
        for t in &tables {
            t.check_keys(&FILE_KEYS)?;
            let _ = t.str_opt("name")?;
            let p = Partial {
                q_min: t.f64_opt("q_min")?,
                q_max: t.f64_opt("q_max")?,
                dq_max: t.f64_opt("dq_max")?,
                ddq_max: t.f64_opt("ddq_max")?,
                tau_max: t.f64_opt("tau_max")?,
            };
            for (key, v) in [
                ("dq_max", p.dq_max),
                ("ddq_max", p.ddq_max),
                ("tau_max", p.tau_max),
            ] {
                if v.is_some_and(|v| v <= 0.0) {
                    return Err(LimitError::File {
                        loc: t.loc_of(key),
                        problem: format!("must be > 0 (got {})", v.unwrap_or(0.0)),
                    });
                }
            }
            out.push(p);
        }
        Ok(out)
    }
}

/// The arm's own limits from its D-H table (an imported URDF's `<limit>` values).
pub fn from_table(table: &DhTable) -> Vec<Partial> {
    table
        .joints
        .iter()
        .map(|j| Partial {
            q_min: j.q_min,
            q_max: j.q_max,
            dq_max: j.dq_max,
            ddq_max: j.ddq_max,
            tau_max: j.tau_max,
        })
        .collect()
}

/// `<safety_controller>` soft position limits of the URDF joints named `chain` (in order);
/// `(None, None)` where a joint has none or the file cannot be read again.
pub fn soft_limits(urdf: &Path, chain: &[String]) -> Vec<(Option<f64>, Option<f64>)> {
    let robot = std::fs::read_to_string(urdf)
        .ok()
        .and_then(|t| urdf_rs::read_from_string(&t).ok());
    chain
        .iter()
        .map(|name| {
            let sc = robot
                .as_ref()
                .and_then(|r| r.joints.iter().find(|j| &j.name == name))
                .and_then(|j| j.safety_controller.clone());
            match sc {
                Some(s) if s.soft_lower_limit < s.soft_upper_limit => {
                    (Some(s.soft_lower_limit), Some(s.soft_upper_limit))
                }
                _ => (None, None),
            }
        })
        .collect()
}

/// Parses a comma list for `dof` joints: one value (every joint) or `dof` values.
pub fn parse_list(flag: &'static str, text: &str, dof: usize) -> Result<Vec<f64>, LimitError> {
    let vals: Result<Vec<f64>, _> = text
        .split(',')
        .map(|s| {
            let s = s.trim();
            s.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| LimitError::Flag {
                    flag,
                    problem: format!("`{s}` is not a finite number"),
                })
        })
        .collect();
    let vals = vals?;
    match vals.len() {
        1 => Ok(vec![vals[0]; dof]),
        n if n == dof => Ok(vals),
        n => Err(LimitError::Flag {
            flag,
            problem: format!("{n} values for an arm of {dof} joints (give 1 or {dof})"),
        }),
    }
}

impl LimitSources {
    /// Merges the sources and validates the result (see the module docs).
    pub fn resolve(&self) -> Result<Limits, LimitError> {
        let n = self.names.len();
        let o = &self.overrides;
        for (flag, v) in [
            ("--q-min", &o.q_min),
            ("--q-max", &o.q_max),
            ("--dq-max", &o.dq_max),
            ("--ddq-max", &o.ddq_max),
            ("--tau-max", &o.tau_max),
            ("--q0", &o.q0),
        ] {
            if let Some(v) = v {
                if v.len() != n {
                    return Err(LimitError::Flag {
                        flag,
                        problem: format!("{} values for an arm of {n} joints", v.len()),
                    });
                }
            }
        }
        let mut joints = Vec::with_capacity(n);
        let mut q0 = Vec::with_capacity(n);
        for j in 0..n {
            let name = self.names[j].clone();
            let Merged {
                q_min: (lo, lo_src),
                q_max: (hi, hi_src),
                dq_max: (dq, dq_src),
                ddq_max: (ddq, ddq_src),
                tau_max: (tau, tau_src),
            } = self.merged(j);
            let (ddq, ddq_src, why) = match (ddq, self.derived_ddq.get(j)) {
                (Some(v), _) => (Some(v), ddq_src, String::new()),
                (None, Some(Ok(v))) => (Some(*v), self.derived_label.clone(), String::new()),
                (None, Some(Err(e))) => (None, ddq_src, format!(", and none can be derived: {e}")),
                (None, None) => (None, ddq_src, String::new()),
            };
            let missing = |what, key, flag, why: &str| LimitError::Missing {
                joint: j + 1,
                name: name.clone(),
                what,
                key,
                flag,
                why: why.to_string(),
            };
            let lo = lo.ok_or_else(|| missing("lower position limit", "q_min", "--q-min", ""))?;
            let hi = hi.ok_or_else(|| missing("upper position limit", "q_max", "--q-max", ""))?;
            let dq = dq.ok_or_else(|| missing("velocity limit", "dq_max", "--dq-max", ""))?;
            let ddq =
                ddq.ok_or_else(|| missing("acceleration limit", "ddq_max", "--ddq-max", &why))?;
            let bad = |problem: String| LimitError::Bad {
                joint: j + 1,
                name: name.clone(),
                problem,
            };
            if lo >= hi {
                return Err(bad(format!(
                    "q_min = {lo} is not below q_max = {hi} ({lo_src}, {hi_src})"
                )));
            }
            for (what, v, src) in [
                ("dq_max", Some(dq), &dq_src),
                ("ddq_max", Some(ddq), &ddq_src),
                ("tau_max", tau, &tau_src),
            ] {
                if let Some(v) = v {
                    if !(v > 0.0 && v.is_finite()) {
                        return Err(bad(format!("{what} = {v} must be > 0 ({src})")));
                    }
                }
            }
            let start = o.q0.as_ref().map_or(0.5 * (lo + hi), |v| v[j]);
            if !(start > lo && start < hi) {
                return Err(bad(format!(
                    "q0 = {start} is not strictly inside [q_min, q_max] = [{lo}, {hi}]: the motion starts and ends there — pass --q0 inside the range"
                )));
            }
            q0.push(start);
            let mut source =
                format!("q_min: {lo_src}, q_max: {hi_src}, dq: {dq_src}, ddq: {ddq_src}");
            if tau.is_some() {
                source.push_str(&format!(", tau: {tau_src}"));
            }
            joints.push(JointLimits {
                name,
                q_min: lo,
                q_max: hi,
                dq_max: dq,
                ddq_max: ddq,
                tau_max: tau,
                source,
            });
        }
        Ok(Limits {
            joints,
            q0,
            notes: Vec::new(),
        })
    }

    /// Joint `j`'s values from the arm, the file and the flags (the last source that has a
    /// field wins; the safety controller narrows the arm's range), before anything is derived.
    pub fn merged(&self, j: usize) -> Merged {
        let o = &self.overrides;
        let pick = |arm: Option<f64>,
                    file: Option<f64>,
                    flag: Option<f64>,
                    flag_name: &'static str|
         -> (Option<f64>, String) {
            if let Some(v) = flag {
                (Some(v), flag_name.to_string())
            } else if let Some(v) = file {
                let label = self.file.as_ref().map(|f| f.0.clone()).unwrap_or_default();
                (Some(v), label)
            } else {
                (arm, self.arm_label.clone())
            }
        };
        let arm = self.arm.get(j).cloned().unwrap_or_default();
        let file = self
            .file
            .as_ref()
            .and_then(|f| f.1.get(j).cloned())
            .unwrap_or_default();
        let flag = |v: &Option<Vec<f64>>| v.as_ref().and_then(|v| v.get(j).copied());
        let soft = self.soft.get(j).copied().unwrap_or((None, None));
        // The safety controller's soft range is where the controller lets the joint go.
        let arm_lo = match (arm.q_min, soft.0) {
            (Some(a), Some(s)) => Some(a.max(s)),
            (a, None) => a,
            (None, s) => s,
        };
        let arm_hi = match (arm.q_max, soft.1) {
            (Some(a), Some(s)) => Some(a.min(s)),
            (a, None) => a,
            (None, s) => s,
        };
        Merged {
            q_min: pick(arm_lo, file.q_min, flag(&o.q_min), "--q-min"),
            q_max: pick(arm_hi, file.q_max, flag(&o.q_max), "--q-max"),
            dq_max: pick(arm.dq_max, file.dq_max, flag(&o.dq_max), "--dq-max"),
            ddq_max: pick(arm.ddq_max, file.ddq_max, flag(&o.ddq_max), "--ddq-max"),
            tau_max: pick(arm.tau_max, file.tau_max, flag(&o.tau_max), "--tau-max"),
        }
    }
}

impl Limits {
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// Checks that a period leaves room to move: within `period` each joint must be able to
    /// travel 10 % of its range and back at its velocity and acceleration limits (a bang-bang
    /// profile); otherwise the design could only dither around `q0`.
    pub fn check_period(&self, period: f64) -> Result<(), LimitError> {
        for (j, l) in self.joints.iter().enumerate() {
            let d = 0.1 * (l.q_max - l.q_min);
            // time to travel d from rest to rest: triangular or trapezoidal velocity profile
            let t = if d < l.dq_max * l.dq_max / l.ddq_max {
                2.0 * (d / l.ddq_max).sqrt()
            } else {
                d / l.dq_max + l.dq_max / l.ddq_max
            };
            if 2.0 * t > period {
                return Err(LimitError::Bad {
                    joint: j + 1,
                    name: l.name.clone(),
                    problem: format!(
                        "--period {period} s is too short for its limits: moving 10 % of its range ({d:.3}) and back takes {:.3} s at dq_max = {}, ddq_max = {} — lengthen --period or raise the limits",
                        2.0 * t,
                        l.dq_max,
                        l.ddq_max
                    ),
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sources() -> LimitSources {
        LimitSources {
            names: vec!["a".into(), "b".into()],
            arm: vec![
                Partial {
                    q_min: Some(-2.0),
                    q_max: Some(2.0),
                    dq_max: Some(1.0),
                    ..Partial::default()
                },
                Partial {
                    q_min: Some(-1.0),
                    q_max: Some(1.0),
                    dq_max: Some(2.0),
                    tau_max: Some(10.0),
                    ..Partial::default()
                },
            ],
            arm_label: "urdf".into(),
            soft: vec![(Some(-1.5), Some(3.0)), (None, None)],
            file: None,
            overrides: Overrides {
                ddq_max: Some(vec![3.0, 4.0]),
                ..Overrides::default()
            },
            derived_ddq: Vec::new(),
            derived_label: String::new(),
        }
    }

    /// A derived acceleration limit fills only a joint no source gives one, and a joint it
    /// cannot fill stays an error that names it and says why.
    #[test]
    fn derived_acceleration_is_the_last_resort() {
        let mut s = sources();
        s.overrides.ddq_max = None;
        s.file = Some((
            "lim.toml".into(),
            LimitsFile::parse("[[joint]]\n[[joint]]\nddq_max = 7\n", "lim.toml", 2).unwrap(),
        ));
        s.derived_ddq = vec![Ok(20.0), Ok(30.0)];
        s.derived_label = "urdf effort/inertia".into();
        let l = s.resolve().unwrap();
        assert_eq!(l.joints[0].ddq_max, 20.0);
        assert!(l.joints[0].source.contains("ddq: urdf effort/inertia"));
        assert_eq!(l.joints[1].ddq_max, 7.0); // the file wins over the derived value
        assert!(l.joints[1].source.contains("ddq: lim.toml"));
        s.derived_ddq[0] = Err("it has no effort limit either".into());
        let e = s.resolve().unwrap_err().to_string();
        assert!(
            e.contains("joint 1 (a)") && e.contains("no effort limit") && e.contains("--ddq-max"),
            "{e}"
        );
    }

    #[test]
    fn sources_merge_in_order_and_soft_limits_tighten() {
        let mut s = sources();
        let text = "[[joint]]\ndq_max = 0.5\n[[joint]]\nq_max = 0.5\n";
        s.file = Some((
            "lim.toml".into(),
            LimitsFile::parse(text, "lim.toml", 2).unwrap(),
        ));
        s.overrides.q_min = Some(vec![-1.8, -0.9]);
        let l = s.resolve().unwrap();
        // soft lower −1.5 is tighter than −2 but the flag overrides both
        assert_eq!(l.joints[0].q_min, -1.8);
        assert_eq!(l.joints[0].q_max, 2.0); // soft upper 3.0 is looser than the hard 2.0
        assert_eq!(l.joints[0].dq_max, 0.5); // file over arm
        assert_eq!(l.joints[1].q_max, 0.5);
        assert_eq!(l.joints[1].tau_max, Some(10.0));
        assert!(
            l.joints[1].source.contains("lim.toml"),
            "{}",
            l.joints[1].source
        );
        assert!((l.q0[0] - 0.1).abs() < 1e-15 && (l.q0[1] + 0.2).abs() < 1e-15);
    }

    #[test]
    fn bad_limits_name_the_joint_and_the_value() {
        let mut s = sources();
        s.overrides.ddq_max = None;
        let e = s.resolve().unwrap_err().to_string();
        assert!(e.contains("joint 1 (a)") && e.contains("--ddq-max"), "{e}");

        let mut s = sources();
        s.overrides.q_min = Some(vec![0.0, 1.0]);
        let e = s.resolve().unwrap_err().to_string();
        assert!(e.contains("joint 2 (b)") && e.contains("q_min = 1"), "{e}");

        let mut s = sources();
        s.overrides.q0 = Some(vec![0.0, 1.5]);
        let e = s.resolve().unwrap_err().to_string();
        assert!(e.contains("joint 2 (b)") && e.contains("q0 = 1.5"), "{e}");

        let l = sources().resolve().unwrap();
        let e = l.check_period(0.5).unwrap_err().to_string();
        assert!(
            e.contains("joint 1 (a)") && e.contains("--period 0.5"),
            "{e}"
        );
        assert!(l.check_period(10.0).is_ok());
    }

    #[test]
    fn a_bad_limits_file_names_the_line_and_field() {
        let e = LimitsFile::parse("[[joint]]\nq_min = 0\ndq_max = -1\n", "l.toml", 1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("l.toml:3") && e.contains("dq_max"), "{e}");
        let e = LimitsFile::parse("[[joint]]\nqmin = 0\n", "l.toml", 1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("l.toml:2"), "{e}");
        let e = LimitsFile::parse("[[joint]]\n", "l.toml", 2)
            .unwrap_err()
            .to_string();
        assert!(e.contains("1 [[joint]] tables"), "{e}");
        let e = parse_list("--q-max", "1,x", 2).unwrap_err().to_string();
        assert!(e.contains("--q-max") && e.contains("`x`"), "{e}");
        assert_eq!(parse_list("--q-max", "2", 3).unwrap(), vec![2.0; 3]);
    }
}
