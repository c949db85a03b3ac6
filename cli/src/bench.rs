//! `dynid bench [--arm A] [--json] [--samples N] [--pinocchio FILE --markdown FILE --svg FILE]`:
//! quick in-process throughput of the generated kernels next to the hand-written reference, and a
//! streaming identification of a generated 1,000,000-sample PUMA 560 log. The careful numbers come
//! from `cargo bench`; the README table with Pinocchio measured in the same run from
//! `scripts/bench_table.sh`, which passes the harness output with `--pinocchio`.

use std::path::PathBuf;

use anyhow::Result;

use crate::{write_output, InputError};
use dynid::arms::{resolve, ArmSource};
use dynid::bench::table::{markdown, svg, PinocchioTimes, RunInfo};
use dynid::bench::{Report, Settings, IDENTIFY_SAMPLES};
use dynid::model::Model;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Measure only this arm's kernels (default: every generated arm).
    #[arg(long)]
    pub arm: Option<String>,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Samples in the streaming PUMA 560 identification.
    #[arg(long, default_value_t = IDENTIFY_SAMPLES)]
    pub samples: usize,
    /// Output of `benches/peers/pinocchio/run.sh` from the same run (its
    /// `pinocchio,<model>,<algo>,<ns>` lines), for the Pinocchio columns of --markdown/--svg.
    #[arg(long, value_name = "FILE")]
    pub pinocchio: Option<PathBuf>,
    /// Write the README benchmark section (Markdown table with ratios and targets) here.
    #[arg(long, value_name = "FILE")]
    pub markdown: Option<PathBuf>,
    /// Write the benchmark plot (SVG) here.
    #[arg(long, value_name = "FILE")]
    pub svg: Option<PathBuf>,
}

/// The generated arms to measure: all, or the one named (an arm given only as a D-H table has no
/// generated kernels to time: a clear error says how to generate them).
pub(super) fn generated_arms(arm: Option<&str>) -> Result<Vec<&'static dyn Model>> {
    Ok(match arm {
        None => dynid::arms::all().to_vec(),
        Some(name) => match resolve(name)? {
            ArmSource::Generated(m) => vec![m],
            ArmSource::Table(t) => {
                return Err(InputError(format!(
                    "{name}: `dynid bench` measures generated kernels — copy the table to arms/{}.toml and run `cargo build` to generate them",
                    t.name
                ))
                .into())
            }
        },
    })
}

pub fn run(args: &Args) -> Result<()> {
    let arms = generated_arms(args.arm.as_deref())?;
    if args.samples == 0 {
        return Err(InputError("--samples must be at least 1".into()).into());
    }
    // Read the harness output before measuring: a wrong path fails in a second, not after the run.
    let pinocchio = match &args.pinocchio {
        None => PinocchioTimes::default(),
        Some(path) => {
            let text = std::fs::read_to_string(path).map_err(|e| {
                InputError(format!(
                    "--pinocchio {}: cannot read the harness output: {e}",
                    path.display()
                ))
            })?;
            let times = PinocchioTimes::parse(&text);
            if times.is_empty() {
                return Err(InputError(format!(
                    "--pinocchio {}: no `pinocchio,<model>,<algo>,<ns>` lines — pass the full output of benches/peers/pinocchio/run.sh",
                    path.display()
                ))
                .into());
            }
            times
        }
    };
    let info = RunInfo::current();
    let bar = indicatif::ProgressBar::new(arms.len() as u64 + 1);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let (report, ident) = dynid::bench::run(&arms, &Settings::quick(), args.samples, |done| {
        bar.set_message(done.to_string());
        bar.inc(1);
    })?;
    bar.finish_and_clear();
    if let Some(path) = &args.markdown {
        let md = markdown(&report, &pinocchio, &info);
        dynid::io::atomic_write(path, |w| w.write_all(md.as_bytes()))?;
    }
    if let Some(path) = &args.svg {
        let svg = svg(&report, &pinocchio)
            .map_err(|e| anyhow::anyhow!("drawing the benchmark plot: {e}"))?;
        dynid::io::atomic_write(path, |w| w.write_all(svg.as_bytes()))?;
    }
    write_output(None, |w| {
        if args.json {
            serde_json::to_writer_pretty(&mut *w, &report)?;
            return writeln!(w);
        }
        write_table(w, &report)?;
        let s = &ident.solution;
        writeln!(
            w,
            "  identified {} base parameters: cond(Yb, column-scaled) = {:.3e}, rms residual {:.4} N·m, max relative error {:.2e}",
            s.theta.len(),
            s.cond,
            s.rms_residual,
            ident.max_rel_error
        )
    })
}

fn write_table(w: &mut dyn std::io::Write, report: &Report) -> std::io::Result<()> {
    writeln!(
        w,
        "{:<10} {:<17} {:>14} {:>16} {:>17} {:>13} {:>14} {:>8}",
        "ARM",
        "KERNEL",
        "GENERATED ns",
        "LANES ns/sample",
        "LANES8 ns/sample",
        "LANES/LANES8",
        "REFERENCE ns",
        "REF/GEN"
    )?;
    for k in &report.kernels {
        writeln!(
            w,
            "{:<10} {:<17} {:>14.1} {:>16.1} {:>17.1} {:>13} {:>14.1} {:>7.1}×",
            k.arm,
            k.kernel,
            k.generated_ns,
            k.lanes_ns,
            k.lanes8_ns,
            format!(
                "{:.2}× ({:.2}×)",
                k.lanes_ns / k.lanes8_ns,
                k.lanes_skip_ns / k.lanes8_skip_ns
            ),
            k.reference_ns,
            k.reference_ns / k.generated_ns
        )?;
    }
    writeln!(
        w,
        "(LANES: the same generated kernel on {} samples per call, dynid::pack; LANES8: on {}, {}; in parentheses \
         the ratio of the forms that skip the constant-zero outputs)",
        dynid::pack::LANES,
        dynid::pack::wide::WIDE_LANES,
        dynid::pack::wide::wide_form()
    )?;
    let i = &report.identify;
    writeln!(
        w,
        "\nstreaming identification ({}, {} samples, one thread): {:.3} s, peak RSS {:.1} MB",
        i.arm, i.samples, i.seconds, i.peak_rss_mb
    )
}
