//! Identification from measured or simulated data: base-parameter least squares, the residual →
//! effect loop and everything a report needs.
//!
//! [`run`] (and [`leave_one_out`], once per held-out file) goes through these stages, each in a
//! file of its own, each handing its value to the next (every step is reported):
//!
//! 0. **Cut-off scan** (`scan.rs`, [`choose_cutoff`]): candidates and smoothings are judged by
//!    stages 1–5 on the training files (on evenly spaced pieces past [`SCAN_SAMPLES`] samples,
//!    [`scan_pieces`]); the held-out error against the measured torque picks the filters.
//! 1. **Preparation** (`prepare.rs`, [`Prepared`]): derivatives per file
//!    ([`crate::derivative::Estimator`], run window by window on the file's [`Log`] as each pass
//!    needs them, so neither a long log nor its states are ever held whole — a long log lives in a
//!    temporary file): uneven sampling is resampled to a uniform grid, q is low-passed with a
//!    zero-phase filter whose cut-off is chosen from the spectrum, q̇/q̈ come from central
//!    differences (a q̇ column in the file is used, filtered, and differentiated for q̈). Files
//!    with both q̇ and q̈ are used as given.
//! 2. **Layout** (`layout.rs`, [`Layout`]): base columns, then effect terms; `rows.rs` fills
//!    the rows of one state — once per file into a table that every later pass reads, when the
//!    files' rows fit in 48 MB (each scan trial's, the final fit's), and a study's folds share
//!    each file's states and base regressor per cut-off (only the effect columns depend on the
//!    training set).
//! 3. **Regression** (`regress.rs`) with *parallel filtering*: on each file's uniform grid the
//!    rows `[Yb(q,q̇,q̈) | effect columns | τ]` are filtered column by column with a zero-phase
//!    *regression filter* (also τ) of the same kind as the derivative filter, at its cut-off or
//!    half of it ([`Smoothing`]), in overlapping chunks so memory does not grow with the log
//!    length, kept at [`KEEP_RATE_PER_CUTOFF`] times the regression cut-off (Gautier's
//!    decimation: nothing above a few cut-offs survives the filter) and folded into
//!    incremental QR factors ([`ls::Accumulator`]) per joint and per time block; a joint's
//!    factor holds only the columns that can be non-zero in its rows. Filter edges are
//!    dropped. Several files are fitted together, each filtered on its own.
//! 4. **Weighted least squares** (`problem.rs`, [`Problem`]): each joint's rows are weighted by
//!    the inverse of its residual standard deviation (two passes), solved by QR over the stacked
//!    factors; leave-one-block-out fits for held-out errors. No physical consistency constraints
//!    are imposed (plain least squares); the condition number of the weighted regressor is
//!    reported.
//! 5. **Errors** (`evaluate.rs`, predictions in `predict.rs`) are computed against the torque
//!    *as measured in the file* (unfiltered), at every one of the file's own sample times, by
//!    predicting each reported model directly ([`raw_sums`]) from the rows of the estimated
//!    states or from the parallel-filtered rows (whichever [`Smoothing`] the scan chose; rows
//!    interpolated between grid samples): relative RMS per joint `‖τ̂ⱼ−τⱼ‖/‖τⱼ‖` and overall
//!    `‖τ̂−τ‖/‖τ‖`, for the declared (rigid) and the augmented model, on training and
//!    validation data, and held out (each time block predicted by the fit without it).
//! 6. **Effect selection** (`select.rs`, [`select`]) on the problem (with two training files or
//!    more, a per-run offset is a column per run: [`crate::effects::Run`]); position ripple
//!    ([`ripple`]: a wavenumber per joint from the residual's periodogram, then the pair
//!    searched, and the first stage's candidates again on top of an accepted pair);
//!    asymmetric Coulomb friction beside a joint's Coulomb friction also on its coefficient
//!    (`asym_stage.rs`: its evidence sits at the rests, in a few held-out blocks); friction as a
//!    spline in the velocity ([`friction_spline`]: the catch-all, on what the closed forms
//!    leave); load-dependent effects
//!    ([`Effect::LOADED`](crate::effects::Effect::LOADED)) in a second stage on top of the first
//!    stage's model (`load_stage.rs`: their columns hold its torque, so the layout and problem
//!    are rebuilt); when one is found, the scan is repeated with it in its models
//!    ([`LoadModel`]).
//!    No effect is searched on a weak joint (`weak.rs`: its torque sits on its resolution floor).
//!    Then the **Coulomb width scan** (`coulomb_width.rs`, unless `Config::coulomb_width` fixes
//!    it): the smoothing of the Coulomb sign is chosen by held-out error on the training data.
//!    Then the **per-joint guard** (`guard.rs`, with `--effects auto`): the plain fit (rigid body +
//!    viscous, Coulomb, offset, armature on every joint) is always fitted; where it predicts a
//!    joint better on held-out training data (by run, or by block with one file), the plain terms
//!    the search left out are added, and the verdict per joint is reported.
//! 7. **Outcome** (`outcome.rs`, [`Outcome`]): the reported models fitted and judged, parameter
//!    standard deviations from a block jackknife over the time blocks (honest under the
//!    residual autocorrelation that filtering creates), reported also as %σ = 100·σ/|θ|.

