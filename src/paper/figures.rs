//! SVG figures matching the paper's Figs 9–17, plus the noise study (plotters, SVG backend; text
//! is emitted as SVG `<text>`, so no font files are needed).

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::noise::Differentiator;
use super::{PaperError, PaperResults, Traces};

type Series = (String, Vec<(f64, f64)>, RGBColor);

const COLORS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(90, 90, 90),
];

fn fig_err(name: &str, e: impl std::fmt::Display) -> PaperError {
    PaperError::Figure {
        name: name.into(),
        msg: e.to_string(),
    }
}

fn bounds(series: &[Series]) -> ((f64, f64), (f64, f64)) {
    let pts = series
        .iter()
        .flat_map(|s| s.1.iter())
        .filter(|p| p.0.is_finite() && p.1.is_finite());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in pts {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if x0 > x1 {
        return ((0.0, 1.0), (0.0, 1.0));
    }
    if x1 - x0 < 1e-12 {
        x1 = x0 + 1.0;
    }
    let pad = ((y1 - y0) * 0.05).max(1e-9);
    ((x0, x1), (y0 - pad, y1 + pad))
}

fn chart(
    area: &DrawingArea<SVGBackend, Shift>,
    title: &str,
    xl: &str,
    yl: &str,
    series: &[Series],
    points: bool,
) -> Result<(), String> {
    let ((x0, x1), (y0, y1)) = bounds(series);
    let mut c = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(64)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| e.to_string())?;
    c.configure_mesh()
        .x_desc(xl)
        .y_desc(yl)
        .draw()
        .map_err(|e| e.to_string())?;
    for (name, pts, color) in series {
        let color = *color;
        c.draw_series(LineSeries::new(pts.iter().copied(), color.stroke_width(2)))
            .map_err(|e| e.to_string())?
            .label(name.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
        if points {
            c.draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))
                .map_err(|e| e.to_string())?;
        }
    }
    c.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| e.to_string())?;
    Ok(())
}

