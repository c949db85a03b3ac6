//! The README benchmark table and plot: `dynid bench` numbers next to Pinocchio's, measured in
//! the same run (`scripts/bench_table.sh`).
//!
//! Pinocchio's harness (`benches/peers/pinocchio/run.sh`: Pinocchio on the models, parameters and
//! input pool of `dynid bench`, checked against dynid's torques before timing) prints
//! machine-readable lines `pinocchio,<model>,<algo>,<median_ns>`; [`PinocchioTimes::parse`] reads
//! them from its whole output. Kernel ↔ algorithm: `regressor` and `base_regressor` ↔ `regressor`
//! (Pinocchio has no base regressor; the targets compare against its full one), `mass_matrix` ↔
//! `crba`, `bias` ↔ `nle`, `gravity` ↔ `gravity` (`computeGeneralizedGravity`),
//! `inverse_dynamics` ↔ `rnea`.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use plotters::prelude::*;

use super::{Kernel, KernelTiming, Report};

/// Pinocchio's median ns per call by `(model, algo)`.
#[derive(Debug, Clone, Default)]
pub struct PinocchioTimes(BTreeMap<(String, String), f64>);

impl PinocchioTimes {
    /// Reads every `pinocchio,<model>,<algo>,<ns>` line of the harness output; other lines
    /// (headers, the human-readable table, `pinocchio_prebuilt` lines) are ignored.
    pub fn parse(text: &str) -> Self {
        let mut map = BTreeMap::new();
        for line in text.lines() {
            let f: Vec<&str> = line.trim().split(',').collect();
            if let [tag, model, algo, ns] = f[..] {
                if tag == "pinocchio" {
                    if let Ok(ns) = ns.trim().parse::<f64>() {
                        map.insert((model.to_string(), algo.to_string()), ns);
                    }
                }
            }
        }
        PinocchioTimes(map)
    }

    /// True when no timing line was found.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Pinocchio's time for `kernel` of `arm`, if the harness measures a counterpart.
    pub fn get(&self, arm: &str, kernel: &str) -> Option<f64> {
        let algo = pinocchio_algo(kernel)?;
        self.0.get(&(arm.to_string(), algo.to_string())).copied()
    }
}

/// The Pinocchio algorithm compared with `kernel`.
pub fn pinocchio_algo(kernel: &str) -> Option<&'static str> {
    match kernel {
        "regressor" | "base_regressor" => Some("regressor"),
        "mass_matrix" => Some("crba"),
        "bias" => Some("nle"),
        "gravity" => Some("gravity"),
        "inverse_dynamics" => Some("rnea"),
        "forward_dynamics" => Some("aba"),
        "inverse_mass_matrix" => Some("minverse"),
        "inverse_dynamics_derivatives" => Some("rnea_derivatives"),
        "forward_dynamics_derivatives" => Some("aba_derivatives"),
        _ => None,
    }
}

/// A performance target of issue 7 / DESIGN.md.
#[derive(Debug, Clone, Copy)]
pub enum Target {
    /// Pinocchio's `algo` / our `kernel` on `arm` must be at least `ratio`.
    VsPinocchio {
        arm: &'static str,
        kernel: &'static str,
        ratio: f64,
    },
    /// Our `kernel` on `arm` at most `ns` nanoseconds per call (the "2× SymPyBotics" goal).
    Ns {
        arm: &'static str,
        kernel: &'static str,
        ns: f64,
    },
    /// Every generated kernel at least `ratio` times faster than the reference.
    VsReference { ratio: f64 },
    /// The 1e6-sample identification within `seconds`.
    IdentifySeconds { seconds: f64 },
}

