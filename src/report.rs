//! Writes what `dynid identify` found: `report.md`, SVG plots, `report.json` and, with
//! validation data, `validation_prediction.csv`; a leave-one-out study's summary and folds in
//! [`leave_one_out`].
//!
//! Every file is rendered in memory first and then written atomically
//! ([`crate::io::atomic_write`]), so an error leaves no partial report.
//!
//! `report.json` keys: `arm`, `dof`, `base_parameters_from`, `data` (`train`/`validate` files with
//! sampling and the derivative estimator used), `theta` (base parameters: `name`, `expression`,
//! `value`, `std`, `rel_std_percent`), `effects` (coefficients of the augmented model, same
//! fields plus `joint`, `effect`, `run` (a per-run term's training run, from 1), `unit`),
//! `effects_found` (`joint`, `effect`, `run`, `evidence`),
//! `not_identifiable`, `at_rest` (per joint, the share of training samples at rest),
//! `not_searched` (`asym_coulomb` terms left out for too few rests: `effect`, `at_rest`,
//! `needed`), `error` (`before`/`after` × `train`/`validation`, each `per_joint` and
//! `overall` relative RMS `‖τ̂−τ‖/‖τ‖` against the measured torque), `steps` (rigid → + effect →
//! …), `selection`, `condition_number`, `cutoff_scan`, `guard` (per joint: the selected model
//! against the plain fit on held-out training data, the winner, what the guard added, the weak
//! joints; `error.plain` is the plain fit judged like `after`), `command`; `residual_maps` (per
//! joint and variable — `q`, `dq`, `ddq`, `time` since the file's start, `run`, `tau_hat` the
//! joint's predicted torque — the final model's training residual binned: `joint`, `variable`,
//! `unit`, `bins` (`lo`, `hi`, `centre`, `n`, `mean`, `std`, `n_eff`, `ci95_lo`, `ci95_hi`),
//! `rho`, `n_eff_factor`, `chi2`, `dof`, `p_value`, `note`) and `residual_maps_info` (what was
//! binned, every how many samples, how the bands and the test are made; [`residual_map`]);
//! `run_offsets` (per joint with a per-run offset: `joint`, `offsets` per training run, `mean`
//! — a new run's — and `sd` between runs; [`run_offsets`]). The
//! maps are a diagnostic of the fitted model, not what the effect search tested (held-out gains).

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use plotters::prelude::*;
use rayon::prelude::*;
use serde_json::{json, Value};

use crate::dh::DhTable;
use crate::effects::{Effect, Term};
use crate::identify::{Errors, ModelResult, Outcome, Predictions, KEEP_RATE_PER_CUTOFF};
use crate::io::{atomic_write, WriteError};

pub mod guard;
pub mod leave_one_out;
pub mod physical;
pub mod residual_map;
pub mod run_offsets;

/// Why a report could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error(transparent)]
    Write(#[from] WriteError),
    #[error("{}: cannot create the output directory: {source} — check the path and permissions", path.display())]
    Dir {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("plot {name}: {msg}")]
    Plot { name: String, msg: String },
}

