//! `dynid`, the command line (clap) of the `dynid` library: parse, call the library, print; map
//! errors to exit codes (2 = bad input, 1 = internal error; never a panic's 101).
//!
//! Adding a subcommand: a file in `cli/src/` with an `Args` struct (clap `Args`) and a
//! `run(&Args) -> anyhow::Result<()>`, one variant in [`Command`] and one arm in [`run`]; the work
//! itself goes in the library.

use std::path::Path;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod allocator;
mod arms;
mod bar;
mod bench;
mod bench_models;
mod convert;
mod excite;
mod export_urdf;
mod identify;
mod import_urdf;
mod paper;
mod payload;
mod simulate;
mod torque;

/// From a D-H table to generated dynamics kernels and identified dynamic parameters.
#[derive(Debug, Parser)]
#[command(name = "dynid", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// List the generated arms: DOF, base-parameter count and expressions.
    Arms(arms::Args),
    /// Quick throughput of the generated kernels vs the reference, and a 1e6-sample identification.
    Bench(bench::Args),
    /// The models, parameters and input pool of `dynid bench`, for peer harnesses (benches/peers/).
    BenchModels(bench_models::Args),
    /// A ROS 2 bag's (.mcap) joint states as a CSV for identify and torque.
    Convert(convert::Args),
    /// Inverse dynamics along a trajectory (CSV of t, tau1..taun).
    Torque(torque::Args),
    /// Identify base parameters from data, find missing effects (friction, armature, ...), report.
    Identify(identify::Args),
    /// Convert a URDF serial chain to a D-H table (NAME.toml) and inertial parameters (NAME.params.toml).
    ImportUrdf(import_urdf::Args),
    /// Write a D-H arm (and its inertial parameters) as a URDF.
    ExportUrdf(export_urdf::Args),
    /// Reproduce the seed paper end to end (the default when no command is given).
    Paper(paper::Args),
    /// Optimise an excitation trajectory (GA): Logistic (the paper's) or Fourier.
    Excite(excite::Args),
    /// Identify the flange payload (mass, centre of mass, inertia) and, with its mass known, the drive gains.
    Payload(payload::Args),
    /// Closed-loop simulation (RK4 plant + RHFTC/CTC/PD) along a trajectory, to CSV.
    Simulate(simulate::Args),
}

fn main() -> ExitCode {
    allocator::keep_large_buffers();
    let cli = Cli::parse();
    match std::panic::catch_unwind(|| run(cli)) {
        Ok(Ok(())) => ExitCode::SUCCESS,
        Ok(Err(err)) if is_broken_pipe(&err) => ExitCode::SUCCESS,
        Ok(Err(err)) => {
            eprintln!("error: {err:#}");
            ExitCode::from(exit_code(&err))
        }
        Err(_) => {
            eprintln!("error: internal error (a bug in dynid; the panic message is above) — please report it with the command line");
            ExitCode::from(1)
        }
    }
}

/// Runs one command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        None => paper::run(&paper::Args::default()),
        Some(Command::Paper(args)) => paper::run(&args),
        Some(Command::Excite(args)) => excite::run(&args),
        Some(Command::Simulate(args)) => simulate::run(&args),
        Some(Command::Payload(args)) => payload::run(&args),
        Some(Command::Arms(args)) => arms::run(&args),
        Some(Command::Bench(args)) => bench::run(&args),
        Some(Command::BenchModels(args)) => bench_models::run(&args),
        Some(Command::Torque(args)) => torque::run(&args),
        Some(Command::Convert(args)) => convert::run(&args),
        Some(Command::Identify(args)) => identify::run(&args),
        Some(Command::ImportUrdf(args)) => import_urdf::run(&args),
        Some(Command::ExportUrdf(args)) => export_urdf::run(&args),
    }
}

/// A bad-input error raised by the CLI itself (e.g. an invalid combination of options).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct InputError(pub String);

/// Process exit code for an error: 2 when the input (files, options) is bad, 1 otherwise.
pub fn exit_code(err: &anyhow::Error) -> u8 {
    let bad_input = err.chain().any(|e| {
        e.is::<InputError>()
            || e.downcast_ref::<dynid::app::AppError>()
                .is_some_and(dynid::app::AppError::is_bad_input)
            || e.is::<dynid::dh::DhError>()
            || e.is::<dynid::params::ParamsError>()
            || e.is::<dynid::data::DataError>()
            || e.is::<dynid::bag::BagError>()
            || e.is::<dynid::arms::ArmError>()
            || e.is::<dynid::io::WriteError>()
            || e.is::<dynid::urdf::UrdfError>()
            || e.is::<dynid::urdf::ExportError>()
            || e.is::<clap::Error>()
    });
    if bad_input {
        2
    } else {
        1
    }
}

/// True when the error is a closed stdout (e.g. `dynid torque ... | head`): not a failure.
pub fn is_broken_pipe(err: &anyhow::Error) -> bool {
    err.chain().any(|e| {
        e.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// Writes an output atomically to `out`, or to stdout when `out` is `None` or `-`.
pub fn write_output<F>(out: Option<&Path>, write: F) -> anyhow::Result<()>
where
    F: FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
{
    match out {
        Some(path) if path != Path::new("-") => Ok(dynid::io::atomic_write(path, write)?),
        _ => {
            let stdout = std::io::stdout();
            let mut lock = std::io::BufWriter::new(stdout.lock());
            write(&mut lock)?;
            std::io::Write::flush(&mut lock)?;
            Ok(())
        }
    }
}