/// The targets, in the order of the issue.
pub const TARGETS: [Target; 13] = [
    Target::VsPinocchio {
        arm: "puma560",
        kernel: "base_regressor",
        ratio: 7.5,
    },
    Target::VsPinocchio {
        arm: "panda",
        kernel: "base_regressor",
        ratio: 7.0,
    },
    Target::VsPinocchio {
        arm: "planar2",
        kernel: "base_regressor",
        ratio: 11.0,
    },
    Target::VsPinocchio {
        arm: "puma560",
        kernel: "regressor",
        ratio: 5.8,
    },
    Target::VsPinocchio {
        arm: "puma560",
        kernel: "mass_matrix",
        ratio: 3.7,
    },
    Target::VsPinocchio {
        arm: "panda",
        kernel: "mass_matrix",
        ratio: 2.8,
    },
    Target::VsPinocchio {
        arm: "puma560",
        kernel: "inverse_dynamics",
        ratio: 6.3,
    },
    Target::VsReference { ratio: 5.0 },
    Target::Ns {
        arm: "puma560",
        kernel: "base_regressor",
        ns: 80.0,
    },
    Target::Ns {
        arm: "puma560",
        kernel: "mass_matrix",
        ns: 45.0,
    },
    Target::Ns {
        arm: "puma560",
        kernel: "inverse_dynamics",
        ns: 50.0,
    },
    Target::Ns {
        arm: "planar2",
        kernel: "base_regressor",
        ns: 20.0,
    },
    Target::IdentifySeconds { seconds: 1.0 },
];

fn find<'a>(report: &'a Report, arm: &str, kernel: &str) -> Option<&'a KernelTiming> {
    report
        .kernels
        .iter()
        .find(|k| k.arm == arm && k.kernel == kernel)
}

/// `(description, measured, met)` for each target that this report can evaluate.
pub fn evaluate(report: &Report, pin: &PinocchioTimes) -> Vec<(String, String, bool)> {
    let mut rows = Vec::new();
    for t in TARGETS {
        match t {
            Target::VsPinocchio { arm, kernel, ratio } => {
                let (Some(k), Some(p)) = (find(report, arm, kernel), pin.get(arm, kernel)) else {
                    continue;
                };
                let algo = pinocchio_algo(kernel).unwrap_or("?");
                let r = p / k.generated_ns;
                rows.push((
                    format!("{arm}: Pinocchio {algo} / ours {kernel} ≥ {ratio}"),
                    format!("{r:.2}"),
                    r >= ratio,
                ));
            }
            Target::Ns { arm, kernel, ns } => {
                let Some(k) = find(report, arm, kernel) else {
                    continue;
                };
                let g = k.generated_ns;
                rows.push((
                    format!("{arm}: {kernel} ≤ {ns} ns (one call)"),
                    format!("{g:.1} ns"),
                    g <= ns,
                ));
                let l = k.lanes_ns;
                rows.push((
                    format!("{arm}: {kernel} ≤ {ns} ns per sample, lane-batched"),
                    format!("{l:.1} ns"),
                    l <= ns,
                ));
            }
            Target::VsReference { ratio } => {
                let Some(worst) = report.kernels.iter().min_by(|a, b| {
                    (a.reference_ns / a.generated_ns).total_cmp(&(b.reference_ns / b.generated_ns))
                }) else {
                    continue;
                };
                let r = worst.reference_ns / worst.generated_ns;
                rows.push((
                    format!("every generated kernel ≥ {ratio}× the reference (one call)"),
                    format!("lowest {r:.1}× ({} {})", worst.arm, worst.kernel),
                    r >= ratio,
                ));
                if let Some(worst) = report.kernels.iter().min_by(|a, b| {
                    (a.reference_ns / a.lanes_ns).total_cmp(&(b.reference_ns / b.lanes_ns))
                }) {
                    let r = worst.reference_ns / worst.lanes_ns;
                    rows.push((
                        format!("every generated kernel ≥ {ratio}× the reference (lane-batched, per sample)"),
                        format!("lowest {r:.1}× ({} {})", worst.arm, worst.kernel),
                        r >= ratio,
                    ));
                }
            }
            Target::IdentifySeconds { seconds } => {
                let i = &report.identify;
                rows.push((
                    format!(
                        "{} samples {} identification ≤ {seconds} s",
                        i.samples, i.arm
                    ),
                    format!("{:.3} s, peak RSS {:.1} MB", i.seconds, i.peak_rss_mb),
                    i.seconds <= seconds,
                ));
            }
        }
    }
    rows
}

