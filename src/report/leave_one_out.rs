//! The leave-one-out study's report: `leave_one_out.md` / `.json` (one row per held-out file,
//! the pooled validation error) and each fold's full report in `heldout_<file>/`.

use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::Path;

use super::ReportError;
use crate::dh::DhTable;
use crate::identify::{
    pooled_plain_validation, pooled_validation, pooled_validation_from_states, Errors, Outcome,
};
use crate::io::atomic_write;

/// Writes the study's reports into `dir` (each fold's, then the summary); returns the summary
/// table (`leave_one_out.md`) for the terminal.
pub fn write(
    dir: &Path,
    outs: &[Outcome],
    command: &str,
    table: Option<&DhTable>,
) -> Result<String, ReportError> {
    let mut md = String::from("# Leave-one-out identification\n\n");
    let _ = writeln!(md, "Reproduce: `{command}`\n");
    let _ = writeln!(
        md,
        "| held-out file | effects found | cut-off (Hz) | regression filter, prediction | validation before | validation after | after, from states | consistent |"
    );
    let _ = writeln!(md, "|---|---|---|---|---|---|---|---|");
    let mut rows = Vec::new();
    let mut reports = Vec::new();
    for o in outs {
        let v = o
            .validate
            .as_ref()
            .map(|f| f.file.clone())
            .unwrap_or_default();
        let found: Vec<String> = o.selection.steps.iter().map(|s| s.label.clone()).collect();
        let (b, a) = (
            o.before.validation.as_ref().map_or(f64::NAN, |e| e.overall),
            o.after.validation.as_ref().map_or(f64::NAN, |e| e.overall),
        );
        let c = o
            .consistent
            .as_ref()
            .and_then(|c| c.validation.as_ref())
            .map_or(f64::NAN, |e| e.overall);
        let states = o
            .after
            .from_states
            .as_ref()
            .map_or(o.after.validation.as_ref(), |s| s.validation.as_ref())
            .map_or(f64::NAN, |e| e.overall);
        let fc = o.train.first().map_or(f64::NAN, |f| f.derivative.cutoff_hz);
        let sm = o.train.first().map(|f| f.smoothing).unwrap_or_default();
        let _ = writeln!(
            md,
            "| `{v}` | {} | {fc:.2} | {} | {:.2} % | {:.2} % | {:.2} % | {:.2} % |",
            found.join(", "),
            sm.label(),
            100.0 * b,
            100.0 * a,
            100.0 * states,
            100.0 * c
        );
        rows.push(serde_json::json!({"heldout": v, "effects_found": found, "cutoff_hz": fc, "smoothing": sm, "validation_before": o.before.validation, "validation_after": o.after.validation, "validation_consistent": o.consistent.as_ref().and_then(|c| c.validation.as_ref()), "validation_after_from_states": states, "least_squares_consistent": o.physical.as_ref().map(|p| p.least_squares_consistent), "steps": o.steps}));
        let stem = Path::new(&v)
            .file_name()
            .map(|s| {
                s.to_string_lossy()
                    .replace(".csv.gz", "")
                    .replace(".csv", "")
            })
            .unwrap_or_default();
        reports.push((dir.join(format!("heldout_{stem}")), o));
    }
    let pooled = pooled_validation(outs);
    if let Some((b, a, c)) = &pooled {
        let _ = writeln!(md, "\nPooled over all held-out files (‖τ̂−τ‖/‖τ‖ against the measured torque): before {:.2} %, after {:.2} % (per joint before {:?}, after {:?}).", 100.0 * b.overall, 100.0 * a.overall, b.per_joint, a.per_joint);
        if let Some(c) = c {
            let _ = writeln!(
                md,
                "The physically consistent estimate, pooled: {:.2} % (per joint {:?}).",
                100.0 * c.overall,
                c.per_joint
            );
        }
    }
    let plain = pooled_plain_validation(outs);
    if let (Some((_, a, _)), Some(p)) = (&pooled, &plain) {
        let _ = writeln!(md, "\nPer joint, pooled over the held-out files: the selected model against the plain fit (rigid + viscous, Coulomb, offset, armature on every joint, one least-squares solve), each with the prediction its fold chose.\n\n| joint | selected | plain | selected / plain |\n|---|---|---|---|");
        for (j, (s, q)) in a.per_joint.iter().zip(&p.per_joint).enumerate() {
            let _ = writeln!(
                md,
                "| {} | {:.2} % | {:.2} % | {:.3} |",
                j + 1,
                100.0 * s,
                100.0 * q,
                s / q
            );
        }
    }
    let states = pooled_validation_from_states(outs);
    if let Some((b, a, c)) = &states {
        let _ = writeln!(md, "\nThe same, every model's torque predicted from the estimated states (what a controller computing τ from those states would see; the table's prediction column says which one each fold chose): before {:.2} %, after {:.2} %{}.", 100.0 * b.overall, 100.0 * a.overall, c.as_ref().map_or(String::new(), |c| format!(", consistent {:.2} %", 100.0 * c.overall)));
    }
    let both = |p: Option<(Errors, Errors, Option<Errors>)>| {
        p.map(|(b, a, c)| serde_json::json!({"before": b, "after": a, "consistent": c}))
    };
    let json = serde_json::json!({"folds": rows, "pooled": both(pooled), "pooled_from_states": both(states), "pooled_plain": plain, "command": command});
    // Each fold's report on its own thread (they share nothing).
    reports
        .par_iter()
        .try_for_each(|(d, o)| super::write(d, o, command, table).map(drop))?;
    atomic_write(&dir.join("leave_one_out.md"), |w| {
        w.write_all(md.as_bytes())
    })?;
    let text = serde_json::to_string_pretty(&json).unwrap_or_default();
    atomic_write(&dir.join("leave_one_out.json"), |w| {
        w.write_all(text.as_bytes())
    })?;
    Ok(md)
}