/// Renders `panels` stacked vertically into an SVG string.
fn render(panels: &[(String, &str, &str, Vec<Series>, bool)]) -> Result<String, String> {
    let mut s = String::new();
    {
        let h = 360 * panels.len() as u32;
        let root = SVGBackend::with_string(&mut s, (900, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let areas = root.split_evenly((panels.len(), 1));
        for (area, (title, xl, yl, series, points)) in areas.iter().zip(panels) {
            chart(area, title, xl, yl, series, *points)?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(s)
}

fn save(
    dir: &Path,
    name: &str,
    panels: &[(String, &str, &str, Vec<Series>, bool)],
    out: &mut Vec<String>,
) -> Result<(), PaperError> {
    let svg = render(panels).map_err(|e| fig_err(name, e))?;
    crate::io::atomic_write(&dir.join(name), |w| w.write_all(svg.as_bytes()))?;
    out.push(name.to_string());
    Ok(())
}

fn column(v: &[f64], dof: usize, j: usize) -> impl Iterator<Item = f64> + '_ {
    v.iter().skip(j).step_by(dof).copied()
}

/// Writes every figure; returns the file names.
pub fn write_all(dir: &Path, r: &PaperResults, tr: &Traces) -> Result<Vec<String>, PaperError> {
    let mut out = Vec::new();
    fig_ga_convergence(dir, r, &mut out)?;
    fig_logistic_excitation(dir, tr, &mut out)?;
    fig_tracking(dir, tr, &mut out)?;
    fig_theta(dir, r, &mut out)?;
    fig_fourier_excitation(dir, tr, &mut out)?;
    fig_validation(dir, tr, &mut out)?;
    fig_noise_study(dir, r, &mut out)?;
    Ok(out)
}

/// Fig. 9: the GA's convergence, Logistic and Fourier.
fn fig_ga_convergence(
    dir: &Path,
    r: &PaperResults,
    out: &mut Vec<String>,
) -> Result<(), PaperError> {
    let ga: Vec<(f64, f64)> =
        r.ga.history
            .iter()
            .enumerate()
            .map(|(g, &h)| (g as f64 + 1.0, h.log10()))
            .collect();
    let gf: Vec<(f64, f64)> = r
        .fourier
        .ga_history
        .iter()
        .enumerate()
        .map(|(g, &h)| (g as f64 + 1.0, h.log10()))
        .collect();
    save(
        dir,
        "fig09_ga_convergence.svg",
        &[(
            "GA: best H = cond(M) + cond(Q) (+ penalty) per generation".into(),
            "generation",
            "log10 H",
            vec![
                ("Logistic (eq. 17)".into(), ga, COLORS[0]),
                ("Fourier, cond(Φ)".into(), gf, COLORS[1]),
            ],
            false,
        )],
        out,
    )?;
    Ok(())
}

/// Fig. 10: the Logistic excitation of the two steps.
fn fig_logistic_excitation(
    dir: &Path,
    tr: &Traces,
    out: &mut Vec<String>,
) -> Result<(), PaperError> {
    let mut panels = Vec::new();
    for (s, (traj, joint)) in tr.step_trajectories.iter().zip([1usize, 0]).enumerate() {
        let Some(l) = traj.moving(joint) else {
            continue;
        };
        let n = 600;
        let pts = |k: usize| -> Vec<(f64, f64)> {
            (0..=n)
                .map(|i| {
                    let t = l.period * i as f64 / n as f64;
                    let v = l.eval(t);
                    (t, [v.0, v.1, v.2][k])
                })
                .collect()
        };
        panels.push((
            format!("step {}: joint {} (Logistic, eq. 14)", s + 1, joint + 1),
            "t (s)",
            "rad, rad/s, rad/s²",
            vec![
                ("q".into(), pts(0), COLORS[0]),
                ("dq".into(), pts(1), COLORS[1]),
                ("ddq".into(), pts(2), COLORS[2]),
            ],
            false,
        ));
    }
    save(dir, "fig10_logistic_excitation.svg", &panels, out)?;
    Ok(())
}

/// Figs. 11–12: tracking error per iteration, each step.
fn fig_tracking(dir: &Path, tr: &Traces, out: &mut Vec<String>) -> Result<(), PaperError> {
    for (s, name) in [
        (0usize, "fig11_tracking_step1.svg"),
        (1, "fig12_tracking_step2.svg"),
    ] {
        let mut panels = Vec::new();
        for j in [1usize - s, s] {
            let role = if j == 1 - s { "moving" } else { "held" };
            let series = tr
                .logs
                .iter()
                .take(3)
                .enumerate()
                .map(|(it, pair)| {
                    let log = &pair[s];
                    let e = log.tracking_error(j);
                    (
                        format!("iteration {}", it + 1),
                        log.t.iter().copied().zip(e).collect(),
                        COLORS[it],
                    )
                })
                .collect();
            panels.push((
                format!("step {}: tracking error of joint {} ({role})", s + 1, j + 1),
                "t (s)",
                "qd − q (rad)",
                series,
                false,
            ));
        }
        save(dir, name, &panels, out)?;
    }
    Ok(())
}

/// Figs. 13–14: θ̂ per iteration.
fn fig_theta(dir: &Path, r: &PaperResults, out: &mut Vec<String>) -> Result<(), PaperError> {
    for (s, name, cols) in [
        (1usize, "fig13_theta_step1.svg", [3usize, 4, 5]),
        (2, "fig14_theta_step2.svg", [0, 1, 2]),
    ] {
        let mut series: Vec<Series> = Vec::new();
        for (k, &c) in cols.iter().enumerate() {
            let pts = r
                .iterations
                .iter()
                .filter(|x| x.step == s)
                .map(|x| (x.iteration as f64, x.theta_hat[c]))
                .collect();
            series.push((
                format!("θ{} (true {})", c + 1, r.theta_true[c]),
                pts,
                COLORS[k],
            ));
        }
        save(
            dir,
            name,
            &[(
                format!("step {s}: identified parameters per iteration"),
                "iteration",
                "θ̂",
                series,
                true,
            )],
            out,
        )?;
    }
    Ok(())
}

/// Fig. 15: the Fourier excitation and its tracking.
fn fig_fourier_excitation(
    dir: &Path,
    tr: &Traces,
    out: &mut Vec<String>,
) -> Result<(), PaperError> {
    let fl = &tr.fourier_log;
    let fs: Vec<Series> = (0..fl.dof)
        .map(|j| {
            (
                format!("q{}", j + 1),
                fl.t.iter().copied().zip(column(&fl.q, fl.dof, j)).collect(),
                COLORS[j],
            )
        })
        .collect();
    save(
        dir,
        "fig15_fourier_excitation.svg",
        &[(
            "Fourier excitation (measured q, PD loop)".into(),
            "t (s)",
            "rad",
            fs,
            false,
        )],
        out,
    )?;
    Ok(())
}

/// Figs. 16–17: the validation torque and its prediction errors.
fn fig_validation(dir: &Path, tr: &Traces, out: &mut Vec<String>) -> Result<(), PaperError> {
    for (j, name) in [
        (0usize, "fig16_validation_joint1.svg"),
        (1, "fig17_validation_joint2.svg"),
    ] {
        let t = &tr.validation_t;
        let [m, l, f] = &tr.validation_tau;
        let series = vec![
            (
                "measured".into(),
                t.iter().copied().zip(column(m, 2, j)).collect(),
                COLORS[5],
            ),
            (
                "Logistic θ̂".into(),
                t.iter().copied().zip(column(l, 2, j)).collect(),
                COLORS[0],
            ),
            (
                "Fourier θ̂".into(),
                t.iter().copied().zip(column(f, 2, j)).collect(),
                COLORS[1],
            ),
        ];
        let err = vec![
            (
                "Logistic − measured".into(),
                t.iter()
                    .copied()
                    .zip(column(l, 2, j).zip(column(m, 2, j)).map(|(a, b)| a - b))
                    .collect(),
                COLORS[0],
            ),
            (
                "Fourier − measured".into(),
                t.iter()
                    .copied()
                    .zip(column(f, 2, j).zip(column(m, 2, j)).map(|(a, b)| a - b))
                    .collect(),
                COLORS[1],
            ),
        ];
        save(
            dir,
            name,
            &[
                (
                    format!(
                        "validation q1 = sin t, q2 = sin(−t): torque of joint {}",
                        j + 1
                    ),
                    "t (s)",
                    "N·m",
                    series,
                    false,
                ),
                ("prediction error".into(), "t (s)", "N·m", err, false),
            ],
            out,
        )?;
    }
    Ok(())
}

/// The noise study: error against encoder bits and torque noise.
fn fig_noise_study(dir: &Path, r: &PaperResults, out: &mut Vec<String>) -> Result<(), PaperError> {
    let nz = &r.noise;
    let quant: Vec<Series> = Differentiator::ALL
        .iter()
        .enumerate()
        .map(|(i, &e)| {
            let pts = nz
                .config
                .quant_bits
                .iter()
                .filter_map(|&b| {
                    b.and_then(|bits| {
                        nz.cell(Some(bits), 0.0, e)
                            .map(|c| (bits as f64, c.mean.log10()))
                    })
                })
                .collect();
            (e.label().to_string(), pts, COLORS[i])
        })
        .collect();
    let torque: Vec<Series> = Differentiator::ALL
        .iter()
        .enumerate()
        .map(|(i, &e)| {
            let pts = nz
                .config
                .torque_pct
                .iter()
                .filter_map(|&p| nz.cell(Some(16), p, e).map(|c| (p, c.mean.log10())))
                .collect();
            (e.label().to_string(), pts, COLORS[i])
        })
        .collect();
    save(
        dir,
        "noise_study.svg",
        &[
            (
                "encoder quantisation (no torque noise): mean max|θ̂ − θ|".into(),
                "encoder bits per revolution",
                "log10 error",
                quant,
                true,
            ),
            (
                "torque noise (16-bit encoder): mean max|θ̂ − θ|".into(),
                "torque noise (% of RMS)",
                "log10 error",
                torque,
                true,
            ),
        ],
        out,
    )?;
    Ok(())
}
