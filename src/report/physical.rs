//! The physically consistent estimate in the report: its section of `report.md`, its keys in
//! `report.json`, and the model a user loads elsewhere — `identified.params.toml` (the params
//! format of `dynid torque` and `dynid simulate`) and, for a D-H arm, `identified.urdf`.

use std::fmt::Write as _;

use serde_json::{json, Value};

use super::{num, pct};
use crate::dh::DhTable;
use crate::effects::Run;
use crate::identify::Outcome;
use crate::params::{Effects, InertialParams};

/// The identified model as a params file's contents (none without a consistent estimate).
pub fn params(o: &Outcome) -> Option<InertialParams> {
    let ph = o.physical.as_ref()?;
    let n = o.dof;
    let mut e = Effects::default();
    for &(t, v) in &ph.effects {
        // A new run's per-run offset is the mean of the training runs' ([`Run::Unseen`]).
        let w = if t.effect.is_per_run() {
            Run::Unseen { runs: o.runs.len() }.indicator(t.run)
        } else {
            1.0
        };
        e.coefficients_mut(t.effect)
            .get_or_insert_with(|| vec![0.0; n])[t.joint] += w * v;
    }
    // The model's friction sign is the fitted tanh(q̇/v); the plant must use the same.
    if [&e.coulomb, &e.asym_coulomb, &e.stribeck, &e.loadcoulomb]
        .iter()
        .any(|v| v.is_some())
    {
        e.sign_velocity = Some(o.scales.iter().map(|s| s.coulomb_v).collect());
    }
    if e.ripple_sin.is_some() || e.ripple_cos.is_some() {
        e.ripple_wavenumber = Some(o.scales.iter().map(|s| s.ripple_k).collect());
    }
    if e.spline_a.is_some() || e.spline_b.is_some() || e.spline_c.is_some() {
        e.spline_velocity = Some(o.scales.iter().map(|s| s.spline_v).collect());
    }
    if e.stribeck.is_some() {
        e.stribeck_velocity = Some(o.scales.iter().map(|s| s.stribeck_v).collect());
    }
    Some(InertialParams::from_full_vector(&ph.params, e))
}

/// `identified.params.toml`.
pub fn params_toml(o: &Outcome, command: &str) -> Option<String> {
    let p = params(o)?;
    let mut header = vec![
        format!("Identified by: {command}"),
        format!(
            "The physically consistent estimate of `{}` (report.md, \"Physically consistent estimate\"):",
            o.arm
        ),
        "every link's pseudo-inertia is positive semidefinite; friction and rotor inertia are >= 0.".into(),
        "Only the base parameters are determined by the data; the rest of each link follows the regulariser".into(),
        "named in the report. Load it with: dynid torque --arm ARM --params identified.params.toml --data LOG".into(),
    ];
    if p.effects.loadcoulomb.is_some() {
        header.push("loadcoulomb: here it scales the final model's torque |u|; identification's column used the first-stage model's torque, so predictions differ slightly.".into());
    }
    Some(p.to_toml(&header))
}

/// `identified.urdf`: the D-H arm with the consistent inertials and `<dynamics>` (none without a
/// D-H table or a consistent estimate).
pub fn urdf(o: &Outcome, table: Option<&DhTable>) -> Option<Result<String, String>> {
    let (p, table) = (params(o)?, table?);
    Some(
        crate::urdf::export(table, Some(&p))
            .map(|s| {
                let note = "<!-- dynid identify: identified (physically consistent) inertials; viscous and Coulomb friction as <dynamics damping friction>. URDF has no place for asymmetric Coulomb friction, rotor inertia, offsets, springs, Stribeck, spline or load-dependent friction, or for the smoothed friction sign: identified.params.toml carries them. -->\n";
                match s.find("<robot") {
                    Some(i) => format!("{}{note}{}", &s[..i], &s[i..]),
                    None => s,
                }
            })
            .map_err(|e| e.to_string()),
    )
}

/// `identified.urdf` for an arm that came from a URDF: that file with the consistent inertials
/// and `<dynamics>` spliced in (see [`crate::urdf::roundtrip`]); none without a consistent
/// estimate.
pub fn urdf_roundtrip(
    o: &Outcome,
    source: &crate::urdf::roundtrip::UrdfSource,
) -> Option<Result<crate::urdf::roundtrip::RoundTrip, crate::urdf::UrdfError>> {
    Some(source.rewrite(&params(o)?))
}