/// Context printed under the table (machine, load, command).
#[derive(Debug, Clone, Default)]
pub struct RunInfo {
    pub cpu: String,
    pub load: String,
    pub rustflags: String,
}

impl RunInfo {
    /// CPU model and load average from `/proc`, the target CPU this binary was built for.
    pub fn current() -> Self {
        let cpu = std::fs::read_to_string("/proc/cpuinfo")
            .ok()
            .and_then(|s| {
                s.lines()
                    .find(|l| l.starts_with("model name"))
                    .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
            })
            .unwrap_or_else(|| "unknown CPU".into());
        let load = std::fs::read_to_string("/proc/loadavg")
            .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
            .unwrap_or_default();
        let mut features = Vec::new();
        if cfg!(target_feature = "avx512f") {
            features.push("avx512f");
        }
        if cfg!(target_feature = "avx2") {
            features.push("avx2");
        }
        if cfg!(target_feature = "fma") {
            features.push("fma");
        }
        let rustflags = if features.is_empty() {
            "baseline x86-64 (SSE2)".into()
        } else {
            features.join("+")
        };
        RunInfo {
            cpu,
            load,
            rustflags,
        }
    }
}

fn ratio(num: Option<f64>, den: f64) -> String {
    num.map_or("—".into(), |n| format!("{:.1}×", n / den))
}