mod asym_stage;
pub mod base;
mod columns;
pub mod coulomb_width;
mod dot;
mod evaluate;
pub mod extrapolation;
pub mod friction_spline;
pub mod guard;
mod hotelling;
pub mod identifiability;
mod jackknife;
mod layout;
mod load_stage;
pub mod ls;
mod outcome;
pub mod physical;
mod predict;
mod prepare;
mod problem;
mod regress;
pub mod residual_map;
pub mod ripple;
mod row_table;
mod rows;
mod scan;
mod select;
pub mod synth;
pub mod weak;

pub use crate::progress::Progress;
pub use evaluate::{raw_sums, Errors, Judged, ModelResult, Prediction, RawSums, StateErrors};
pub use guard::{Guard, JointGuard};
pub use identifiability::Undetermined;
pub use layout::Layout;
pub use load_stage::LoadModel;
pub use outcome::{Estimated, FileInfo, Outcome, StepRow};
pub use predict::{BeforeAfter, Predictions, Series};
pub use prepare::{PrepCache, Prepared, Smoothing};
pub use problem::Problem;
pub use regress::KEEP_RATE_PER_CUTOFF;
pub use scan::{
    choose_cutoff, scan_pieces, scan_sampling, CutoffTrial, FilterChoice, ScanSampling,
    SCAN_PIECES, SCAN_SAMPLES,
};
pub use select::{select, CoefficientTest, Evidence, Rules, Selection, Step};
pub use weak::WeakJoint;

use rayon::prelude::*;

use crate::arms::ArmSource;
use crate::derivative;
use crate::effects::{EffectsSpec, Term};
use crate::log::Log;
use base::BaseModel;
use columns::make_layout;
use load_stage::load_stage;

/// Fewest samples per file.
pub const MIN_SAMPLES: usize = 64;

/// Why identification could not run. Nothing is written when this is returned.
#[derive(Debug, thiserror::Error)]
pub enum IdentifyError {
    #[error(transparent)]
    Data(#[from] crate::data::DataError),
    #[error("{file}: {source}")]
    Derivative {
        file: String,
        source: derivative::DerivativeError,
    },
    #[error("{file}: no torque columns — identification needs measured torques tau1..tau{dof}")]
    NoTorque { file: String, dof: usize },
    #[error("{file}: the file is for {found} joints but the arm has {dof}")]
    Dof {
        file: String,
        found: usize,
        dof: usize,
    },
    #[error(transparent)]
    Rank(#[from] RankError),
    #[error("{0}")]
    Effects(String),
    #[error("cannot write a temporary file (validation predictions of a long log): {0} — free space in the temporary directory or point TMPDIR elsewhere")]
    Spill(std::io::Error),
}

/// Rank-deficient excitation: some parameters cannot be told apart with the given data.
#[derive(Debug, Clone, PartialEq)]
pub struct RankError {
    pub files: String,
    /// The parameters whose columns depend on earlier ones, e.g. `MX2`, `coulomb1`.
    pub params: Vec<String>,
    /// Which joints hardly move, if any (starts with a space).
    pub hint: String,
}

impl std::fmt::Display for RankError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names = self
            .params
            .iter()
            .map(|p| format!("`{p}`"))
            .collect::<Vec<_>>()
            .join(", ");
        write!(
            f,
            "rank-deficient excitation in {}: {} cannot be identified (each is a combination of the other columns in this data){} — record a trajectory that moves every joint through a wide range with changing velocity",
            self.files, names, self.hint
        )
    }
}

