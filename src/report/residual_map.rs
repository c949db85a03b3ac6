//! The residual maps in the report ([`crate::identify::residual_map`]): `report.json`'s
//! `residual_maps` and `residual_maps_info` ([`json()`]), one small-multiples SVG per joint
//! ([`plot`]) and the `report.md` section that links them ([`section`]).

use std::fmt::Write as _;

use plotters::prelude::*;
use serde_json::{json, Value};

use crate::identify::residual_map::{ResidualMap, Variable};
use crate::identify::Outcome;

/// A map "departs from zero" in `report.md` when its χ² p-value is below this.
pub const DEPARTS_P: f64 = 0.01;

/// The SVG of joint `j`'s maps.
pub fn file_name(j: usize) -> String {
    format!("residual_map_joint{}.svg", j + 1)
}

/// `report.json`'s `residual_maps` (one entry per joint and variable, `joint` 1-based) and
/// `residual_maps_info` (what was binned and how the bands are made).
pub fn json(o: &Outcome) -> (Value, Value) {
    let r = &o.residual_maps;
    let maps: Vec<Value> = r
        .maps
        .iter()
        .map(|m| {
            json!({
                "joint": m.joint + 1, "variable": m.variable.name(), "unit": m.unit,
                "bins": m.bins, "rho": m.rho, "n_eff_factor": m.n_eff_factor, "chi2": m.chi2,
                "dof": m.dof, "p_value": m.p_value, "note": m.note,
            })
        })
        .collect();
    let info = json!({
        "residual": "tau measured - tau predicted by the final (after) model fitted without the sample's time block (held out), training files, the prediction of the errors above: the residual whose per-block errors the effect search and the guard compare",
        "every": r.every,
        "samples": r.samples,
        "bins": "12 equal-count bins of the variable (one per file for run); lo/hi/centre: min/max/mean of the variable in the bin",
        "band": "95 % band of the bin mean: mean +- t(n_eff - 1) * std / sqrt(n_eff), n_eff = n^2 / sum_ik rho^|t_i - t_k| (AR(1) with rho the lag-1 autocorrelation of the residual about the bin means; n * n_eff_factor for a contiguous bin), within [2, n]",
        "test": "chi2 = sum over bins of (mean / (std / sqrt(n_eff)))^2, p_value = P(chi2_dof >= chi2): small when the bin means depart from zero beyond their bands. A diagnostic of the final model on held-out training data; the effect search tests held-out gains over the same time blocks, not these bins",
    });
    (Value::Array(maps), info)
}

/// The maps of joint `j` (0-based), in [`Variable::ALL`] order.
fn joint_maps(o: &Outcome, j: usize) -> Vec<&ResidualMap> {
    o.residual_maps
        .maps
        .iter()
        .filter(|m| m.joint == j)
        .collect()
}

/// The `report.md` section: how to read the maps, which depart from zero, and the plots.
pub fn section(m: &mut String, o: &Outcome) {
    let r = &o.residual_maps;
    if r.maps.is_empty() {
        return;
    }
    let _ = writeln!(m, "\n## Residual maps\n");
    let _ = writeln!(
        m,
        "The final model's held-out torque residual (measured − predicted by the fit without the sample's time block) on the training data ({} samples{}) binned per joint against q, dq/dt (signed), d2q/dt2, time since the start of its file, the file (run) and the joint's own predicted torque: each dot is a bin's mean residual, the shaded band its 95 % confidence interval (widened for the residual's autocorrelation), so a run of dots whose band stays off the zero line is torque the model does not carry to data it was not fitted on, as a function of that variable. It is the residual the effect search compared block by block (above); the bins themselves are a diagnostic, not the search's test. Tables in `report.json` (`residual_maps`).\n",
        r.samples,
        if r.every > 1 {
            format!(", one in every {} used samples", r.every)
        } else {
            String::new()
        }
    );
    let _ = writeln!(
        m,
        "| joint | maps whose means depart from zero (χ² p < {DEPARTS_P}) |\n|---|---|"
    );
    for j in 0..o.dof {
        let off = departing(o, j);
        let _ = writeln!(
            m,
            "| {} | {} |",
            j + 1,
            if off.is_empty() {
                "none".to_string()
            } else {
                off.join(", ")
            }
        );
    }
    let _ = writeln!(m);
    for j in 0..o.dof {
        let f = file_name(j);
        let _ = writeln!(m, "![{f}]({f})\n");
    }
}

/// Joint `j`'s maps whose bin means depart from zero (p < [`DEPARTS_P`]), as `name (p = …)`.
pub fn departing(o: &Outcome, j: usize) -> Vec<String> {
    joint_maps(o, j)
        .iter()
        .filter(|m| m.p_value < DEPARTS_P)
        .map(|m| format!("{} (p = {:.1e})", label(m.variable, j), m.p_value))
        .collect()
}

