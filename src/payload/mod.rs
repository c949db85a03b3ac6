//! Payload identification: the 10 inertial parameters of what the flange carries, from runs
//! with it (and optionally the same motion without it), given the identified arm; and, with the
//! payload's mass known, the drive gains (torque scale per joint).
//!
//! | file | what |
//! |---|---|
//! | [`runs`] | a run's torque and states (the file's derivatives, or `identify`'s estimator) |
//! | [`align`] | the unloaded twin's time shift, and the check that it is the same motion |
//! | [`cutoff`] | the automatic derivative cut-off: a scan judged on the unfiltered rows |
//! | [`rows`] | the regression `d = Y_n·φ` of the last link's regressor columns |
//! | [`fit`] | weighted least squares, physical consistency, σ |
//! | [`drive_gain`] | the per-joint torque scales from a payload of known mass |
//! | [`output`] | `payload.json`, the params snippet, `payload.urdf`, `report.md` |
//!
//! ```no_run
//! use dynid::payload::{identify_payload, PayloadOptions};
//! # let table: dynid::dh::DhTable = todo!();
//! # let params: dynid::params::InertialParams = todo!();
//! let loaded = dynid::data::Trajectory::from_path("loaded.csv".as_ref(), Some(6)).unwrap();
//! let est = identify_payload(&table, &params, vec![loaded], vec![], &PayloadOptions::default()).unwrap();
//! println!("{} kg at {:?} m", est.mass, est.com);
//! ```

pub mod align;
pub mod cutoff;
pub mod drive_gain;
pub mod fit;
pub mod output;
pub mod rows;
pub mod runs;

use serde::Serialize;

use crate::data::Trajectory;
use crate::derivative;
use crate::dh::DhTable;
use crate::params::InertialParams;
use crate::progress::Progress;
use crate::reference::RefModel;

pub use align::Alignment;
pub use drive_gain::DriveGains;

/// σ above which a payload parameter is called poorly excited: mass 2 % of it, centre of mass
/// 5 mm, inertia a quarter of the largest of its principal moments or `m·(2 cm)²`.
pub const WARN_MASS: f64 = 0.02;
pub const WARN_COM: f64 = 0.005;
pub const WARN_INERTIA: f64 = 0.25;

#[derive(Debug, Clone, Default)]
pub struct PayloadOptions {
    /// The payload's known mass (kg): only its centre of mass and inertia are estimated, and
    /// with it the drive gains.
    pub mass: Option<f64>,
    /// Multiply the data's torque by these per joint (e.g. gains calibrated before).
    pub torque_scale: Option<Vec<f64>>,
    pub derivative: derivative::Options,
}

#[derive(Debug, Clone, thiserror::Error)]
pub enum PayloadError {
    #[error("{0}")]
    Input(String),
    /// The unloaded twin is not the loaded motion.
    #[error("{0}")]
    Mismatch(String),
    #[error("{0}")]
    Numerical(String),
}

/// σ of each reported quantity (same layout as [`PayloadEstimate`]).
#[derive(Debug, Clone, Serialize)]
pub struct Sigma {
    pub mass: f64,
    pub com: [f64; 3],
    pub inertia: [f64; 6],
}

/// The fit of one loaded run: RMS of the unexplained torque per joint without and with the
/// payload.
#[derive(Debug, Clone, Serialize)]
pub struct RunFit {
    pub source: String,
    pub twin: Option<String>,
    pub alignment: Option<Alignment>,
    /// The derivative cut-off the run's states were estimated with (`None`: the file's own).
    pub cutoff_hz: Option<f64>,
    pub rms_before: Vec<f64>,
    pub rms_after: Vec<f64>,
}