impl std::error::Error for RankError {}

/// Options of [`run`].
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    pub derivative: derivative::Options,
    /// Use a q̇ column of the file (filtered) instead of differentiating q.
    pub file_velocity: bool,
    pub effects: EffectsSpec,
    pub rules: Rules,
    /// Number of time blocks over all training files (for held-out tests and the jackknife).
    pub blocks: usize,
    /// Regression filter and prediction; `None` = chosen by the scan with the cut-off.
    pub smoothing: Option<Smoothing>,
    /// The Coulomb sign's smoothing velocity as a fraction of each joint's RMS training
    /// velocity; `None` = chosen by the Coulomb width scan ([`coulomb_width`]).
    pub coulomb_width: Option<f64>,
    /// Stage 8: the physically consistent estimate.
    pub physical: physical::PhysicalOptions,
    /// Where to report progress (stages, the scan's cut-offs, a study's folds).
    pub progress: Progress,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            derivative: derivative::Options::default(),
            file_velocity: true,
            effects: EffectsSpec::Auto,
            rules: Rules::default(),
            blocks: 20,
            smoothing: None,
            coulomb_width: None,
            physical: physical::PhysicalOptions::default(),
            progress: Progress::default(),
        }
    }
}

/// Chooses the filters on `train`, prepares the files and identifies; if the model found has
/// load-dependent terms (which the first scan's models lack, see [`crate::effects::Effect::LOADED`]) and the
/// choice was automatic, the scan is repeated with them in its models, and the identification
/// with its choice if that differs.
fn scan_and_run(
    arm: &ArmSource,
    base: &BaseModel,
    train: &[Log],
    val: Option<&Log>,
    cfg: &Config,
    cache: &mut PrepCache,
) -> Result<Outcome, IdentifyError> {
    check_runs(cfg, train)?;
    let table = arm.dh_table().ok();
    cfg.progress
        .stage("estimating derivatives and the spectral cut-off", 0);
    let fit = |cache: &mut PrepCache, choice: FilterChoice| -> Result<Outcome, IdentifyError> {
        let (fc, sm) = (choice.cutoff_hz, choice.smoothing);
        let preps = cache.get_all(train, cfg, fc, sm)?;
        let val = match val {
            Some(v) => {
                Some(cache.get(v, cfg, fc.or(Some(preps[0].est.report.cutoff_hz)), sm, None)?)
            }
            None => None,
        };
        run_prepared_with(
            arm.name(),
            base,
            table.as_ref(),
            &preps,
            val.as_ref(),
            cfg,
            &cache.grids,
        )
    };
    let (choice, scan) = choose_cutoff(base, table.as_ref(), train, cfg, cache, None)?;
    cfg.progress
        .stage("fitting, searching effects, judging the models", 0);
    let mut out = fit(cache, choice)?;
    out.cutoff_scan = scan;
    let automatic = cfg.derivative.cutoff_hz.is_none() || cfg.smoothing.is_none();
    if let (Some(lm), true) = (out.load_model.clone(), automatic) {
        let (again, scan) = choose_cutoff(base, table.as_ref(), train, cfg, cache, Some(&lm))?;
        if again != choice {
            cfg.progress.stage("refitting at the new cut-off", 0);
            out = fit(cache, again)?;
        }
        out.cutoff_scan = scan;
        out.rescanned_with = lm.terms.iter().map(Term::label).collect();
    }
    if !out.cutoff_scan.is_empty() {
        out.scan_sampling = scan_sampling(train);
    } else if cfg.derivative.cutoff_hz.is_none() {
        let fc = out
            .train
            .first()
            .map_or(f64::NAN, |f| f.derivative.cutoff_hz);
        out.warnings.push(format!(
            "the automatic cut-off scan could fit none of its trials (the rigid model with every candidate effect is rank-deficient on every cut-off's data), so the spectral rule's {fc:.2} Hz was used untested — give `--cutoff` from a range you trust, or more varied motion"
        ));
    }
    Ok(out)
}