/// Joint `j`'s mean held-out residual per training file with its 95 % band (the run map's bins),
/// and the torque's unit (the predicted-torque map's).
pub fn run_means(o: &Outcome, j: usize) -> (Vec<(f64, f64, f64)>, String) {
    let maps = joint_maps(o, j);
    let unit = maps
        .iter()
        .find(|m| m.variable == Variable::Torque)
        .map_or(String::new(), |m| m.unit.clone());
    let means = maps
        .iter()
        .filter(|m| m.variable == Variable::Run)
        .flat_map(|m| m.bins.iter().map(|b| (b.mean, b.ci95_lo, b.ci95_hi)))
        .collect();
    (means, unit)
}

/// The variable's plain-ASCII name for joint `j` (common SVG fonts lose combining dots).
fn label(v: Variable, j: usize) -> String {
    let j = j + 1;
    match v {
        Variable::Position => format!("q{j}"),
        Variable::Velocity => format!("dq{j}/dt"),
        Variable::Acceleration => format!("d2q{j}/dt2"),
        Variable::Time => "time since start".into(),
        Variable::Run => "run".into(),
        Variable::Torque => format!("tau_hat{j}"),
    }
}

/// Joint `j`'s maps as a 3 × 2 grid: per map the bin means (dots, joined), their 95 % band
/// (shaded; bars for the runs), the zero line.
pub fn plot(o: &Outcome, j: usize) -> Result<String, String> {
    let maps = joint_maps(o, j);
    let torque_unit = maps.first().map_or("N·m", |m| {
        if m.variable.unit(true) == m.unit {
            "N"
        } else {
            "N·m"
        }
    });
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1200, 720)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let root = root
            .titled(
                &format!(
                    "joint {}: final model's held-out residual on the training data, binned (mean and 95 % band)",
                    j + 1
                ),
                ("sans-serif", 20),
            )
            .map_err(|e| e.to_string())?;
        for (area, map) in root.split_evenly((2, 3)).iter().zip(&maps) {
            panel(area, map, j, torque_unit)?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}

/// One map's panel.
fn panel(
    area: &DrawingArea<SVGBackend, plotters::coord::Shift>,
    map: &ResidualMap,
    j: usize,
    torque_unit: &str,
) -> Result<(), String> {
    let finite = |v: f64| v.is_finite().then_some(v);
    let xs = map
        .bins
        .iter()
        .flat_map(|b| [b.lo, b.hi])
        .filter_map(finite);
    let ys = map
        .bins
        .iter()
        .flat_map(|b| [b.ci95_lo, b.ci95_hi, b.mean, 0.0])
        .filter_map(finite);
    let range = |it: &mut dyn Iterator<Item = f64>| {
        let (lo, hi) = it.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
        if lo.is_finite() && hi > lo {
            let pad = 0.05 * (hi - lo);
            (lo - pad, hi + pad)
        } else if lo.is_finite() {
            (lo - 1.0, lo + 1.0)
        } else {
            (-1.0, 1.0)
        }
    };
    let (x0, x1) = range(&mut xs.into_iter());
    let (y0, y1) = range(&mut ys.into_iter());
    let caption = format!(
        "{}: chi2/dof {:.1}/{}, p {:.1e}",
        label(map.variable, j),
        map.chi2,
        map.dof,
        map.p_value
    );
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 15))
        .margin(8)
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_labels(5)
        .y_labels(5)
        .x_desc(format!("{} ({})", label(map.variable, j), map.unit))
        .y_desc(format!("residual ({torque_unit})"))
        .draw()
        .map_err(|e| e.to_string())?;
    let blue = RGBColor(40, 90, 200);
    let banded: Vec<_> = map
        .bins
        .iter()
        .filter(|b| b.ci95_lo.is_finite() && b.ci95_hi.is_finite())
        .collect();
    if map.variable == Variable::Run || banded.len() == 1 {
        chart
            .draw_series(banded.iter().map(|b| {
                PathElement::new(
                    vec![(b.centre, b.ci95_lo), (b.centre, b.ci95_hi)],
                    blue.mix(0.5).stroke_width(6),
                )
            }))
            .map_err(|e| e.to_string())?;
    } else if banded.len() > 1 {
        let mut band: Vec<(f64, f64)> = banded.iter().map(|b| (b.centre, b.ci95_hi)).collect();
        band.extend(banded.iter().rev().map(|b| (b.centre, b.ci95_lo)));
        chart
            .draw_series(std::iter::once(Polygon::new(band, blue.mix(0.25).filled())))
            .map_err(|e| e.to_string())?;
    }
    chart
        .draw_series(LineSeries::new(
            [(x0, 0.0), (x1, 0.0)],
            BLACK.stroke_width(1),
        ))
        .map_err(|e| e.to_string())?;
    let means = map.bins.iter().filter(|b| b.mean.is_finite());
    if map.variable != Variable::Run {
        chart
            .draw_series(LineSeries::new(
                means.clone().map(|b| (b.centre, b.mean)),
                blue.stroke_width(1),
            ))
            .map_err(|e| e.to_string())?;
    }
    chart
        .draw_series(means.map(|b| Circle::new((b.centre, b.mean), 3, blue.filled())))
        .map_err(|e| e.to_string())?;
    Ok(())
}