#[derive(Debug, Clone, Serialize)]
pub struct PayloadEstimate {
    /// kg.
    pub mass: f64,
    /// Centre of mass in the last link's frame (m).
    pub com: [f64; 3],
    /// Inertia about the centre of mass, `[xx, xy, xz, yy, yz, zz]` (kg·m²).
    pub inertia: [f64; 6],
    pub sigma: Sigma,
    /// `[XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M]` about the last link's origin (the params-file
    /// order), what adds to the last link.
    pub params: [f64; 10],
    pub mass_known: bool,
    /// With `mass`: the factor per joint by which the data's torque must be multiplied (including
    /// any `torque_scale` given).
    pub torque_scale: Option<Vec<f64>>,
    pub torque_scale_sigma: Option<Vec<f64>>,
    /// Joints (1-based) the runs cannot calibrate (scale kept as given).
    pub uncalibrated_joints: Vec<usize>,
    pub runs: Vec<RunFit>,
    pub samples: usize,
    /// The least-squares estimate was not physical and was pulled into the physical set.
    pub projected: bool,
    pub warnings: Vec<String>,
}

/// Estimates the payload on the last link of `table` (identified as `arm`) from `loaded` runs
/// and, when given, one unloaded twin per loaded run (same order).
pub fn identify_payload(
    table: &DhTable,
    arm: &InertialParams,
    loaded: Vec<Trajectory>,
    unloaded: Vec<Trajectory>,
    opts: &PayloadOptions,
) -> Result<PayloadEstimate, PayloadError> {
    identify_payload_with(table, arm, loaded, unloaded, opts, &Progress::silent())
}

/// [`identify_payload`] reporting its steps to `progress`.
pub fn identify_payload_with(
    table: &DhTable,
    arm: &InertialParams,
    loaded: Vec<Trajectory>,
    unloaded: Vec<Trajectory>,
    opts: &PayloadOptions,
    progress: &Progress,
) -> Result<PayloadEstimate, PayloadError> {
    let n = table.dof();
    let given = check_inputs(table, arm, &loaded, &unloaded, opts)?;
    let model = RefModel::new(table);
    let p = arm.full_vector();
    let am = rows::ArmModel {
        model: &model,
        params: &p,
        effects: &arm.effects,
    };
    progress.stage("payload: reading and aligning the runs", 1);
    let mut prep = prepare(&am, &loaded, &unloaded, &given, &opts.derivative)?;
    progress.step();
    if let (None, Some(proposal)) = (opts.derivative.cutoff_hz, prep.cutoff_hz) {
        let grid = cutoff::grid(proposal, prep.fs_hz);
        progress.stage("payload: the cut-off scan", grid.len() as u64);
        // With the mass known the scales are what is estimated, so their σ judges the cut-off.
        let judge = |p: &Prepared| match opts.mass {
            Some(m) => drive_gain::spread(&p.rows, m),
            None => cutoff::score(&p.rows, &p.raw),
        };
        let mut best = judge(&prep);
        for fc in grid {
            let d = derivative::Options {
                method: opts.derivative.method,
                cutoff_hz: Some(fc),
            };
            // A cut-off the runs are too short for is skipped, not an error.
            if let Ok(p) = prepare(&am, &loaded, &unloaded, &given, &d) {
                let s = judge(&p);
                if s < best {
                    (best, prep) = (s, p);
                }
            }
            progress.step();
        }
    }
    let Prepared {
        rows: mut all_rows,
        mut fits,
        ..
    } = prep;
    if all_rows.iter().all(|r| r.is_empty()) {
        return Err(PayloadError::Input(
            "no usable samples in the loaded runs (too short for the filter's reach?)".into(),
        ));
    }
    let mut warnings = Vec::new();
    let (gains, scale) = match opts.mass {
        Some(m) => {
            let g = drive_gain::drive_gains(&all_rows, m)?;
            for r in all_rows.iter_mut() {
                for (k, d) in r.d.iter_mut().enumerate() {
                    *d *= g.scale[k % n];
                }
            }
            let total: Vec<f64> = given.iter().zip(&g.scale).map(|(a, b)| a * b).collect();
            (Some(g), Some(total))
        }
        None => (None, None),
    };
    let f = fit::fit(&all_rows, opts.mass)?;
    for (rf, r) in fits.iter_mut().zip(&all_rows) {
        let one = std::slice::from_ref(r);
        rf.rms_before = fit::residual_rms_of(one, &[0.0; 10]);
        rf.rms_after = fit::residual_rms_of(one, &f.phi);
    }
    let (mass, com, inertia) = fit::physical(&f.phi);
    let s = fit::sigma(&f.phi, &f.cov);
    let sigma = Sigma {
        mass: if opts.mass.is_some() { 0.0 } else { s[0] },
        com: [s[1], s[2], s[3]],
        inertia: [s[4], s[5], s[6], s[7], s[8], s[9]],
    };
    warnings.extend(excitation_warnings(
        mass,
        &inertia,
        &sigma,
        opts.mass.is_some(),
    ));
    if f.projected {
        warnings.push(
            "the least-squares payload was not a physical body; the estimate is the closest physical one (pseudo-inertia ⪰ 0) — excite the flange more".into(),
        );
    }
    let uncalibrated = gains
        .as_ref()
        .map_or_else(Vec::new, |g| uncalibrated_joints(g, &given, &mut warnings));
    Ok(PayloadEstimate {
        mass,
        com,
        inertia,
        sigma,
        params: f.phi,
        mass_known: opts.mass.is_some(),
        torque_scale: scale,
        torque_scale_sigma: gains.as_ref().map(|g| {
            g.sigma
                .iter()
                .zip(&given)
                .map(|(s, k)| s * k.abs())
                .collect()
        }),
        uncalibrated_joints: uncalibrated,
        runs: fits,
        samples: f.samples,
        projected: f.projected,
        warnings,
    })
}

