//! `dynid.identify`: the CLI's `identify` on files or arrays.
//!
//! An array (or a DataFrame, converted by `dynid/__init__.py` into column names + a float64
//! block) is streamed through the CSV reader of the library as the CSV text it stands for
//! (header = the column names, one line per row, each value in Rust's shortest round-trip form,
//! so the reader parses back exactly the array's values). Every check and message of the CLI
//! applies unchanged: a row is named by its line in that text (line 1 the header, row `i` of
//! the array line `i + 2`).

use std::io::Read;
use std::path::PathBuf;

use dynid::arms::ArmSource;
use dynid::bag::{self, BagOptions};
use dynid::data::Trajectory;
use dynid::derivative::{Method, Options as DerivativeOptions};
use dynid::effects::parse_list;
use dynid::identify::{self, physical::PhysicalOptions, Config, Smoothing};
use dynid::log::Log;
use dynid::params::{InertialParams, ParamsOptions};

/// One training or validation input.
pub enum Source<'a> {
    Path(PathBuf),
    /// A label for messages (`data[0]`), the column names and `rows × names.len()` values.
    Table {
        label: String,
        names: Vec<String>,
        values: &'a [f64],
    },
}

/// Options of a run (the CLI's flags).
pub struct Options {
    pub effects: String,
    pub cutoff: Option<f64>,
    pub smoothing: String,
    pub derivative: String,
    pub file_velocity: bool,
    pub physical: bool,
    pub prior: Option<PathBuf>,
    pub strict: bool,
    pub out: Option<PathBuf>,
    pub command: String,
    pub topic: Option<String>,
    pub joints: Option<Vec<String>>,
    pub torque_scale: Option<Vec<f64>>,
}

/// What the Python side gets: `report.json` as text, the files written, the warnings.
pub struct Ran {
    pub json: String,
    pub files: Vec<String>,
    pub warnings: Vec<String>,
}

/// Streams `values` (`rows × names.len()`) as CSV text.
pub(crate) struct CsvText<'a> {
    values: &'a [f64],
    width: usize,
    row: usize,
    buf: Vec<u8>,
    at: usize,
}

impl<'a> CsvText<'a> {
    pub(crate) fn new(names: &[String], values: &'a [f64]) -> Self {
        let mut buf = names.join(",").into_bytes();
        buf.push(b'\n');
        CsvText {
            values,
            width: names.len().max(1),
            row: 0,
            buf,
            at: 0,
        }
    }
}

impl Read for CsvText<'_> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        use std::io::Write as _;
        while self.at == self.buf.len() {
            let start = self.row * self.width;
            if start >= self.values.len() {
                return Ok(0);
            }
            self.buf.clear();
            self.at = 0;
            // A few hundred rows per refill: the formatting, not the hand-over, is the cost.
            for r in self.values[start..].chunks(self.width).take(256) {
                for (k, v) in r.iter().enumerate() {
                    if k > 0 {
                        self.buf.push(b',');
                    }
                    // `{:?}`: the shortest text that parses back to the same f64 (NaN, inf as
                    // `NaN`, `inf`: the reader's non-finite error names the cell).
                    write!(self.buf, "{v:?}")?;
                }
                self.buf.push(b'\n');
                self.row += 1;
            }
        }
        let n = out.len().min(self.buf.len() - self.at);
        out[..n].copy_from_slice(&self.buf[self.at..self.at + n]);
        self.at += n;
        Ok(n)
    }
}