/// The README section: per arm × kernel, generated, reference and Pinocchio ns per call with
/// ratios and operation counts, then the targets.
pub fn markdown(report: &Report, pin: &PinocchioTimes, info: &RunInfo) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "## Benchmarks\n");
    let _ = writeln!(
        s,
        "ns per call, single thread, median; the same 1024-sample random input pool for every column \
         (q ~ U(−π, π), q̇ ~ U(−2, 2), q̈ ~ U(−5, 5)). *generated*: the kernels in `generated/` through \
         the `Model` trait; *reference*: the hand-written recursive Newton–Euler in `src/reference/`; \
         *Pinocchio*: Pinocchio 4.1 C++ (`-O3 -march=native`, header-only) on the same models, \
         parameters and inputs, checked against our torques, measured in the same run by \
         `benches/peers/pinocchio/run.sh` (base regressor vs its full regressor, M vs CRBA, bias vs \
         `nonLinearEffects`, gravity vs `computeGeneralizedGravity`, inverse dynamics vs RNEA). \
         Operation counts are the generator's (binary `*` `/` and `+` `−`). *lanes*: the same generated kernel batched over 4 samples per call \
         (`dynid::pack`, one AVX instruction per operation), ns per *sample*; *8 lanes*: over 8 samples per call \
         (`dynid::pack::wide`: {}), ns per sample, and *lanes / 8 lanes* the throughput gained by the wider form; *zeros skipped*: the same ratio for the forms that leave the \
         constant-zero outputs to the caller's buffer (`call_lanes_skip_zeros`, `call_lanes8_skip_zeros`: zero it once, then reuse it) — \
         at eight lanes a regressor's zeros cost about one 64-byte store each, a cycle, whatever the width.\n",
        crate::pack::wide::wide_form()
    );
    let _ = writeln!(s, "| arm | kernel | mul / add | generated | lanes (per sample) | 8 lanes (per sample) | lanes / 8 lanes | zeros skipped | reference | Pinocchio | reference / generated | Pinocchio / generated | Pinocchio / lanes |");
    let _ = writeln!(
        s,
        "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for k in &report.kernels {
        let ops = crate::arms::find(&k.arm)
            .and_then(|m| {
                m.op_counts()
                    .iter()
                    .find(|o| o.kernel == k.kernel)
                    .map(|o| format!("{} / {}", o.mul, o.add))
            })
            .unwrap_or_else(|| "—".into());
        let p = pin.get(&k.arm, k.kernel);
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.2}× | {:.2}× | {:.1} | {} | {:.1}× | {} | {} |",
            k.arm,
            k.kernel,
            ops,
            k.generated_ns,
            k.lanes_ns,
            k.lanes8_ns,
            k.lanes_ns / k.lanes8_ns,
            k.lanes_skip_ns / k.lanes8_skip_ns,
            k.reference_ns,
            p.map_or("—".into(), |v| format!("{v:.0}")),
            k.reference_ns / k.generated_ns,
            ratio(p, k.generated_ns),
            ratio(p, k.lanes_ns)
        );
    }
    let i = &report.identify;
    let _ = writeln!(
        s,
        "\nStreaming identification of a generated {}-sample {} log (trajectory, inverse dynamics, base \
         regressor, normal equations with a conditioning check; one thread): **{:.3} s**, peak RSS {:.1} MB.\n",
        i.samples, i.arm, i.seconds, i.peak_rss_mb
    );
    let rows = evaluate(report, pin);
    if !rows.is_empty() {
        let _ = writeln!(s, "| target | measured | met |\n|---|---|---|");
        for (what, got, ok) in rows {
            let _ = writeln!(
                s,
                "| {what} | {got} | {} |",
                if ok { "yes" } else { "**no**" }
            );
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(
        s,
        "Machine: {} ({}), load average at the start {}; dynid built for {}. \
         Regenerate with `scripts/bench_table.sh` (writes `docs/bench.md`, `docs/bench.svg`, `docs/bench.json`); \
         careful per-kernel numbers: `cargo bench`.\n\n![benchmark plot](bench.svg)",
        info.cpu,
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        info.load,
        info.rustflags
    );
    s
}

/// Grouped bar chart (log scale, headroom above the bars for the legend), one panel per arm:
/// generated, reference and Pinocchio ns per call for each kernel.
pub fn svg(report: &Report, pin: &PinocchioTimes) -> Result<String, String> {
    let mut arms: Vec<&str> = Vec::new();
    for k in &report.kernels {
        if !arms.contains(&k.arm.as_str()) {
            arms.push(&k.arm);
        }
    }
    let cols = arms.len().clamp(1, 2);
    let rows = arms.len().div_ceil(cols).max(1);
    let (w, h) = (560 * cols as u32, 380 * rows as u32);
    let mut buf = String::new();
    {
        let root = SVGBackend::with_string(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let panels = root.split_evenly((rows, cols));
        let series: [(&str, RGBColor); 4] = [
            ("generated", RGBColor(31, 119, 180)),
            ("lanes, per sample", RGBColor(148, 103, 189)),
            ("reference", RGBColor(255, 127, 14)),
            ("Pinocchio", RGBColor(44, 160, 44)),
        ];
        let short = ["Y", "Yb", "M", "bias", "g", "ID"];
        for (arm, area) in arms.iter().zip(panels.iter()) {
            let max = report
                .kernels
                .iter()
                .filter(|k| k.arm == *arm)
                .flat_map(|k| {
                    [
                        k.generated_ns,
                        k.reference_ns,
                        pin.get(arm, k.kernel).unwrap_or(0.0),
                    ]
                })
                .fold(10.0f64, f64::max);
            let mut chart = ChartBuilder::on(area)
                .caption(
                    format!("{arm}: ns per call (log scale)"),
                    ("sans-serif", 18),
                )
                .margin(10)
                .x_label_area_size(28)
                .y_label_area_size(48)
                .build_cartesian_2d(
                    0f64..Kernel::ALL.len() as f64,
                    (1f64..max * 20.0).log_scale(),
                )
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .disable_x_mesh()
                .x_labels(Kernel::ALL.len() * 2 + 1)
                .x_label_formatter(&|x| {
                    let i = x.floor() as usize;
                    if (x - i as f64 - 0.5).abs() < 0.01 && i < short.len() {
                        short[i].to_string()
                    } else {
                        String::new()
                    }
                })
                .y_desc("ns")
                .draw()
                .map_err(|e| e.to_string())?;
            for (si, (name, color)) in series.iter().enumerate() {
                let bars: Vec<Rectangle<(f64, f64)>> = Kernel::ALL
                    .iter()
                    .enumerate()
                    .filter_map(|(ki, kernel)| {
                        let k = find(report, arm, kernel.name())?;
                        let v = match si {
                            0 => Some(k.generated_ns),
                            1 => Some(k.lanes_ns),
                            2 => Some(k.reference_ns),
                            _ => pin.get(arm, kernel.name()),
                        }?;
                        let x0 = ki as f64 + 0.08 + 0.21 * si as f64;
                        Some(Rectangle::new(
                            [(x0, 1.0), (x0 + 0.19, v.max(1.0))],
                            color.filled(),
                        ))
                    })
                    .collect();
                chart
                    .draw_series(bars)
                    .map_err(|e| e.to_string())?
                    .label(*name)
                    .legend(move |(x, y)| {
                        Rectangle::new([(x, y - 5), (x + 10, y + 5)], color.filled())
                    });
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .position(SeriesLabelPosition::UpperMiddle)
                .draw()
                .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(buf)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::IdentifyTiming;

    fn report() -> Report {
        let k = |arm: &str, kernel: &'static str, g: f64, r: f64| KernelTiming {
            arm: arm.into(),
            kernel,
            generated_ns: g,
            reference_ns: r,
            lanes_ns: g / 4.0,
            lanes8_ns: g / 6.0,
            lanes_skip_ns: g / 5.0,
            lanes8_skip_ns: g / 9.0,
        };
        Report {
            kernels: vec![
                k("puma560", "regressor", 150.0, 1500.0),
                k("puma560", "base_regressor", 100.0, 1600.0),
                k("puma560", "gravity", 20.0, 300.0),
                k("scara", "bias", 50.0, 200.0),
            ],
            identify: IdentifyTiming {
                arm: "puma560".into(),
                samples: 1_000_000,
                seconds: 0.5,
                peak_rss_mb: 4.0,
            },
        }
    }

    const HARNESS: &str = "# Pinocchio 4.1.0\nmodel nv algo median\npuma560 6 regressor 1160.0\n\
        pinocchio,puma560,regressor,1160.0\npinocchio,puma560,rnea,600.5\npinocchio_prebuilt,puma560,rnea,700\n";

    #[test]
    fn parses_only_the_machine_readable_lines() {
        let pin = PinocchioTimes::parse(HARNESS);
        assert_eq!(pin.get("puma560", "base_regressor"), Some(1160.0));
        assert_eq!(pin.get("puma560", "inverse_dynamics"), Some(600.5));
        assert_eq!(pin.get("puma560", "gravity"), None, "no gravity line");
        let g = PinocchioTimes::parse("pinocchio,puma560,gravity,90.5\n");
        assert_eq!(g.get("puma560", "gravity"), Some(90.5));
        assert_eq!(pin.get("panda", "regressor"), None);
        assert!(PinocchioTimes::parse("nothing here").is_empty());
    }

    #[test]
    fn targets_are_evaluated_from_the_same_run() {
        let rows = evaluate(&report(), &PinocchioTimes::parse(HARNESS));
        let get = |p: &str| rows.iter().find(|r| r.0.starts_with(p)).cloned();
        let (_, got, ok) = get("puma560: Pinocchio regressor / ours base_regressor").unwrap();
        assert_eq!((got.as_str(), ok), ("11.60", true));
        let (_, got, ok) = get("every generated kernel").unwrap();
        assert!(
            got.contains("4.0×") && got.contains("scara bias") && !ok,
            "{got}"
        );
        assert!(get("panda").is_none(), "no panda numbers, no panda rows");
    }

    #[test]
    fn markdown_has_one_row_per_kernel_and_the_reproduce_command() {
        let md = markdown(
            &report(),
            &PinocchioTimes::parse(HARNESS),
            &RunInfo::default(),
        );
        assert!(md.contains("| puma560 | base_regressor |"));
        assert!(
            md.contains(
                "| 100.0 | 25.0 | 16.7 | 1.50× | 1.80× | 1600.0 | 1160 | 16.0× | 11.6× | 46.4× |"
            ),
            "{md}"
        );
        assert!(md.contains("| puma560 | gravity |") && md.contains("| — | 15.0× | — | — |"));
        assert!(md.contains("scripts/bench_table.sh"));
    }

    #[test]
    fn svg_renders() {
        let svg = svg(&report(), &PinocchioTimes::parse(HARNESS)).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("puma560") && svg.contains("scara"));
    }
}