/// The runs read, aligned and turned into rows at one derivative setting.
struct Prepared {
    /// The fit's rows (filtered) and the same unfiltered, per loaded run.
    rows: Vec<rows::Rows>,
    raw: Vec<rows::Rows>,
    fits: Vec<RunFit>,
    /// The first loaded run's cut-off (`None`: the file's own derivatives) and sampling rate.
    cutoff_hz: Option<f64>,
    fs_hz: f64,
}

fn prepare(
    am: &rows::ArmModel,
    loaded: &[Trajectory],
    unloaded: &[Trajectory],
    given: &[f64],
    d: &derivative::Options,
) -> Result<Prepared, PayloadError> {
    let mut out = Prepared {
        rows: vec![],
        raw: vec![],
        fits: vec![],
        cutoff_hz: None,
        fs_hz: 0.0,
    };
    for (i, traj) in loaded.iter().enumerate() {
        let run = runs::Run::new(traj.clone(), given, d)?;
        if i == 0 {
            out.cutoff_hz = run.cutoff_hz;
            let span = run.t[run.len() - 1] - run.t[0];
            out.fs_hz = (run.len() - 1) as f64 / span.max(1e-12);
        }
        // The twin's states through the loaded run's own filter: the model terms of the two runs
        // must cancel, and at two cut-offs they do not (an inertial torque filtered at two
        // cut-offs differs by far more than the payload's).
        let twin_opts = derivative::Options {
            method: d.method,
            cutoff_hz: run.cutoff_hz.or(d.cutoff_hz),
        };
        let twin = match unloaded.get(i) {
            Some(u) => Some(runs::Run::new(u.clone(), given, &twin_opts)?),
            None => None,
        };
        let alignment = match &twin {
            Some(u) => Some(align::align(&run, u)?),
            None => None,
        };
        let (r, raw) = rows::build(am, &run, twin.as_ref().zip(alignment.as_ref()));
        out.fits.push(RunFit {
            source: run.source.clone(),
            twin: twin.as_ref().map(|u| u.source.clone()),
            alignment,
            cutoff_hz: run.cutoff_hz,
            rms_before: vec![],
            rms_after: vec![],
        });
        out.rows.push(r);
        out.raw.push(raw);
    }
    Ok(out)
}