/// Files written, in order. `table` (the arm's D-H table, when it has one) is for
/// `identified.urdf`.
pub fn write(
    dir: &Path,
    o: &Outcome,
    command: &str,
    table: Option<&DhTable>,
) -> Result<Vec<PathBuf>, ReportError> {
    // Render everything first: nothing is written if any part fails.
    // The plots, rendered in parallel (each on its own), kept in order.
    type Render = fn(&Outcome, usize) -> Result<String, String>;
    let mut wanted: Vec<(String, Render, usize)> = (0..o.dof)
        .map(|j| {
            let name = format!("residual_vs_velocity_joint{}.svg", j + 1);
            (name, residual_plot as Render, j)
        })
        .collect();
    if !o.residual_maps.maps.is_empty() {
        wanted.extend(
            (0..o.dof).map(|j| (residual_map::file_name(j), residual_map::plot as Render, j)),
        );
    }
    if o.validate.is_some() {
        wanted.extend((0..o.dof).map(|j| {
            let name = format!("validation_joint{}.svg", j + 1);
            (name, validation_plot as Render, j)
        }));
    }
    let rendered: Vec<Result<String, String>> = wanted
        .par_iter()
        .map(|(_, render, j)| render(o, *j))
        .collect();
    let mut files: Vec<(String, Vec<u8>)> = Vec::new();
    let mut plots = Vec::new();
    for ((name, _, _), svg) in wanted.into_iter().zip(rendered) {
        let svg = svg.map_err(|msg| ReportError::Plot {
            name: name.clone(),
            msg,
        })?;
        files.push((name.clone(), svg.into_bytes()));
        plots.push(name);
    }
    let json = serde_json::to_string_pretty(&json_report(o, command))
        .unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"));
    files.push(("report.json".into(), json.into_bytes()));
    files.push((
        "report.md".into(),
        markdown(o, command, &plots).into_bytes(),
    ));
    if let Some(text) = physical::params_toml(o, command) {
        files.push(("identified.params.toml".into(), text.into_bytes()));
    }
    if let Some(urdf) = physical::urdf(o, table) {
        let urdf = urdf.map_err(|msg| ReportError::Plot {
            name: "identified.urdf".into(),
            msg,
        })?;
        files.push(("identified.urdf".into(), urdf.into_bytes()));
    }

    std::fs::create_dir_all(dir).map_err(|source| ReportError::Dir {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut written = Vec::new();
    for (name, bytes) in files {
        let path = dir.join(name);
        atomic_write(&path, |w| w.write_all(&bytes))?;
        written.push(path);
    }
    if let Some(p) = &o.predictions {
        let path = dir.join("validation_prediction.csv");
        atomic_write(&path, |w| prediction_csv(p, w))?;
        written.push(path);
    }
    Ok(written)
}

fn errors_json(e: &Errors) -> Value {
    json!({ "per_joint": e.per_joint, "overall": e.overall })
}

/// A model's errors in `report.json`: training, validation, held-out, and `from_states` (the
/// same from the estimated states) when the prediction is the low-passed one.
pub(crate) fn model_errors_json(r: &ModelResult) -> Value {
    let opt = |e: &Option<Errors>| e.as_ref().map(errors_json).unwrap_or(Value::Null);
    let mut v = json!({ "train": errors_json(&r.train), "validation": opt(&r.validation), "heldout_train_blocks": r.heldout_rms });
    if let Some(s) = &r.from_states {
        v["from_states"] =
            json!({ "train": errors_json(&s.train), "validation": opt(&s.validation) });
    }
    v
}

/// The `report.json` document.
/// A per-run term's training run, counted from 1 as the files were given (`null` otherwise).
fn run_number(t: &Term) -> Option<usize> {
    t.effect.is_per_run().then_some(t.run + 1)
}

/// A step's coefficient test: one coefficient's `z`, or a unit's joint F.
fn coefficient_json(c: crate::identify::CoefficientTest) -> Value {
    if c.columns > 1 {
        return json!({"f": c.z, "f_crit": c.z_crit, "columns": c.columns, "test": "the friction spline's coefficients together: Hotelling's T^2 from their block-jackknife covariance as F(columns, blocks - columns), fitted with the model and the joint's offset, per-run offsets, viscous and Coulomb friction; Bonferroni over the joints tested, family 1 %; added when it also passes the gain and torque-share rules"});
    }
    json!({"z": c.z, "z_crit": c.z_crit, "test": "asym_coulomb on a joint whose model holds coulomb: |coefficient| / block-jackknife sigma, fitted with the model and the joint's offset, two-sided, Bonferroni over the joints tested, family 1 %; added when it also passes the gain and torque-share rules"})
}

pub fn json_report(o: &Outcome, command: &str) -> Value {
    let eff: Vec<Value> = o
        .effects
        .iter()
        .map(|(t, e)| {
            json!({
                "joint": t.joint + 1, "effect": t.effect.name(), "run": run_number(t), "name": e.name,
                "value": e.value, "std": e.std, "rel_std_percent": e.rel_std_percent, "unit": e.unit,
            })
        })
        .collect();
    let found: Vec<Value> = o
        .selection
        .steps
        .iter()
        .map(|s| {
            json!({
                "joint": s.added.joint + 1, "effect": s.added.effect.name(),
                "run": run_number(&s.added),
                "evidence": {
                    "heldout_gain": s.evidence.heldout_gain,
                    "torque_share": s.evidence.torque_share,
                    "t_stat": s.evidence.t_stat,
                    "t_crit": s.evidence.t_crit,
                    "partial_corr": s.evidence.partial_corr,
                    "coefficient": s.evidence.coefficient.map(coefficient_json),
                    "test": "leave-one-block-out held-out error; one-sided t-test on per-block log ratios of the joint's held-out error, each capped at ±ln 4 (Bonferroni, family 1 %), gain >= 1 % of the joint's held-out residual variance and >= 1e-6 of its torque power",
                }
            })
        })
        .collect();
    let (maps, maps_info) = residual_map::json(o);
    json!({
        "arm": o.arm,
        "dof": o.dof,
        "base_parameters_from": o.base_source,
        "data": { "train": o.train, "validate": o.validate },
        "effects_mode": o.effects_mode,
        "theta": o.theta,
        "effects": eff,
        "effects_found": found,
        "not_identifiable": o.merged.iter().map(|(t, w)| json!({"effect": t, "merged_with": w})).collect::<Vec<_>>(),
        "at_rest": o.at_rest,
        "not_searched": asym_not_searched(o).map(|(j, r)| json!({"effect": Term::new(Effect::AsymCoulomb, j).label(), "at_rest": r, "needed": Effect::ASYM_REST_MIN})).collect::<Vec<_>>(),
        "error": {
            "before": model_errors_json(&o.before),
            "after": model_errors_json(&o.after),
            "plain": o.plain.as_ref().map(model_errors_json),
            "prediction": if o.after.from_states.is_some() { "low-passed (from the parallel-filtered rows); from_states: the same models' torque from the estimated states" } else { "from the estimated states" },
            "definition": "relative RMS ||tau_hat - tau|| / ||tau|| against the torque as measured in the file (unfiltered), per joint and over all joints",
        },
        "steps": o.steps,
        "selection": o.selection,
        "condition_number": o.cond,
        "condition_number_scaled_columns": o.cond_scaled,
        "residual_sigma_per_joint": o.sigma,
        "time_blocks": o.blocks,
        "friction_scales": o.scales,
        "cutoff_scan": o.cutoff_scan,
        "coulomb_width": o.coulomb_width.as_ref().map(|w| json!({
            "cross_validation": w.cross_validation,
            "chosen_fraction": w.chosen,
            "trials": w.trials,
            "definition": "the Coulomb column is tanh(dq / v), v = fraction x the joint's RMS training velocity; each fraction refits the model, judged by the geometric mean over the compared joints of the held-out relative RMS error (by run, or by block with one file); the default 0.01 is kept unless another lowers it by more than 0.1 %",
        })),
        "ripple": {
            "scans": o.ripple,
            "definition": "per scanned joint, the wavenumber k (rad^-1) whose sin(k q), cos(k q) best fit the residual of the model selected without them and without the joint's offset and spring (periodogram beyond a constant per run and, where the model holds a spring, a line in q; k from max(2, 2 pi / range of q) to 60; then refined by backfitting: the joint's partial residual with the pair in the model scanned again, up to twice; then fitted by least squares: the weighted residual sum of squares of the model with the pairs and a constant per run, over k within pi / range of q either side), the share of the residual variance they explain in sample, the prominence (the peak's power over the median of its neighbouring wavenumbers' powers) and whether it is significant (prominence >= log2(m / 0.01), m independent wavenumbers scanned; only then, with --effects auto, is the pair searched), and whether the pair then passed the selection test",
        },
        "estimator": "weighted least squares (per-joint 1/sigma), incremental QR, parallel zero-phase filtering of tau and regressor; std by block jackknife; then the physically consistent estimate closest to it in the same weighted metric (`physical`)",
        "physical": physical::json(o),
        "guard": guard::json(o),
        "run_offsets": run_offsets::json(o),
        "warnings": o.warnings,
        "fixed": o.fixed,
        "undetermined": o.undetermined,
        "residual_maps": maps,
        "residual_maps_info": maps_info,
        "command": command,
    })
}

/// Streams `validation_prediction.csv` (rows as many as the validation samples used, so it is
/// written straight to the file rather than rendered first).
fn prediction_csv(p: &Predictions, w: &mut dyn std::io::Write) -> std::io::Result<()> {
    let n = p.dof;
    let mut w = std::io::BufWriter::new(w);
    write!(w, "t")?;
    let prefixes: &[&str] = if p.consistent {
        &["tau", "before", "after", "consistent"]
    } else {
        &["tau", "before", "after"]
    };
    for prefix in prefixes {
        for j in 1..=n {
            write!(w, ",{prefix}{j}")?;
        }
    }
    writeln!(w)?;
    let mut res = Ok(());
    p.rows(0, p.len(), |t, tau, before, after, consistent| {
        // `{}` prints the shortest representation that parses back to the same f64, so t and tau
        // are the values read from the validation file.
        if res.is_ok() {
            res = (|| {
                write!(w, "{t}")?;
                for v in tau
                    .iter()
                    .chain(before)
                    .chain(after)
                    .chain(consistent.into_iter().flatten())
                {
                    write!(w, ",{v}")?;
                }
                writeln!(w)
            })();
        }
    });
    res?;
    w.flush()
}

fn pct(v: f64) -> String {
    if v.is_finite() {
        format!("{:.2} %", 100.0 * v)
    } else {
        "—".into()
    }
}

fn err_cells(e: &Errors) -> String {
    let mut s: Vec<String> = e.per_joint.iter().map(|v| pct(*v)).collect();
    s.push(format!("**{}**", pct(e.overall)));
    s.join(" | ")
}

fn num(v: f64) -> String {
    if !v.is_finite() {
        return "—".into();
    }
    if v != 0.0 && (v.abs() < 1e-3 || v.abs() >= 1e4) {
        format!("{v:.4e}")
    } else {
        format!("{v:.5}")
    }
}

/// The `report.md` text.
pub fn markdown(o: &Outcome, command: &str, plots: &[String]) -> String {
    let mut m = String::new();
    let _ = writeln!(m, "# Identification of `{}`\n", o.arm);
    let _ = writeln!(m, "Reproduce: `{command}`\n");
    let found: Vec<String> = o
        .selection
        .steps
        .iter()
        .map(|s| format!("`{}`", s.label))
        .collect();
    let _ = writeln!(
        m,
        "Effects mode `{}`; effects found: {}.\n",
        o.effects_mode,
        if found.is_empty() {
            "none".to_string()
        } else {
            found.join(", ")
        }
    );
    if !o.warnings.is_empty() {
        let _ = writeln!(m, "## Warnings: what these data cannot determine\n");
        for w in &o.warnings {
            let _ = writeln!(m, "- {w}");
        }
        let _ = writeln!(m);
    }
    errors_section(&mut m, o);
    guard::section(&mut m, o);
    run_offsets::section(&mut m, o);
    steps_section(&mut m, o);
    evidence_section(&mut m, o);
    parameters_section(&mut m, o);
    physical::section(&mut m, o);
    data_section(&mut m, o);
    residual_map::section(&mut m, o);
    let _ = writeln!(m, "\n## Plots\n");
    // The residual maps are linked in their own section.
    for p in plots.iter().filter(|p| !p.starts_with("residual_map_")) {
        let _ = writeln!(m, "![{p}]({p})\n");
    }
    if o.predictions.is_some() {
        let _ = writeln!(m, "`validation_prediction.csv`: `t`, measured `tau`, and the torques predicted by the declared (`before`) and augmented (`after`) models{} at every validation sample used; the errors above can be recomputed from it.", if o.consistent.is_some() { " and the physically consistent estimate (`consistent`)" } else { "" });
    }
    m
}

/// The torque error table: declared and augmented model, training and validation — each from
/// the prediction the smoothing chose and, when that is the low-passed one, also from the
/// estimated states (what a controller fed those states would compute).
fn errors_section(m: &mut String, o: &Outcome) {
    let n = o.dof;
    let _ = writeln!(
        m,
        "## Torque error (relative RMS ‖τ̂−τ‖/‖τ‖ against the torque as measured in the file)\n"
    );
    let low_passed = o.after.from_states.is_some();
    if low_passed {
        let _ = writeln!(m, "The scan chose to predict from the parallel-filtered rows (*low-passed*): the model's torque is low-passed like the rows it was fitted to. A controller or simulator computing τ from the states sees the *from states* rows.\n");
    }
    let mut models = vec![
        ("before (declared: rigid body)", &o.before),
        ("after (augmented)", &o.after),
    ];
    models.extend(
        o.plain
            .as_ref()
            .map(|p| ("plain fit (rigid + viscous, Coulomb, offset, armature)", p)),
    );
    model_error_table(m, n, "model", &models);
    let _ = writeln!(m);
}

/// Rows `label | training/validation | prediction | per joint | overall` for `models`: the
/// chosen prediction's errors and, where it is the low-passed one, those from the states.
pub(crate) fn model_error_table(
    m: &mut String,
    n: usize,
    what: &str,
    models: &[(&str, &ModelResult)],
) {
    let head: Vec<String> = (1..=n).map(|j| format!("joint {j}")).collect();
    let _ = writeln!(
        m,
        "| {what} | data | prediction | {} | overall |",
        head.join(" | ")
    );
    let _ = writeln!(m, "|---|---|---|{}---|", "---|".repeat(n));
    for (label, r) in models {
        let states = r.from_states.as_ref();
        let chosen = if states.is_some() {
            "low-passed"
        } else {
            "from states"
        };
        let _ = writeln!(
            m,
            "| {label} | training | {chosen} | {} |",
            err_cells(&r.train)
        );
        if let Some(s) = states {
            let _ = writeln!(
                m,
                "| {label} | training | from states | {} |",
                err_cells(&s.train)
            );
        }
        if let Some(v) = &r.validation {
            let _ = writeln!(m, "| {label} | validation | {chosen} | {} |", err_cells(v));
        }
        if let Some(v) = states.and_then(|s| s.validation.as_ref()) {
            let _ = writeln!(
                m,
                "| {label} | validation | from states | {} |",
                err_cells(v)
            );
        }
    }
}

/// The rigid → + effect → … table.
fn steps_section(m: &mut String, o: &Outcome) {
    let _ = writeln!(m, "## Steps: rigid → + effect → …\n");
    let _ = writeln!(
        m,
        "| model | training error | held-out (blocks) | validation error |"
    );
    let _ = writeln!(m, "|---|---|---|---|");
    for s in &o.steps {
        let _ = writeln!(
            m,
            "| {} | {} | {} | {} |",
            s.model,
            pct(s.train.overall),
            pct(s.heldout_rms),
            s.validation.as_ref().map_or("—".into(), |v| pct(v.overall))
        );
    }
    let _ = writeln!(m);
}

/// The evidence for each effect added, why the search stopped, and what was merged, dropped or skipped.
fn evidence_section(m: &mut String, o: &Outcome) {
    let _ = writeln!(m, "## Evidence for each effect added\n");
    let _ = writeln!(
        m,
        "Each candidate (effect, joint) is judged on held-out time blocks ({} blocks; each block predicted by a fit on the others): added only if a one-sided t-test on the per-block log ratios of the joint's held-out error (each capped at ±ln 4) passes (Bonferroni over the candidates, family level 1 %), it removes ≥ 1 % of the joint's held-out residual variance and explains ≥ 1e-6 of its torque power. `asym_coulomb` on a joint whose model holds `coulomb` is also tested on its coefficient (`coefficient z`: |x| / block-jackknife σ, fitted with the model and the joint's offset, Bonferroni over those joints): its evidence sits in the few blocks with rests. The friction spline (`spline_a…c`, after the closed forms) is tested on its three coefficients together (`coefficients F`: Hotelling's T² from their block-jackknife covariance, fitted with the model and the joint's offset, per-run offsets, viscous and Coulomb friction, Bonferroni over the joints): its evidence sits in the blocks where the joint moves fast.\n",
        o.blocks
    );
    let _ = writeln!(
        m,
        "| step | added | held-out gain | t / t_crit | partial corr. of residual |"
    );
    let _ = writeln!(m, "|---|---|---|---|---|");
    for (i, s) in o.selection.steps.iter().enumerate() {
        let e = &s.evidence;
        let test = match e.coefficient {
            Some(c) if c.columns > 1 => format!("coefficients F {:.2} / {:.2}", c.z, c.z_crit),
            Some(c) => format!("coefficient z {:.2} / {:.2}", c.z, c.z_crit),
            None => format!("{:.1} / {:.1}", e.t_stat, e.t_crit),
        };
        let _ = writeln!(
            m,
            "| {} | `{}` | {} | {test} | {:.3} |",
            i + 1,
            s.label,
            pct(e.heldout_gain),
            e.partial_corr
        );
    }
    if let Some(e) = &o.selection.stopped_on {
        let _ = writeln!(
            m,
            "\nStopped: the best remaining candidate `{}` gained {} (t = {:.2}, needed {:.2}; torque share {:.2e}).",
            e.label,
            pct(e.heldout_gain),
            e.t_stat,
            e.t_crit,
            e.torque_share
        );
    }
    let gated: Vec<String> = asym_not_searched(o)
        .map(|(j, r)| format!("joint {} {:.1} %", j + 1, 100.0 * r))
        .collect();
    if !gated.is_empty() {
        let _ = writeln!(m, "\n`asym_coulomb` (different friction levels in the two directions) was not searched where a joint is at rest in under {:.0} % of the training samples ({}): there its column is the offset's but for the velocity reversals, so these data cannot tell the two apart. Record motion with rests (point to point) to identify it.", 100.0 * Effect::ASYM_REST_MIN, gated.join(", "));
    }
    for (t, w) in &o.merged {
        let _ = writeln!(m, "\n`{t}` is not identifiable: its column equals a combination of {} for every motion, so it is merged there (not reported as an effect).", w.join(", "));
    }
    if !o.selection.dropped.is_empty() {
        let _ = writeln!(
            m,
            "\nDropped (found first, then redundant once a load-dependent term was in the model): {}.",
            o.selection.dropped.join(", ")
        );
    }
    if !o.selection.collinear.is_empty() {
        let _ = writeln!(
            m,
            "\nSkipped (collinear with the model in this data): {}.",
            o.selection.collinear.join(", ")
        );
    }
    let _ = writeln!(m);
}

/// The augmented model's parameters and its conditioning.
fn parameters_section(m: &mut String, o: &Outcome) {
    let _ = writeln!(m, "## Identified parameters (augmented model)\n");
    let _ = writeln!(
        m,
        "Base parameters from {}. Standard deviations by block jackknife.\n",
        o.base_source
    );
    let _ = writeln!(m, "| parameter | expression | value | std | %σ |");
    let _ = writeln!(m, "|---|---|---|---|---|");
    for p in &o.theta {
        let _ = writeln!(
            m,
            "| `{}` | {} | {} | {} | {:.2} |",
            p.name,
            p.expression,
            num(p.value),
            num(p.std),
            p.rel_std_percent
        );
    }
    for (_, p) in &o.effects {
        let _ = writeln!(
            m,
            "| `{}` | {} [{}] | {} | {} | {:.2} |",
            p.name,
            p.expression,
            p.unit.as_deref().unwrap_or(""),
            num(p.value),
            num(p.std),
            p.rel_std_percent
        );
    }
    let _ = writeln!(
        m,
        "\nCondition number of the weighted regressor: {:.1} (columns scaled to unit norm: {:.1}).",
        o.cond, o.cond_scaled
    );
    let _ = writeln!(
        m,
        "Residual standard deviation per joint (weights 1/σ): {}.\n",
        o.sigma
            .iter()
            .map(|s| num(*s))
            .collect::<Vec<_>>()
            .join(", ")
    );
}

/// The files, filters and derivative estimator, and the cut-off scan.
fn data_section(m: &mut String, o: &Outcome) {
    let _ = writeln!(m, "## Data, filter and derivative estimator\n");
    let _ = writeln!(m, "| file | role | rows (used) | duration | sampling dt median / min / max | resampled | filter | q̇ | q̈ | regression filter | regression row every |");
    let _ = writeln!(m, "|---|---|---|---|---|---|---|---|---|---|---|");
    let files = o
        .train
        .iter()
        .map(|f| ("training", f))
        .chain(o.validate.iter().map(|f| ("validation", f)));
    for (role, f) in files {
        let d = &f.derivative;
        let s = &d.sampling;
        let _ = writeln!(
            m,
            "| `{}` | {} | {} ({}) | {:.2} s | {:.3} / {:.3} / {:.3} ms | {} | {} | {} | {} | {} | {} |",
            f.file,
            role,
            f.rows,
            f.rows_used,
            f.duration_s,
            1e3 * s.dt_median,
            1e3 * s.dt_min,
            1e3 * s.dt_max,
            if d.resampled {
                "yes (linear, to the median step)"
            } else {
                "no"
            },
            d.filter,
            d.dq_source,
            d.ddq_source,
            f.regression_filter,
            if role == "training" {
                format!("{} samples", f.regression_row_every)
            } else {
                "—".to_string()
            }
        );
    }
    if !o.cutoff_scan.is_empty() {
        let scope = match o.scan_sampling {
            Some(s) => format!(
                "; fitted on {} evenly spaced pieces of each training file, {} samples in all — the final fit uses every sample",
                s.pieces_per_file, s.samples
            ),
            None => String::new(),
        };
        let fixed_fc = o
            .cutoff_scan
            .iter()
            .all(|c| c.cutoff_hz == o.cutoff_scan[0].cutoff_hz);
        let what = if fixed_fc {
            "Regression filter and prediction chosen automatically (one cut-off)"
        } else {
            "Cut-off, regression filter and prediction chosen automatically"
        };
        let again = if o.rescanned_with.is_empty() {
            String::new()
        } else {
            format!(
                "; repeated with {} in the models, found by the first pass",
                o.rescanned_with.join(", ")
            )
        };
        let _ = writeln!(m, "\n{what}: smallest held-out error against the measured torque over the scan (rigid body + all candidate effects{scope}{again}):\n");
        let _ = writeln!(
            m,
            "| cut-off (Hz) | regression filter | prediction | held-out error |"
        );
        let _ = writeln!(m, "|---|---|---|---|");
        for c in &o.cutoff_scan {
            let _ = writeln!(
                m,
                "| {:.2} | {}·fc | {} | {} |",
                c.cutoff_hz,
                c.smoothing.regression_ratio,
                c.smoothing.prediction_source(),
                pct(c.heldout_error)
            );
        }
    }
    width_section(m, o);
    ripple_section(m, o);
    let sm = o.train.first().map(|f| f.smoothing).unwrap_or_default();
    let _ = writeln!(
        m,
        "\nThe regression filter (zero-phase, at {}× the derivative filter's cut-off) was applied to the measured torque and to every regressor column (parallel filtering) to build the regression, whose rows are then kept at {}× its cut-off or more (the table's last column: the filtered columns carry nothing above a few cut-offs). Models predict the torque from {}; errors are computed against the unfiltered torque at every one of the file's own samples. Filter edges are dropped.",
        sm.regression_ratio,
        KEEP_RATE_PER_CUTOFF,
        if sm.filtered_prediction {
            "the parallel-filtered rows, the very rows the parameters were fitted to (right when the torque is smooth and the motion kinks, e.g. an arm driven by smooth torques whose friction flips at velocity reversals)"
        } else {
            "the rows of the estimated states (right when the motion is smooth and the torque jumps, e.g. Coulomb friction under a stiff position loop)"
        }
    );
}

/// The Coulomb width scan's table (nothing when the model was not scanned).
fn width_section(m: &mut String, o: &Outcome) {
    let Some(w) = &o.coulomb_width else {
        return;
    };
    let _ = writeln!(
        m,
        "\nCoulomb width: the Coulomb column is tanh(q̇ / v), v a fraction of each joint's RMS training velocity; each width refitted the model and was judged on held-out training data (by {}; geometric mean of the joints' errors). Kept: {}{}.\n",
        w.cross_validation,
        w.chosen,
        if w.chosen == crate::effects::Scales::COULOMB_FRACTION {
            " (the default)"
        } else {
            ""
        }
    );
    let _ = writeln!(
        m,
        "| v / RMS velocity | held-out error per joint | geometric mean |"
    );
    let _ = writeln!(m, "|---|---|---|");
    for t in &w.trials {
        let per: Vec<String> = t.heldout.iter().map(|e| pct(*e)).collect();
        let _ = writeln!(
            m,
            "| {} | {} | {} |",
            t.fraction,
            per.join(" / "),
            pct(t.score)
        );
    }
}

/// The ripple scan's table (nothing when no joint was scanned).
fn ripple_section(m: &mut String, o: &Outcome) {
    if o.ripple.is_empty() {
        return;
    }
    let _ = writeln!(
        m,
        "\nPosition ripple: per joint, the wavenumber k whose sin(k·q), cos(k·q) best fit the residual of the model without them (periodogram); a peak that stands out of its neighbours more than noise would (prominence: its power over their median) is then tested like any effect.\n"
    );
    let _ = writeln!(
        m,
        "| joint | k (1/rad) | residual variance explained | prominence | in the model |"
    );
    let _ = writeln!(m, "|---|---|---|---|---|");
    for s in &o.ripple {
        let _ = writeln!(
            m,
            "| {} | {:.3} | {} | {:.1}{} | {} |",
            s.joint + 1,
            s.k,
            pct(s.share),
            s.prominence,
            if s.significant { "" } else { " (noise)" },
            if s.accepted { "yes" } else { "no" }
        );
    }
}

fn bounds(pts: impl Iterator<Item = (f64, f64)>) -> (f64, f64, f64, f64) {
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for (x, y) in pts {
        if x.is_finite() && y.is_finite() {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
    }
    if x1.is_nan() || x0.is_nan() || x1 <= x0 {
        (x0, x1) = (x0.min(0.0) - 1.0, x1.max(0.0) + 1.0);
    }
    if y1.is_nan() || y0.is_nan() || y1 <= y0 {
        (y0, y1) = (y0.min(0.0) - 1.0, y1.max(0.0) + 1.0);
    }
    let (px, py) = (0.03 * (x1 - x0), 0.05 * (y1 - y0));
    (x0 - px, x1 + px, y0 - py, y1 + py)
}

fn residual_plot(o: &Outcome, j: usize) -> Result<String, String> {
    let (before, after) = &o.series.resid_vs_vel[j];
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (800, 500)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let (x0, x1, y0, y1) = bounds(before.iter().chain(after.iter()).copied());
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!(
                    "joint {}: torque residual vs velocity (training data)",
                    j + 1
                ),
                ("sans-serif", 20),
            )
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            // Plain ASCII: the combining dot of q̇ is lost by common SVG fonts (it rendered as "q1").
            .x_desc(format!("joint velocity dq{}/dt (rad/s)", j + 1))
            .y_desc("τ measured − τ predicted (N·m)")
            .draw()
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(
                before
                    .iter()
                    .map(|&(x, y)| Circle::new((x, y), 1, RGBColor(200, 80, 60).filled())),
            )
            .map_err(|e| e.to_string())?
            .label("before (rigid body)")
            .legend(|(x, y)| Circle::new((x, y), 3, RGBColor(200, 80, 60).filled()));
        chart
            .draw_series(
                after
                    .iter()
                    .map(|&(x, y)| Circle::new((x, y), 1, RGBColor(40, 90, 200).filled())),
            )
            .map_err(|e| e.to_string())?
            .label("after (augmented)")
            .legend(|(x, y)| Circle::new((x, y), 3, RGBColor(40, 90, 200).filled()));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}

/// A labelled curve of the validation plot: which value of `(t, measured, before, after)`.
type Curve = (&'static str, RGBColor, fn(&(f64, f64, f64, f64)) -> f64);

fn validation_plot(o: &Outcome, j: usize) -> Result<String, String> {
    let pts = &o.series.validation[j];
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1000, 450)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let (x0, x1, y0, y1) = bounds(
            pts.iter()
                .flat_map(|&(t, a, b, c)| [(t, a), (t, b), (t, c)]),
        );
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!(
                    "joint {}: predicted vs measured torque (validation data)",
                    j + 1
                ),
                ("sans-serif", 20),
            )
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("t (s)")
            .y_desc(format!("τ{} (N·m)", j + 1))
            .draw()
            .map_err(|e| e.to_string())?;
        let series: [Curve; 3] = [
            ("measured", RGBColor(120, 120, 120), |p| p.1),
            ("before (rigid body)", RGBColor(200, 80, 60), |p| p.2),
            ("after (augmented)", RGBColor(40, 90, 200), |p| p.3),
        ];
        for (label, color, f) in series {
            chart
                .draw_series(LineSeries::new(
                    pts.iter().map(|p| (p.0, f(p))),
                    color.stroke_width(1),
                ))
                .map_err(|e| e.to_string())?
                .label(label)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}

/// The joints (and their share of samples at rest) where `--effects auto` did not search
/// `asym_coulomb`: at rest too rarely to tell it from an offset.
fn asym_not_searched(o: &Outcome) -> impl Iterator<Item = (usize, f64)> + '_ {
    let auto = o.effects_mode == "auto";
    o.at_rest
        .iter()
        .copied()
        .enumerate()
        .filter(move |&(_, r)| auto && !Effect::rests_enough(r))
}
