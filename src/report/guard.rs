//! The per-joint guard's section of `report.md` and its `report.json` value: per joint, the
//! selected model against the plain fit on held-out training data (and on the validation file
//! when there is one), which won and by how much, what the guard added, the weak joints.

use std::fmt::Write as _;

use serde_json::{json, Value};

use crate::identify::Outcome;

fn pct(v: f64) -> String {
    if v.is_finite() {
        format!("{:.2} %", 100.0 * v)
    } else {
        "—".into()
    }
}

/// `report.json`'s `guard` (null without one).
pub fn json(o: &Outcome) -> Value {
    let Some(g) = &o.guard else {
        return Value::Null;
    };
    let val = |r: Option<&crate::identify::ModelResult>, j: usize| {
        r.and_then(|r| r.validation.as_ref())
            .and_then(|v| v.per_joint.get(j).copied())
    };
    let joints: Vec<Value> = g
        .joints
        .iter()
        .map(|jg| {
            let mut v = serde_json::to_value(jg).unwrap_or(Value::Null);
            v["joint"] = json!(jg.joint + 1);
            v["validation_selected"] = json!(val(Some(&o.after), jg.joint));
            v["validation_plain"] = json!(val(o.plain.as_ref(), jg.joint));
            v
        })
        .collect();
    let weak: Vec<Value> = g
        .weak
        .iter()
        .map(|w| {
            let mut v = serde_json::to_value(w).unwrap_or(Value::Null);
            v["joint"] = json!(w.joint + 1);
            v
        })
        .collect();
    json!({
        "cross_validation": g.cross_validation,
        "definition": "per joint relative RMS ||tau_hat - tau|| / ||tau|| against the measured torque, each training file predicted by the fit without it (cross_validation = run) or each time block by the fit without it (block); selected = the model --effects auto chose, after the guard's additions; t_stat = one-sided t statistic of the per-block log ratios (selected / plain) of the joint's leave-one-block-out error on the regression rows; the guard adds a joint's missing plain terms when the plain fit is better pooled and t_stat > t_crit (level alpha, Bonferroni over the joints: block route); when it is better pooled but t_stat <= t_crit, coefficient_tests: each missing viscous, Coulomb or armature term fitted with the model, z = |coefficient| / block-jackknife sigma against z_crit (two-sided, level alpha, Bonferroni over the terms tested), added when z > z_crit and the joint's pooled held-out error falls (coefficient route)",
        "alpha": g.alpha,
        "plain_terms": g.plain_terms,
        "plain_collinear": g.plain_collinear,
        "fixes": g.fixes,
        "joints": joints,
        "weak_joints": weak,
        "overall_pools_joints": o.after.train.pooled_joints.as_ref().map(|j| j.iter().map(|j| j + 1).collect::<Vec<_>>()),
    })
}

/// The section (nothing without a guard).
pub fn section(m: &mut String, o: &Outcome) {
    let Some(g) = &o.guard else {
        return;
    };
    let _ = writeln!(
        m,
        "## Per joint: the selected model against the plain fit\n"
    );
    let by = if g.cross_validation == "run" {
        "each training file predicted by the fit without it"
    } else {
        "each time block predicted by the fit without it"
    };
    let _ = writeln!(
        m,
        "The plain fit is the rigid body plus {} (one least-squares solve{}). Held out: {by}; relative RMS against the measured torque, each joint on its own scale. Where the plain fit predicted a joint better — in the pooled error and block after block (t: one-sided t-test on the per-block log ratios, selected / plain; it acts above {:.2}, family level {} % over the joints) — the guard added the plain terms the search had left out on that joint (module docs of `identify::guard`).\n",
        g.plain_terms.join(", "),
        if g.plain_collinear.is_empty() {
            String::new()
        } else {
            format!(
                "; {} left out: collinear with the other columns in this data",
                g.plain_collinear.join(", ")
            )
        },
        g.joints.first().map_or(f64::NAN, |j| j.t_crit),
        100.0 * g.alpha,
    );
    let has_val = o.after.validation.is_some() && o.plain.is_some();
    let _ = writeln!(
        m,
        "| joint | selected, held-out | plain, held-out | selected / plain | t | winner | guard added{} |",
        if has_val { " | selected, validation | plain, validation" } else { "" }
    );
    let _ = writeln!(
        m,
        "|---|---|---|---|---|---|---|{}",
        if has_val { "---|---|" } else { "" }
    );
    for jg in &g.joints {
        let j = jg.joint;
        let val = |r: Option<&crate::identify::ModelResult>| {
            r.and_then(|r| r.validation.as_ref())
                .and_then(|v| v.per_joint.get(j).copied())
                .map_or("—".into(), pct)
        };
        let _ = writeln!(
            m,
            "| {} | {} | {} | {:.3} | {:.2} | {} | {}{} |",
            j + 1,
            pct(jg.selected),
            pct(jg.plain),
            jg.ratio,
            jg.t_stat,
            jg.winner,
            if jg.added.is_empty() {
                "—".into()
            } else {
                jg.added.join(", ")
            },
            if has_val {
                format!(" | {} | {}", val(Some(&o.after)), val(o.plain.as_ref()))
            } else {
                String::new()
            }
        );
    }
    for f in &g.fixes {
        let _ = writeln!(m, "\nGuard: {f}.");
    }
    // Where the plain fit still wins: what the held-out residual maps show on that joint.
    for jg in g.joints.iter().filter(|jg| jg.winner == "plain") {
        let j = jg.joint;
        let off = super::residual_map::departing(o, j);
        let (means, unit) = super::residual_map::run_means(o, j);
        let runs: Vec<String> = means
            .iter()
            .map(|(mean, lo, hi)| format!("{mean:+.3e} {unit} [{lo:+.3e}, {hi:+.3e}]"))
            .collect();
        // The cause reads "joint N: …": the paragraph starts with what follows.
        let cause = jg.cause.as_deref().unwrap_or_default();
        let why = cause.split_once(": ").map_or(cause, |(_, why)| why);
        let _ = writeln!(
            m,
            "\nJoint {}: {why}. Its held-out residual maps (section \"Residual maps\") depart from zero on {}; its mean held-out residual per training file, with 95 % band: {} — a band off zero is a constant the model lacks and the plain fit's offset would take; a departing velocity or acceleration map, friction or rotor inertia.",
            j + 1,
            if off.is_empty() { "no variable".to_string() } else { off.join(", ") },
            runs.join(", "),
        );
    }
    if let Some(p) = &o.after.train.pooled_joints {
        let names: Vec<String> = p.iter().map(|j| (j + 1).to_string()).collect();
        let _ = writeln!(
            m,
            "\nThe overall errors in this report pool joints {} only: the others are weak or in another unit (each is in its own column).",
            names.join(", ")
        );
    }
    for w in &g.weak {
        let _ = writeln!(m, "\nNot identifiable — {}.", w.reason);
    }
    let _ = writeln!(m);
}
