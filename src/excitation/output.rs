//! The files of a design (`dynid excite --out DIR`), each written atomically (temporary file,
//! then rename): `trajectory.csv` (`t,q1..qn,dq1..dqn,ddq1..ddqn` at the design's rate, both
//! ends included), `excitation.json` (family, coefficients, limits, conditioning, per-joint use of
//! each limit), `report.md` and its figures (`q.svg`, `dq.svg`, `ddq.svg`: each joint's signal
//! over its limit, so ±1 is the limit; `singular_values.svg`).

use std::path::Path;

use plotters::prelude::*;
use serde_json::json;

use super::design::{Design, DesignConfig};
use super::limits::Limits;
use super::objective::Grid;
use crate::io::{atomic_write, WriteError};

/// The CSV header for `dof` joints.
pub fn csv_header(dof: usize) -> String {
    let mut cols = vec!["t".to_string()];
    for p in ["q", "dq", "ddq"] {
        cols.extend((1..=dof).map(|j| format!("{p}{j}")));
    }
    cols.join(",")
}

/// Writes `trajectory.csv` for `g` (exact decimal round-trip of every value).
pub fn write_csv(path: &Path, g: &Grid, dof: usize) -> Result<(), WriteError> {
    atomic_write(path, |w| {
        writeln!(w, "{}", csv_header(dof))?;
        for k in 0..g.t.len() {
            write!(w, "{}", g.t[k])?;
            for v in [&g.q, &g.dq, &g.ddq] {
                for j in 0..dof {
                    write!(w, ",{}", v[k * dof + j])?;
                }
            }
            writeln!(w)?;
        }
        Ok(())
    })
}

/// The JSON document describing a design.
pub fn json(arm: &str, d: &Design, limits: &Limits, cfg: &DesignConfig) -> serde_json::Value {
    json!({
        "arm": arm,
        "family": d.excitation,
        "period": cfg.period,
        "harmonics": cfg.harmonics,
        "rate": cfg.rate,
        "objective": cfg.objective,
        "seed": cfg.seed,
        "columns": d.columns,
        "dropped_columns": d.dropped,
        "cond": d.conditioning.cond,
        "logdet": d.conditioning.logdet,
        "singular_values": d.conditioning.singular_values,
        "limits": limits,
        "peak_use": d.check.joints,
        "check_grid_hz": d.check.grid_hz,
        "tool_z_min": d.check.tool_z_min,
        "feasible": d.check.violations.is_empty(),
        "generations": d.generations,
        "evaluations": d.evaluations,
        "stopped_by": d.stopped_by,
        "seconds": d.seconds,
        "trajectory": d.excitation.spec(),
    })
}

fn fig_err(name: &str, e: impl std::fmt::Display) -> std::io::Error {
    std::io::Error::other(format!("figure {name}: {e}"))
}