/// Identifies `arm` from `train` files, validating on `validate` if given (see the module docs).
pub fn run(
    arm: &ArmSource,
    train: Vec<Log>,
    validate: Option<Log>,
    cfg: &Config,
) -> Result<Outcome, IdentifyError> {
    let base = BaseModel::for_arm(arm);
    for t in &train {
        check_dof(t, &base)?;
    }
    if let Some(v) = &validate {
        check_dof(v, &base)?;
    }
    let earlier = validate.as_ref().and_then(|v| v.continues(&train)).cloned();
    let validate = match (validate, &earlier) {
        (Some(v), Some(e)) => Some(v.continuing(e)),
        (v, _) => v,
    };
    let mut out = scan_and_run(
        arm,
        &base,
        &train,
        validate.as_ref(),
        cfg,
        &mut PrepCache::default(),
    )?;
    if let (Some(v), Some(e)) = (&validate, &earlier) {
        out.warnings.push(format!(
            "the validation file `{}` goes on where the training file `{}` stopped (its first sample {:.1} ms after that file's last): it is predicted as the rest of that run — a drift's time and a per-run offset go on from that file's. To predict it as a new run, give it a time column of its own (starting anywhere but just after that file's last sample)",
            v.source,
            e.source,
            1e3 * (v.t(0) - e.t(e.len() - 1))
        ));
    }
    Ok(out)
}

/// A declared per-run term needs its run among the training files (`run_offset:J@R`), and any
/// per-run term two training runs.
fn check_runs(cfg: &Config, train: &[Log]) -> Result<(), IdentifyError> {
    let EffectsSpec::Fixed(terms) = &cfg.effects else {
        return Ok(());
    };
    let runs = Log::runs(train).len();
    let per_run = || terms.iter().filter(|t| t.effect.is_per_run());
    if let Some(t) = per_run().next().filter(|_| runs < 2) {
        return Err(IdentifyError::Effects(format!(
            "--effects {}: a per-run offset needs two training files or more (one --data given); with one run it is `offset`",
            t.effect.name()
        )));
    }
    match per_run().find(|t| t.run >= runs) {
        Some(t) => Err(IdentifyError::Effects(format!(
            "--effects {}:{}@{}: there are {runs} training runs (the --data files, in order)",
            t.effect.name(),
            t.joint + 1,
            t.run + 1,
        ))),
        None => Ok(()),
    }
}

fn check_dof(t: &Log, base: &BaseModel) -> Result<(), IdentifyError> {
    if t.dof() != base.dof() {
        return Err(IdentifyError::Dof {
            file: t.source.clone(),
            found: t.dof(),
            dof: base.dof(),
        });
    }
    Ok(())
}

/// [`run`] on files already prepared (so studies can rotate files without redoing derivatives):
/// the stages 2–7 in order.
pub fn run_prepared(
    arm: &str,
    base: &BaseModel,
    table: Option<&crate::dh::DhTable>,
    train: &[Prepared],
    val: Option<&Prepared>,
    cfg: &Config,
) -> Result<Outcome, IdentifyError> {
    let grids = row_table::GridBaseCache::default();
    run_prepared_with(arm, base, table, train, val, cfg, &grids)
}