fn open(src: &Source, arm: &ArmSource, opt: &Options) -> Result<Log, String> {
    let dof = arm.dof();
    match src {
        Source::Path(p) if bag::is_bag(p) => {
            let names = arm.dh_table().ok().and_then(|t| t.joint_names());
            let opts = BagOptions {
                topic: opt.topic.clone(),
                joints: opt.joints.clone(),
                torque_scale: opt.torque_scale.clone(),
                need_effort: true,
                spill_rows: None,
            };
            let read = bag::read(p, dof, names, &opts).map_err(|e| e.to_string())?;
            Ok(read.log)
        }
        Source::Path(p) => {
            if opt.topic.is_some() || opt.joints.is_some() || opt.torque_scale.is_some() {
                return Err(format!(
                    "{}: topic, joints and torque_scale are for ROS 2 bags (.mcap), and this is not one — drop them for a CSV",
                    p.display()
                ));
            }
            Log::open(p, Some(dof)).map_err(|e| e.to_string())
        }
        Source::Table {
            label,
            names,
            values,
        } => {
            let t = Trajectory::from_reader(CsvText::new(names, values), label, Some(dof))
                .map_err(|e| e.to_string())?;
            Ok(Log::from(t))
        }
    }
}

fn config(arm: &ArmSource, o: &Options) -> Result<Config, String> {
    let dof = arm.dof();
    let effects = parse_list(&o.effects, dof).map_err(|e| format!("effects: {e}"))?;
    if let Some(c) = o.cutoff {
        if !(c.is_finite() && c > 0.0) {
            return Err(format!(
                "cutoff: `{c}` is not a positive number of Hz or \"auto\""
            ));
        }
    }
    let smoothing = match o.smoothing.trim() {
        "auto" => None,
        s => Some(Smoothing::parse(s).map_err(|e| format!("smoothing: {e}"))?),
    };
    let method = match o.derivative.as_str() {
        "butterworth" => Method::Butterworth,
        "savgol" => Method::SavitzkyGolay,
        other => {
            return Err(format!(
                "derivative: `{other}` is not an estimator — use \"butterworth\" or \"savgol\""
            ))
        }
    };
    let prior = match &o.prior {
        Some(path) => {
            let p = InertialParams::from_path(path, dof, &ParamsOptions::default()).map_err(|e| {
                format!("prior: {e} — the prior must be a physically consistent parameter file of this arm")
            })?;
            Some(p.full_vector())
        }
        None => None,
    };
    if prior.is_some() && !o.physical {
        return Err("prior needs the consistent estimate: drop physical=False".into());
    }
    Ok(Config {
        smoothing,
        derivative: DerivativeOptions {
            method,
            cutoff_hz: o.cutoff,
        },
        file_velocity: o.file_velocity,
        effects,
        physical: PhysicalOptions {
            enabled: o.physical,
            prior,
            prior_source: o.prior.as_ref().map(|p| format!("`{}`", p.display())),
        },
        ..Config::default()
    })
}

/// Identifies `arm` from `train` (validated on `validate`), writes the report to `opt.out` if
/// given. Every error is the library's message.
pub fn run(
    arm: &ArmSource,
    train: &[Source],
    validate: Option<&Source>,
    opt: &Options,
) -> Result<Ran, String> {
    let cfg = config(arm, opt)?;
    if train.is_empty() {
        return Err("data: no training data — pass a file path, an array or a DataFrame (or a list of them)".into());
    }
    let logs = train
        .iter()
        .map(|s| open(s, arm, opt))
        .collect::<Result<Vec<_>, _>>()?;
    let val = validate.map(|s| open(s, arm, opt)).transpose()?;
    let outcome = identify::run(arm, logs, val, &cfg).map_err(|e| e.to_string())?;
    let mut warnings = outcome.warnings.clone();
    warnings.dedup();
    if opt.strict && !warnings.is_empty() {
        let list: Vec<String> = warnings.iter().map(|w| format!("  - {w}")).collect();
        return Err(format!(
            "strict: the data cannot identify everything:\n{}",
            list.join("\n")
        ));
    }
    let table = arm.dh_table().ok();
    let files = match &opt.out {
        Some(dir) => dynid::report::write(dir, &outcome, &opt.command, table.as_ref())
            .map_err(|e| format!("writing the report: {e}"))?
            .iter()
            .map(|p| p.display().to_string())
            .collect(),
        None => Vec::new(),
    };
    let json = serde_json::to_string(&dynid::report::json_report(&outcome, &opt.command))
        .map_err(|e| format!("report.json: {e}"))?;
    Ok(Ran {
        json,
        files,
        warnings,
    })
}
