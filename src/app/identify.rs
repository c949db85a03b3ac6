//! `identify` as both front ends run it: [`IdentifyArgs`] (the flags or keywords as given) are
//! checked once into an [`IdentifyRequest`] (the library's [`Config`], the reader of the data,
//! what to do with warnings), which opens the sources and identifies; [`Identified`] is the
//! outcome the CLI writes and Python returns. Nothing here prints or writes but
//! [`Identified::write`].

use std::path::{Path, PathBuf};

use super::options::{self, CutoffArg};
use super::source::{DataSource, Opened, ReadArgs, Reader};
use super::{AppError, Front};
use crate::arms::ArmSource;
use crate::effects::parse_list;
use crate::identify::{self, physical::PhysicalOptions, Config, IdentifyError, Outcome, Smoothing};
use crate::log::Log;
use crate::params::{InertialParams, ParamsOptions};
use crate::progress::Progress;
use crate::urdf::roundtrip::UrdfSource;

/// The options of `identify` as a front end got them. Python's keyword names; the CLI's flags
/// are the same with dashes.
#[derive(Debug, Clone)]
pub struct IdentifyArgs {
    /// `auto` (search), `none` or a list such as `viscous,coulomb:2`.
    pub effects: String,
    pub cutoff: CutoffArg,
    /// `auto` or `RATIO,PREDICTION` (see [`Smoothing::parse`]).
    pub smoothing: String,
    /// `auto` (held-out scan) or the Coulomb sign's smoothing velocity as a fraction of each
    /// joint's RMS velocity, e.g. `0.01`.
    pub coulomb_width: String,
    /// `butterworth` or `savgol`.
    pub derivative: String,
    /// Use a file's dq column (filtered) instead of differentiating q.
    pub file_velocity: bool,
    /// The physically consistent estimate.
    pub physical: bool,
    /// Parameters the consistent estimate is pulled towards.
    pub prior: Option<PathBuf>,
    /// Warnings (what the data cannot identify) are an error.
    pub strict: bool,
    /// Hold each training source out in turn (no validation source then).
    pub leave_one_out: bool,
    pub read: ReadArgs,
}

impl Default for IdentifyArgs {
    fn default() -> Self {
        IdentifyArgs {
            effects: "auto".into(),
            cutoff: CutoffArg::default(),
            smoothing: "auto".into(),
            coulomb_width: "auto".into(),
            derivative: "butterworth".into(),
            file_velocity: true,
            physical: true,
            prior: None,
            strict: false,
            leave_one_out: false,
            read: ReadArgs::default(),
        }
    }
}

/// A checked identification: runs on sources.
#[derive(Debug, Clone)]
pub struct IdentifyRequest {
    pub config: Config,
    pub strict: bool,
    front: Front,
    reader: Reader,
}

/// What an identification found, and the notes and warnings for the user.
#[derive(Debug)]
pub struct Identified {
    pub outcome: Outcome,
    /// What the data cannot identify (deduplicated): printed or warned, never fatal here.
    pub warnings: Vec<String>,
    /// What the readers want the user to know (a bag's time base and topic).
    pub notes: Vec<String>,
}

impl IdentifyArgs {
    /// Checks every option for `arm`, before any data is read; `train` and `validate` count
    /// the sources (for `leave_one_out`).
    pub fn request(
        &self,
        arm: &ArmSource,
        train: usize,
        validate: bool,
        front: Front,
    ) -> Result<IdentifyRequest, AppError> {
        let dof = arm.dof();
        let effects = parse_list(&self.effects, dof).map_err(|e| {
            let e = e.strip_prefix("--effects: ").unwrap_or(&e).to_string();
            AppError::Input(format!("{}: {e}", front.name("effects")))
        })?;
        let derivative = options::derivative(&self.derivative, &self.cutoff, front)?;
        let smoothing = match self.smoothing.trim() {
            "auto" => None,
            s => Some(
                Smoothing::parse(s)
                    .map_err(|e| AppError::Input(format!("{}: {e}", front.name("smoothing"))))?,
            ),
        };
        let coulomb_width = match self.coulomb_width.trim() {
            "auto" => None,
            s => match s.parse::<f64>() {
                Ok(f) if f.is_finite() && f > 0.0 && f <= 1.0 => Some(f),
                _ => {
                    return Err(AppError::Input(format!(
                        "{}: `{s}` is not `auto` or a fraction in (0, 1] of the RMS joint velocity (e.g. 0.01)",
                        front.name("coulomb_width")
                    )))
                }
            },
        };
        if train == 0 {
            return Err(AppError::Input(format!(
                "{}: no training data — give at least one file or table",
                front.name("data")
            )));
        }
        if self.leave_one_out && (train < 2 || validate) {
            return Err(AppError::Input(format!(
                "{} needs at least two {} files and no {}",
                front.name("leave_one_out"),
                front.name("data"),
                front.name("validate")
            )));
        }
        let config = Config {
            smoothing,
            coulomb_width,
            derivative,
            file_velocity: self.file_velocity,
            effects,
            physical: self.physical_options(dof, front)?,
            ..Config::default()
        };
        Ok(IdentifyRequest {
            config,
            strict: self.strict,
            front,
            reader: self.read.for_arm(arm, front, true)?,
        })
    }