/// [`run_prepared`], the files' states and base regressor taken from `grids` where it holds
/// them. When the files' rows fit in [`row_table::ROW_TABLE_BYTES`] they are evaluated once into
/// tables that the regression and the judging passes read (the numbers of rows evaluated pass
/// by pass).
fn run_prepared_with(
    arm: &str,
    base: &BaseModel,
    table: Option<&crate::dh::DhTable>,
    train: &[Prepared],
    val: Option<&Prepared>,
    cfg: &Config,
    grids: &row_table::GridBaseCache,
) -> Result<Outcome, IdentifyError> {
    let (layout, declared, searched, merged) = make_layout(base, table, train, cfg);
    let tabled = row_table::RowTable::attach(base, &layout, train, grids);
    let train = tabled.as_deref().unwrap_or(train);
    let mut problem = Problem::build(base, layout, train, cfg.blocks);
    let rigid = problem.subset(&[]);
    let independent = problem.independent(&rigid);
    problem.layout.fixed = rigid
        .into_iter()
        .filter(|c| !independent.contains(c))
        .collect();
    if independent.is_empty() {
        let e = problem.rank_error(&problem.layout.fixed);
        return Err(IdentifyError::Rank(problem::with_hint(e, train)));
    }
    // No effect is searched on a joint whose torque is its sensor's resolution floor.
    let weak = weak::quantised(train, base.dof());
    let searched: Vec<Term> = searched
        .into_iter()
        .filter(|t| !weak.iter().any(|w| w.joint == t.joint))
        .collect();
    let first = select::first_stage(problem, train, cfg, declared, &searched)?;
    let skip: Vec<usize> = weak.iter().map(|w| w.joint).collect();
    let (first, ripple_scans) = ripple::ripple_stage(base, train, cfg, first, (&skip, &searched))?;
    let first = asym_stage::asym_stage(cfg, first, &searched)?;
    let first = friction_spline::spline_stage(base, train, cfg, first, (&skip, &searched))?;
    let selected = load_stage(base, train, cfg, first)?;
    let (selected, width_scan) = match cfg.coulomb_width {
        None => coulomb_width::choose_width(base, (train, grids), cfg.blocks, selected, &skip),
        Some(_) => (selected, None),
    };
    // The per-joint guard against the plain fit (with `--effects auto`: a fixed list is the
    // user's model).
    let (selected, guard) = match cfg.effects {
        EffectsSpec::Auto => {
            let (s, g) = guard::guard(
                base,
                train,
                (cfg.blocks, cfg.rules.guard_alpha),
                selected,
                weak.clone(),
            )
            .map_err(|e| IdentifyError::Rank(problem::with_hint(e, train)))?;
            (s, Some(g))
        }
        EffectsSpec::Fixed(_) => (selected, None),
    };
    // The judging passes read the final layout's rows (the load stage's, if it rebuilt).
    let all: Vec<Prepared> = train.iter().chain(val).cloned().collect();
    let retabled = row_table::RowTable::attach(base, &selected.problem.layout, &all, grids);
    let (train, val) = match &retabled {
        Some(t) => (&t[..train.len()], t.get(train.len()).or(val)),
        None => (train, val),
    };
    let terms = selected.selection.terms.clone();
    let mut out = outcome::assemble(arm, base, train, val, cfg, selected, &merged)?;
    // The maps' units: those of a prismatic joint where the table says so.
    for m in &mut out.residual_maps.maps {
        let prismatic = table
            .and_then(|t| t.joints.get(m.joint))
            .is_some_and(|jt| jt.kind == crate::dh::JointKind::Prismatic);
        m.unit = m.variable.unit(prismatic).to_string();
    }
    // Each joint's position range over the training files (one pass over them), for both.
    let files: Vec<&Prepared> = train.iter().collect();
    let (lo, hi) = extrapolation::ranges(&files, base.dof());
    out.warnings = identifiability::warnings((&lo, &hi), table);
    out.warnings
        .extend(extrapolation::warnings((&lo, &hi), val, &terms));
    let trained = extrapolation::duration(&files);
    out.warnings
        .extend(extrapolation::time_warning(trained, val, &terms));
    if let Some(g) = &guard {
        out.warnings.extend(g.weak.iter().map(|w| w.reason.clone()));
        out.warnings.extend(
            g.joints
                .iter()
                .filter(|j| j.significant)
                .filter_map(|j| j.cause.clone()),
        );
    }
    let weak = guard.as_ref().map_or(weak, |g| g.weak.clone());
    if let Some(joints) = weak::pooled_joints(table, base.dof(), &weak) {
        pool_overall(&mut out, &joints);
    }
    out.guard = guard;
    out.coulomb_width = width_scan;
    out.ripple = ripple_scans;
    out.warnings
        .extend(identifiability::fixed_warning(&out.fixed));
    out.warnings
        .extend(identifiability::undetermined_warning(&out.undetermined));
    Ok(out)
}