/// The checks of the inputs that need no data: sizes, the known mass, the drive-gain list. Returns
/// the torque scales to apply (1 where none are given).
fn check_inputs(
    table: &DhTable,
    arm: &InertialParams,
    loaded: &[Trajectory],
    unloaded: &[Trajectory],
    opts: &PayloadOptions,
) -> Result<Vec<f64>, PayloadError> {
    let n = table.dof();
    if arm.dof() != n {
        return Err(PayloadError::Input(format!(
            "the parameters have {} links, the arm {} joints",
            arm.dof(),
            n
        )));
    }
    if loaded.is_empty() {
        return Err(PayloadError::Input("no loaded run (--data)".into()));
    }
    if !unloaded.is_empty() && unloaded.len() != loaded.len() {
        return Err(PayloadError::Input(format!(
            "{} loaded runs and {} unloaded: give one unloaded twin per loaded run (same order), or none",
            loaded.len(),
            unloaded.len()
        )));
    }
    if let Some(m) = opts.mass {
        if !(m.is_finite() && m > 0.0) {
            return Err(PayloadError::Input(format!(
                "--mass {m}: the payload's mass must be a positive number of kg"
            )));
        }
    }
    let given = match &opts.torque_scale {
        Some(s) if s.len() != n => {
            return Err(PayloadError::Input(format!(
                "--torque-scale has {} values, the arm {} joints",
                s.len(),
                n
            )))
        }
        Some(s) => s.clone(),
        None => vec![1.0; n],
    };
    for t in loaded.iter().chain(unloaded) {
        if t.dof != n {
            return Err(PayloadError::Input(format!(
                "{}: {} joints, the arm has {}",
                t.source, t.dof, n
            )));
        }
    }
    Ok(given)
}

/// The joints (1-based) whose drive gain the pair cannot calibrate, each with a warning.
fn uncalibrated_joints(
    g: &drive_gain::DriveGains,
    given: &[f64],
    warnings: &mut Vec<String>,
) -> Vec<usize> {
    let mut uncalibrated = Vec::new();
    for (j, ok) in g.calibrated.iter().enumerate() {
        if !ok {
            uncalibrated.push(j + 1);
            warnings.push(format!(
                    "joint {}: the payload loads it too little to calibrate its drive gain (σ {:.2} % of the scale > {:.0} %); kept at {}",
                    j + 1,
                    100.0 * g.sigma[j] / g.scale[j].abs().max(1e-12),
                    100.0 * drive_gain::MAX_RELATIVE_SIGMA,
                    given[j]
                ));
        }
    }
    uncalibrated
}

/// The payload parameters whose σ exceeds the `WARN_*` thresholds, named with their σ.
fn excitation_warnings(m: f64, inertia: &[f64; 6], s: &Sigma, mass_known: bool) -> Vec<String> {
    let mut w = Vec::new();
    if !mass_known && s.mass > WARN_MASS * m.abs() {
        w.push(format!(
            "mass poorly excited: σ {:.4} kg ({:.1} % of {:.4} kg) — use a longer or more vigorous run",
            s.mass,
            100.0 * s.mass / m.abs().max(1e-12),
            m
        ));
    }
    for (axis, sc) in ["x", "y", "z"].iter().zip(&s.com) {
        if *sc > WARN_COM {
            w.push(format!(
                "centre of mass {axis} poorly excited: σ {:.1} mm (> {:.0} mm) — rotate the flange more",
                1e3 * sc,
                1e3 * WARN_COM
            ));
        }
    }
    let t = nalgebra::Matrix3::new(
        inertia[0], inertia[1], inertia[2], inertia[1], inertia[3], inertia[4], inertia[2],
        inertia[4], inertia[5],
    );
    let top = t
        .symmetric_eigenvalues()
        .iter()
        .cloned()
        .fold(0.0, f64::max)
        .max(m.abs() * 0.02 * 0.02);
    for (name, si) in ["xx", "xy", "xz", "yy", "yz", "zz"].iter().zip(&s.inertia) {
        if *si > WARN_INERTIA * top {
            w.push(format!(
                "inertia {name} poorly excited: σ {:.3e} kg·m² (> {:.0} % of {:.3e})",
                si,
                100.0 * WARN_INERTIA,
                top
            ));
        }
    }
    w
}