    /// `physical` and `prior`: the prior must be a physically consistent params file of this arm.
    fn physical_options(&self, dof: usize, front: Front) -> Result<PhysicalOptions, AppError> {
        let prior = match &self.prior {
            Some(path) => {
                let p = InertialParams::from_path(path, dof, &ParamsOptions::default())
                    .map_err(|e| {
                        AppError::Input(format!(
                            "{}: {e} — the prior must be a physically consistent parameter file of this arm",
                            front.name("prior")
                        ))
                    })?;
                Some(p.full_vector())
            }
            None => None,
        };
        if prior.is_some() && !self.physical {
            return Err(AppError::Input(format!(
                "{} needs the consistent estimate: drop {}",
                front.name("prior"),
                front.setting("physical", "off", "False")
            )));
        }
        Ok(PhysicalOptions {
            enabled: self.physical,
            prior,
            prior_source: self.prior.as_ref().map(|p| format!("`{}`", p.display())),
        })
    }
}

/// An identification error as the CLI always reported it: a data file's own error, or bad input.
fn identify_error(e: IdentifyError) -> AppError {
    match e {
        IdentifyError::Data(d) => AppError::Data(d),
        other => AppError::Input(other.to_string()),
    }
}

impl IdentifyRequest {
    /// Reports progress to `progress`.
    pub fn with_progress(mut self, progress: Progress) -> Self {
        self.config.progress = progress;
        self
    }

    /// Opens `sources`, collecting the readers' notes.
    fn open(&self, sources: &[DataSource], notes: &mut Vec<String>) -> Result<Vec<Log>, AppError> {
        sources
            .iter()
            .map(|s| {
                let Opened { log, notes: n } = self.reader.log(s)?;
                notes.extend(n);
                Ok(log)
            })
            .collect()
    }

    /// The outcomes' warnings, deduplicated; with `strict` an error that lists them.
    fn warnings(&self, outs: &[&Outcome]) -> Result<Vec<String>, AppError> {
        let mut all: Vec<String> = outs.iter().flat_map(|o| o.warnings.clone()).collect();
        all.dedup();
        if self.strict && !all.is_empty() {
            let list: Vec<String> = all.iter().map(|w| format!("  - {w}")).collect();
            return Err(AppError::Input(format!(
                "{}: the data cannot identify everything:\n{}",
                self.front.name("strict"),
                list.join("\n")
            )));
        }
        Ok(all)
    }

    /// Identifies `arm` from `train`, judged on `validate`.
    pub fn run(
        &self,
        arm: &ArmSource,
        train: &[DataSource],
        validate: Option<&DataSource>,
    ) -> Result<Identified, AppError> {
        let mut notes = Vec::new();
        let logs = self.open(train, &mut notes)?;
        let val = match validate {
            Some(v) => self.open(std::slice::from_ref(v), &mut notes)?.pop(),
            None => None,
        };
        let outcome = identify::run(arm, logs, val, &self.config).map_err(identify_error)?;
        let warnings = self.warnings(&[&outcome])?;
        Ok(Identified {
            outcome,
            warnings,
            notes,
        })
    }

    /// Holds each of `train` out in turn: one outcome per fold, and the folds' warnings.
    pub fn leave_one_out(&self, arm: &ArmSource, train: &[DataSource]) -> Result<Folds, AppError> {
        let mut notes = Vec::new();
        let logs = self.open(train, &mut notes)?;
        let outs = identify::leave_one_out(arm, logs, &self.config).map_err(identify_error)?;
        let warnings = self.warnings(&outs.iter().collect::<Vec<_>>())?;
        Ok(Folds {
            outs,
            warnings,
            notes,
        })
    }
}

/// A leave-one-out study: one outcome per held-out source, and (as in [`Identified`]) the
/// warnings and the readers' notes.
#[derive(Debug)]
pub struct Folds {
    pub outs: Vec<Outcome>,
    pub warnings: Vec<String>,
    pub notes: Vec<String>,
}

/// What [`Identified::write`] wrote.
#[derive(Debug, Default)]
pub struct Written {
    /// The report's files.
    pub files: Vec<PathBuf>,
    /// `identified.urdf`, for an arm read from a URDF.
    pub urdf: Option<PathBuf>,
    /// What the URDF round trip wants the user to know.
    pub notes: Vec<String>,
}

impl Identified {
    /// Writes the report into `dir` (`command` reproduces the run) and, for an arm read from a
    /// URDF (`urdf`), `identified.urdf`: that URDF with the identified inertials.
    pub fn write(
        &self,
        dir: &Path,
        command: &str,
        arm: &ArmSource,
        urdf: Option<&UrdfSource>,
    ) -> Result<Written, AppError> {
        let table = arm.dh_table().ok();
        let files = crate::report::write(dir, &self.outcome, command, table.as_ref())
            .map_err(|e| AppError::step("writing the report", e))?;
        let mut written = Written {
            files,
            ..Written::default()
        };
        let Some(source) = urdf else {
            return Ok(written);
        };
        let Some(rt) = crate::report::physical::urdf_roundtrip(&self.outcome, source) else {
            return Ok(written);
        };
        let rt =
            rt.map_err(|e| AppError::step("writing identified.urdf into the arm's URDF", e))?;
        written.notes = rt
            .notes
            .iter()
            .map(|n| format!("identified.urdf: {n}"))
            .collect();
        let path = dir.join("identified.urdf");
        crate::io::atomic_write(&path, |w| w.write_all(rt.urdf.as_bytes()))
            .map_err(|e| AppError::step(format!("writing {}", path.display()), e))?;
        written.urdf = Some(path);
        Ok(written)
    }
}

/// Writes the leave-one-out study of `arm` (`outs`, one per fold) into `dir`: each fold's report
/// and the summary table, which is returned.
pub fn write_leave_one_out(
    dir: &Path,
    outs: &[Outcome],
    command: &str,
    arm: &ArmSource,
) -> Result<String, AppError> {
    let table = arm.dh_table().ok();
    crate::report::leave_one_out::write(dir, outs, command, table.as_ref())
        .map_err(|e| AppError::step("writing the leave-one-out report", e))
}