/// Each joint's signal over its limit against time (±1 = the limit).
fn limits_svg(title: &str, t: &[f64], series: &[Vec<f64>]) -> Result<String, String> {
    let mut s = String::new();
    {
        let root = SVGBackend::with_string(&mut s, (900, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let t1 = t.last().copied().unwrap_or(1.0).max(1e-9);
        let mut c = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .build_cartesian_2d(0.0..t1, -1.1..1.1)
            .map_err(|e| e.to_string())?;
        c.configure_mesh()
            .x_desc("t [s]")
            .y_desc("fraction of limit")
            .draw()
            .map_err(|e| e.to_string())?;
        for y in [-1.0, 1.0] {
            c.draw_series(LineSeries::new(
                vec![(0.0, y), (t1, y)],
                BLACK.stroke_width(1),
            ))
            .map_err(|e| e.to_string())?;
        }
        for (j, v) in series.iter().enumerate() {
            let color = Palette99::pick(j).to_rgba();
            // at most ~2000 points per line keep the SVG small
            let step = (t.len() / 2000).max(1);
            c.draw_series(LineSeries::new(
                t.iter().zip(v).step_by(step).map(|(&a, &b)| (a, b)),
                color.stroke_width(2),
            ))
            .map_err(|e| e.to_string())?
            .label(format!("joint {}", j + 1))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color));
        }
        c.configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(s)
}

/// Singular values of the observation matrix (log10), largest first.
fn singular_svg(sv: &[f64]) -> Result<String, String> {
    let mut s = String::new();
    {
        let root = SVGBackend::with_string(&mut s, (900, 360)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let logs: Vec<f64> = sv.iter().map(|v| v.max(1e-300).log10()).collect();
        let lo = logs.iter().copied().fold(f64::INFINITY, f64::min).floor();
        let hi = logs
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max)
            .ceil();
        let (lo, hi) = if lo.is_finite() && hi > lo {
            (lo, hi)
        } else {
            (0.0, 1.0)
        };
        let mut c = ChartBuilder::on(&root)
            .caption(
                "singular values of the observation matrix",
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .build_cartesian_2d(0.0..(sv.len().max(1) as f64 + 1.0), lo..hi)
            .map_err(|e| e.to_string())?;
        c.configure_mesh()
            .x_desc("index")
            .y_desc("log10 σ")
            .draw()
            .map_err(|e| e.to_string())?;
        c.draw_series(
            logs.iter()
                .enumerate()
                .map(|(i, &y)| Circle::new(((i + 1) as f64, y), 4, BLUE.filled())),
        )
        .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(s)
}

/// Writes every file of a design into `dir` (created if missing).
pub fn write_all(
    dir: &Path,
    arm: &str,
    d: &Design,
    limits: &Limits,
    cfg: &DesignConfig,
) -> Result<(), WriteError> {
    let dof = limits.dof();
    let g = Grid::new(d.excitation.as_motion(), cfg.rate);
    write_csv(&dir.join("trajectory.csv"), &g, dof)?;
    let doc = json(arm, d, limits, cfg);
    let text = serde_json::to_string_pretty(&doc).unwrap_or_default();
    atomic_write(&dir.join("excitation.json"), |w| writeln!(w, "{text}"))?;

    let col =
        |v: &[f64], j: usize| -> Vec<f64> { v.iter().skip(j).step_by(dof).copied().collect() };
    let mut figs: Vec<(String, String)> = Vec::new();
    let mut err = None;
    for (name, title, sig) in [
        (
            "q.svg",
            "q: position over its limit (q − q0 over the room to q_max or q_min)",
            0,
        ),
        ("dq.svg", "dq: velocity over dq_max", 1),
        ("ddq.svg", "ddq: acceleration over ddq_max", 2),
    ] {
        let series: Vec<Vec<f64>> = (0..dof)
            .map(|j| {
                let l = &limits.joints[j];
                let q0 = limits.q0[j];
                match sig {
                    0 => col(&g.q, j)
                        .iter()
                        .map(|q| {
                            let d = q - q0;
                            if d >= 0.0 {
                                d / (l.q_max - q0)
                            } else {
                                d / (q0 - l.q_min)
                            }
                        })
                        .collect(),
                    1 => col(&g.dq, j).iter().map(|v| v / l.dq_max).collect(),
                    _ => col(&g.ddq, j).iter().map(|v| v / l.ddq_max).collect(),
                }
            })
            .collect();
        match limits_svg(title, &g.t, &series) {
            Ok(s) => figs.push((name.into(), s)),
            Err(e) => err = Some(fig_err(name, e)),
        }
    }
    match singular_svg(&d.conditioning.singular_values) {
        Ok(s) => figs.push(("singular_values.svg".into(), s)),
        Err(e) => err = Some(fig_err("singular_values.svg", e)),
    }
    if let Some(cause) = err {
        return Err(WriteError {
            path: dir.to_path_buf(),
            cause,
        });
    }
    for (name, svg) in &figs {
        atomic_write(&dir.join(name), |w| w.write_all(svg.as_bytes()))?;
    }
    let md = report(arm, d, limits, cfg);
    atomic_write(&dir.join("report.md"), |w| w.write_all(md.as_bytes()))
}

/// `report.md`: the settings, the conditioning, the per-joint use of each limit, the figures.
pub fn report(arm: &str, d: &Design, limits: &Limits, cfg: &DesignConfig) -> String {
    let mut s = String::new();
    let family = match cfg.family {
        super::design::Family::Fourier => {
            format!("Fourier + quintic, {} harmonics", cfg.harmonics)
        }
        super::design::Family::Logistic => "Logistic (all joints at once)".into(),
    };
    s.push_str(&format!("# Excitation for `{arm}`\n\n"));
    s.push_str(&format!(
        "{family}, period {} s, sampled at {} Hz; starts and ends at rest at q0.\n\n",
        cfg.period, cfg.rate
    ));
    s.push_str(&format!(
        "- condition number of the observation matrix: **{:.2}** (log det(WᵀW/rows) = {:.3})\n",
        d.conditioning.cond, d.conditioning.logdet
    ));
    s.push_str(&format!(
        "- columns ({}): {}\n",
        d.columns.len(),
        d.columns.join(", ")
    ));
    if !d.dropped.is_empty() {
        let dr: Vec<String> = d
            .dropped
            .iter()
            .map(|(t, w)| format!("{t} (= {})", w.join(" + ")))
            .collect();
        s.push_str(&format!(
            "- left out (the same column as base parameters for every motion): {}\n",
            dr.join(", ")
        ));
    }
    s.push_str(&format!(
        "- search: CMA-ES, seed {}, {} generations, {} evaluations, stopped by {}, {:.1} s\n",
        cfg.seed, d.generations, d.evaluations, d.stopped_by, d.seconds
    ));
    s.push_str(&format!(
        "- limits checked on a {} Hz grid, each peak raised by the most it can grow between samples: all within\n\n",
        d.check.grid_hz
    ));
    s.push_str("| joint | q0 | q range used | q_min … q_max | peak dq / dq_max | peak ddq / ddq_max | peak τ / τ_max |\n");
    s.push_str("|---|---|---|---|---|---|---|\n");
    for (j, u) in d.check.joints.iter().enumerate() {
        let l = &limits.joints[j];
        let tau = match (u.tau, u.tau_peak) {
            (Some(f), Some(p)) => format!(
                "{p:.2} / {:.2} ({:.0} %)",
                l.tau_max.unwrap_or(0.0),
                100.0 * f
            ),
            (None, Some(p)) => format!("{p:.2} (no limit)"),
            _ => "—".into(),
        };
        s.push_str(&format!(
            "| {} {} | {:.4} | {:.4} … {:.4} | {:.4} … {:.4} | {:.3} / {} ({:.0} %) | {:.3} / {} ({:.0} %) | {tau} |\n",
            j + 1,
            u.name,
            limits.q0[j],
            u.q_min_reached,
            u.q_max_reached,
            l.q_min,
            l.q_max,
            u.dq * l.dq_max,
            l.dq_max,
            100.0 * u.dq,
            u.ddq * l.ddq_max,
            l.ddq_max,
            100.0 * u.ddq,
        ));
    }
    if let Some(z) = d.check.tool_z_min {
        s.push_str(&format!("\nLowest tool height: {z:.4} m.\n"));
    }
    if !limits.notes.is_empty() {
        s.push_str("\nLimits:\n\n");
        for n in &limits.notes {
            s.push_str(&format!("- {n}\n"));
        }
    }
    s.push_str("\n![q](q.svg)\n\n![dq](dq.svg)\n\n![ddq](ddq.svg)\n\n![singular values](singular_values.svg)\n");
    s
}
