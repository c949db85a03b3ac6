//! The per-run offsets in the report: per joint with a per-run term, each training run's offset
//! (run 1's is the joint's `offset`, 0 without one; run R's adds `run_offsetJ@R`), their mean —
//! what a run the model was not fitted on is predicted with — and their spread between runs, how
//! far a new run's own offset may be from that mean.

use std::fmt::Write as _;

use serde::Serialize;
use serde_json::Value;

use crate::effects::Effect;
use crate::identify::Outcome;

/// One joint's offsets, run by run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JointRunOffsets {
    /// 1-based.
    pub joint: usize,
    /// Each training run's offset, in the order of the training files.
    pub offsets: Vec<f64>,
    /// Their mean: a new run's offset in the model.
    pub mean: f64,
    /// Their sample standard deviation (between runs).
    pub sd: f64,
}

/// The joints of `o`'s model with a per-run term.
pub fn per_joint(o: &Outcome) -> Vec<JointRunOffsets> {
    let runs = o.runs.len();
    let mut joints: Vec<usize> = o
        .effects
        .iter()
        .filter(|(t, _)| t.effect.is_per_run())
        .map(|(t, _)| t.joint)
        .collect();
    joints.sort_unstable();
    joints.dedup();
    joints
        .into_iter()
        .map(|j| {
            let coef = |effect: Effect, run: usize| {
                o.effects
                    .iter()
                    .find(|(t, _)| t.effect == effect && t.joint == j && t.run == run)
                    .map_or(0.0, |(_, e)| e.value)
            };
            let first = coef(Effect::Offset, 0);
            let offsets: Vec<f64> = (0..runs)
                .map(|r| match r {
                    0 => first,
                    r => first + coef(Effect::RunOffset, r),
                })
                .collect();
            let mean = offsets.iter().sum::<f64>() / runs.max(1) as f64;
            let ss: f64 = offsets.iter().map(|v| (v - mean).powi(2)).sum();
            JointRunOffsets {
                joint: j + 1,
                offsets,
                mean,
                sd: (ss / (runs.max(2) - 1) as f64).sqrt(),
            }
        })
        .collect()
}

/// `report.json`'s `run_offsets` (an empty list without per-run terms).
pub fn json(o: &Outcome) -> Value {
    serde_json::to_value(per_joint(o)).unwrap_or(Value::Null)
}

/// The section of `report.md` (nothing without per-run terms).
pub fn section(m: &mut String, o: &Outcome) {
    let joints = per_joint(o);
    if joints.is_empty() {
        return;
    }
    let _ = writeln!(m, "## Per-run offsets\n");
    let _ = writeln!(
        m,
        "Each training run's torque offset (run 1's is `offsetJ`, run R's adds `run_offsetJ@R`). A run the model was not fitted on is predicted with their mean (`identified.params.toml` holds it in `offset`); its own offset may differ from that mean by about the spread between runs.\n"
    );
    for (i, r) in o.runs.iter().enumerate() {
        let _ = writeln!(m, "- run {}: `{r}`", i + 1);
    }
    let heads: Vec<String> = (1..=o.runs.len()).map(|r| format!("run {r}")).collect();
    let _ = writeln!(
        m,
        "\n| joint | {} | mean (a new run) | SD between runs |",
        heads.join(" | ")
    );
    let _ = writeln!(m, "|---|{}---|---|", "---|".repeat(heads.len()));
    for jr in &joints {
        let cells: Vec<String> = jr.offsets.iter().map(|v| format!("{v:.4}")).collect();
        let _ = writeln!(
            m,
            "| {} | {} | {:.4} | {:.4} |",
            jr.joint,
            cells.join(" | "),
            jr.mean,
            jr.sd
        );
    }
    let _ = writeln!(m);
}
