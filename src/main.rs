//! `dynid`: parse the command line, run it through the library, map errors to exit codes
//! (2 = bad input, 1 = internal error; never a panic's 101).

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    keep_large_buffers();
    let cli = dynid::cli::Cli::parse();
    match std::panic::catch_unwind(|| dynid::cli::run(cli)) {
        Ok(Ok(())) => ExitCode::SUCCESS,
        Ok(Err(err)) if dynid::cli::is_broken_pipe(&err) => ExitCode::SUCCESS,
        Ok(Err(err)) => {
            eprintln!("error: {err:#}");
            ExitCode::from(dynid::cli::exit_code(&err))
        }
        Err(_) => {
            eprintln!("error: internal error (a bug in dynid; the panic message is above) — please report it with the command line");
            ExitCode::from(1)
        }
    }
}

/// Keeps freed large buffers in the process's heap for reuse (glibc). An identification allocates
/// and frees buffers of a few megabytes thousands of times (a chunk's rows, a filter's padded
/// copy, predictions); by default glibc maps each above its adaptive threshold afresh and returns
/// freed heap tops to the system, so reuse pays page faults — ~10 % of a 1e6-sample log's CPU
/// time, up to 1.3 s of system time in one run. With fixed thresholds (32 MiB, glibc's largest
/// mapping threshold; trimming only past 1 GiB free) the same peak memory, a fraction of the
/// faults (docs/bench_identify.md, eighth round).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn keep_large_buffers() {
    // SAFETY: `mallopt` only sets two allocator parameters; called before any other thread runs.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 1 << 30);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn keep_large_buffers() {}
