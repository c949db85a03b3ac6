//! What `dynid payload` writes into `--out`: `payload.json` (the estimate, σ, scales, fit),
//! `payload.params.toml` (the last link's `[[link]]` with the payload added, to paste over the
//! last link of the params file), `loaded.params.toml` (the whole file so), `payload.urdf` (the
//! arm's URDF with the payload as a fixed link, when the arm came from one) and `report.md`.
//! Every file goes through a temporary file and a rename.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::params::InertialParams;
use crate::urdf::roundtrip::UrdfSource;

use super::PayloadEstimate;

/// The arm's parameters with the payload added to the last link.
pub fn loaded_params(arm: &InertialParams, est: &PayloadEstimate) -> InertialParams {
    let mut p = arm.full_vector();
    let n = p.len();
    for (a, b) in p[n - 10..].iter_mut().zip(&est.params) {
        *a += b;
    }
    let mut out = InertialParams::from_full_vector(&p, arm.effects.clone());
    for (o, a) in out.links.iter_mut().zip(&arm.links) {
        o.name = a.name.clone();
    }
    out
}

fn write(dir: &Path, name: &str, text: &str, files: &mut Vec<PathBuf>) -> Result<(), String> {
    let path = dir.join(name);
    crate::io::atomic_write(&path, |w| w.write_all(text.as_bytes()))
        .map_err(|e| format!("writing {}: {e}", path.display()))?;
    files.push(path);
    Ok(())
}

/// Writes every output into `dir` (created when missing); returns the files written.
pub fn write_all(
    dir: &Path,
    est: &PayloadEstimate,
    arm: &InertialParams,
    urdf: Option<&UrdfSource>,
    command: &str,
) -> Result<Vec<PathBuf>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    let mut files = Vec::new();
    let json = serde_json::to_string_pretty(est).map_err(|e| e.to_string())?;
    write(dir, "payload.json", &(json + "\n"), &mut files)?;

    let loaded = loaded_params(arm, est);
    let header = [
        format!("The arm with the payload on its last link: {command}"),
        format!(
            "payload: {:.6} kg at [{:.6}, {:.6}, {:.6}] m in the last link's frame",
            est.mass, est.com[0], est.com[1], est.com[2]
        ),
    ];
    let whole = loaded.to_toml(&header);
    write(dir, "loaded.params.toml", &whole, &mut files)?;
    let last = whole.rfind("[[link]]").unwrap_or(0);
    let tail = &whole[last..];
    let snippet_end = tail.find("\n[effects]").unwrap_or(tail.len());
    let snippet = format!(
        "# The last link with the payload ({:.6} kg) added: replace the last [[link]] of the params file with this.\n# {command}\n{}",
        est.mass,
        tail[..snippet_end].trim_end()
    ) + "\n";
    write(dir, "payload.params.toml", &snippet, &mut files)?;

    if let Some(src) = urdf {
        let origin = src.path.display().to_string();
        let text = std::fs::read_to_string(&src.path).map_err(|e| format!("{origin}: {e}"))?;
        let out = crate::urdf::attach::attach_body(
            &text,
            &origin,
            &src.opts,
            "payload",
            est.mass,
            est.com,
            est.inertia,
        )
        .map_err(|e| e.to_string())?;
        write(dir, "payload.urdf", &out, &mut files)?;
    }
    write(dir, "report.md", &report(est, command), &mut files)?;
    Ok(files)
}

/// `report.md`: the estimate with σ, the drive gains, the fit before and after, the warnings.
pub fn report(est: &PayloadEstimate, command: &str) -> String {
    let mut s = String::from("# Payload identification\n\n");
    let _ = writeln!(s, "`{command}`\n");
    let _ = writeln!(
        s,
        "In the last link's frame; ± is one σ (from the residuals, widened by their correlation time).\n"
    );
    s.push_str("| quantity | value | σ |\n|---|---|---|\n");
    let mass_sigma = if est.mass_known {
        "given".to_string()
    } else {
        format!("{:.3e}", est.sigma.mass)
    };
    let _ = writeln!(s, "| mass (kg) | {:.6} | {mass_sigma} |", est.mass);
    for (i, a) in ["x", "y", "z"].iter().enumerate() {
        let _ = writeln!(
            s,
            "| com {a} (mm) | {:.2} | {:.2} |",
            1e3 * est.com[i],
            1e3 * est.sigma.com[i]
        );
    }
    for (i, a) in ["xx", "xy", "xz", "yy", "yz", "zz"].iter().enumerate() {
        let _ = writeln!(
            s,
            "| I{a} about the COM (kg·m²) | {:.4e} | {:.2e} |",
            est.inertia[i], est.sigma.inertia[i]
        );
    }
    if est.projected {
        s.push_str("\nThe least-squares estimate was not a physical body and was pulled into the physical set.\n");
    }
    if let (Some(k), Some(ks)) = (&est.torque_scale, &est.torque_scale_sigma) {
        s.push_str("\n## Drive gains\n\nThe factor by which the data's torque must be multiplied (`torque_scale`; pass it as `--torque-scale` to `identify` and `payload`).\n\n| joint | scale | σ | calibrated |\n|---|---|---|---|\n");
        for j in 0..k.len() {
            let ok = !est.uncalibrated_joints.contains(&(j + 1));
            let _ = writeln!(
                s,
                "| {} | {:.5} | {:.2e} | {} |",
                j + 1,
                k[j],
                ks[j],
                if ok {
                    "yes"
                } else {
                    "no: the payload barely loads it"
                }
            );
        }
    }
    s.push_str("\n## Fit\n\nRMS of the torque the arm model (or the unloaded twin) leaves unexplained, per joint, before and after adding the payload.\n\n");
    for r in &est.runs {
        let _ = writeln!(s, "### {}\n", r.source);
        if let (Some(t), Some(a)) = (&r.twin, &r.alignment) {
            let _ = writeln!(
                s,
                "Unloaded twin `{t}`: shifted by {:+.4} s, covers {:.0} % of the run, RMS position difference {}.\n",
                a.shift_s,
                100.0 * a.coverage,
                a.rms_mismatch
                    .iter()
                    .map(|v| format!("{v:.2e}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        s.push_str("| joint | before | after |\n|---|---|---|\n");
        for j in 0..r.rms_before.len() {
            let _ = writeln!(
                s,
                "| {} | {:.4e} | {:.4e} |",
                j + 1,
                r.rms_before[j],
                r.rms_after[j]
            );
        }
        s.push('\n');
    }
    if !est.warnings.is_empty() {
        s.push_str("## Warnings\n\n");
        for w in &est.warnings {
            let _ = writeln!(s, "- {w}");
        }
    }
    s
}