/// Every overall error of `out` over `joints` only (see [`weak::pooled_joints`]).
fn pool_overall(out: &mut Outcome, joints: &[usize]) {
    for m in [&mut out.before, &mut out.after]
        .into_iter()
        .chain(out.plain.as_mut())
        .chain(out.consistent.as_mut())
    {
        m.pool(joints);
    }
    for s in &mut out.steps {
        s.train.pool(joints);
        if let Some(v) = &mut s.validation {
            v.pool(joints);
        }
    }
}

/// Leave-one-file-out study: each file in turn is the validation file, the others the training
/// set (cut-off chosen on the training files only). Returns one outcome per file, in order.
pub fn leave_one_out(
    arm: &ArmSource,
    files: Vec<Log>,
    cfg: &Config,
) -> Result<Vec<Outcome>, IdentifyError> {
    let base = BaseModel::for_arm(arm);
    for t in &files {
        check_dof(t, &base)?;
    }
    // Every fold's scan starts from each of its files prepared at the given (or spectral)
    // cut-off: prepared once here, then the folds run in parallel, each with its own copy.
    let mut cache = PrepCache::sharing_grids();
    cfg.progress.stage("reading and checking the files", 0);
    cache.get_all(&files, cfg, cfg.derivative.cutoff_hz, Smoothing::default())?;
    cfg.progress
        .stage("leave-one-out folds", files.len() as u64);
    let (outer, inner) = (
        &cfg.progress,
        Config {
            progress: Progress::silent(),
            ..cfg.clone()
        },
    );
    let folds: Vec<Result<Outcome, IdentifyError>> = (0..files.len())
        .into_par_iter()
        .map(|k| {
            let cfg = &inner;
            let train: Vec<Log> = files
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != k)
                .map(|(_, p)| p.clone())
                .collect();
            let mut cache = cache.clone();
            let out = scan_and_run(arm, &base, &train, Some(&files[k]), cfg, &mut cache);
            outer.step();
            out
        })
        .collect();
    folds.into_iter().collect()
}

/// Validation errors pooled over a leave-one-out study's validation files (`‖τ̂−τ‖/‖τ‖` over
/// all held-out samples, per joint and overall): before, after and — when every fold has it —
/// the consistent estimate, each of the prediction its fold chose.
pub fn pooled_validation(outcomes: &[Outcome]) -> Option<(Errors, Errors, Option<Errors>)> {
    pooled(outcomes, |r| r.validation.as_ref())
}

/// [`pooled_validation`] with every model's torque predicted from the estimated states (a fold
/// that predicts from the filtered rows contributes its `from_states` errors).
pub fn pooled_validation_from_states(
    outcomes: &[Outcome],
) -> Option<(Errors, Errors, Option<Errors>)> {
    pooled(outcomes, |r| match &r.from_states {
        Some(s) => s.validation.as_ref(),
        None => r.validation.as_ref(),
    })
}

/// The plain fit's validation errors pooled like [`pooled_validation`] (when every fold has
/// one: `--effects auto`).
pub fn pooled_plain_validation(outcomes: &[Outcome]) -> Option<Errors> {
    let parts: Option<Vec<&Errors>> = outcomes
        .iter()
        .map(|o| o.plain.as_ref().and_then(|p| p.validation.as_ref()))
        .collect();
    Errors::pooled(parts?)
}

fn pooled(
    outcomes: &[Outcome],
    pick: impl Fn(&ModelResult) -> Option<&Errors>,
) -> Option<(Errors, Errors, Option<Errors>)> {
    let all = |f: &dyn Fn(&Outcome) -> Option<&ModelResult>| -> Option<Errors> {
        let parts: Option<Vec<&Errors>> = outcomes.iter().map(|o| f(o).and_then(&pick)).collect();
        Errors::pooled(parts?)
    };
    Some((
        all(&|o| Some(&o.before))?,
        all(&|o| Some(&o.after))?,
        all(&|o| o.consistent.as_ref()),
    ))
}