/// `report.json`'s `physical` object.
pub fn json(o: &Outcome) -> Value {
    match (&o.physical, &o.physical_error) {
        (Some(p), _) => json!({
            "least_squares_consistent": p.least_squares_consistent,
            "residual_increase": p.residual_increase,
            "active_constraints": p.active,
            "links": p.links,
            "standard_parameters": p.params,
            "effects": p.effects.iter().map(|(t, v)| json!({"joint": t.joint + 1, "effect": t.effect.name(), "value": v})).collect::<Vec<_>>(),
            "error": o.consistent.as_ref().map(super::model_errors_json),
            "regulariser": p.regulariser,
            "newton_steps": p.newton_steps,
        }),
        (None, Some(e)) => json!({ "failed": e }),
        (None, None) => Value::Null,
    }
}

/// The one-line verdict.
pub fn verdict(o: &Outcome) -> String {
    match (&o.physical, &o.physical_error) {
        (Some(p), _) => {
            let links: Vec<&str> = p
                .active
                .iter()
                .filter(|a| a.starts_with("link"))
                .map(|a| a.split(':').next().unwrap_or(a))
                .collect();
            let boundary = if links.is_empty() {
                String::new()
            } else {
                format!(
                    "; on the boundary of the physical set (a degenerate body: point mass, rod or plate): {}",
                    links.join(", ")
                )
            };
            if p.least_squares_consistent {
                format!("**Physical consistency:** the least-squares estimate is physically consistent (the consistent estimate equals it){boundary}.")
            } else {
                let binds = if p.active.is_empty() {
                    "no constraint binds".to_string()
                } else {
                    format!("binding: {}", p.active.join("; "))
                };
                format!(
                    "**Physical consistency:** the least-squares estimate is **not** physically consistent (the closest physical arm raises the weighted training residual by {}); consistent estimate — {binds}.",
                    pct(p.residual_increase)
                )
            }
        }
        (None, Some(e)) => format!(
            "**Physical consistency:** not checked — the consistent fit failed: {e}. The least-squares result above stands."
        ),
        (None, None) => "**Physical consistency:** not checked (`--physical off`).".into(),
    }
}

/// The `report.md` section.
pub fn section(m: &mut String, o: &Outcome) {
    let _ = writeln!(m, "## Physically consistent estimate\n");
    let _ = writeln!(m, "{}\n", verdict(o));
    let (Some(p), Some(c)) = (&o.physical, &o.consistent) else {
        return;
    };
    super::model_error_table(
        m,
        o.dof,
        "estimate",
        &[("least squares", &o.after), ("consistent", c)],
    );
    let _ = writeln!(
        m,
        "\n| link | mass (kg) | centre of mass (m) | principal moments (kg·m²) | min eig. of pseudo-inertia | relative |"
    );
    let _ = writeln!(m, "|---|---|---|---|---|---|");
    let three = |v: Option<[f64; 3]>| {
        v.map_or("—".into(), |v| {
            v.iter().map(|x| num(*x)).collect::<Vec<_>>().join(", ")
        })
    };
    for l in &p.links {
        let _ = writeln!(
            m,
            "| {} | {} | {} | {} | {} | {:.1e} |",
            l.link,
            num(l.mass),
            three(l.com),
            three(l.principal_moments),
            num(l.min_eigenvalue),
            l.relative_min_eigenvalue
        );
    }
    if !p.effects.is_empty() {
        let _ = writeln!(m, "\n| effect | least squares | consistent |");
        let _ = writeln!(m, "|---|---|---|");
        for (t, v) in &p.effects {
            let ls = o.effects.iter().find(|(u, _)| u == t).map(|(_, e)| e.value);
            let _ = writeln!(
                m,
                "| `{}` | {} | {} |",
                t.label(),
                ls.map_or("—".into(), num),
                num(*v)
            );
        }
    }
    let _ = writeln!(
        m,
        "\nThe data determine the base parameters; the rest of each link is {}. Solved in {} Newton steps ({:.0} ms).",
        p.regulariser, p.newton_steps, p.solve_ms
    );
    let _ = writeln!(
        m,
        "`identified.params.toml` holds this model (load it with `dynid torque --params`); `identified.urdf`, when written, the same inertials and viscous/Coulomb friction as `<dynamics>`.\n"
    );
}
