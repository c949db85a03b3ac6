//! `dynid`: parse the command line, run it through the library, map errors to exit codes
//! (2 = bad input, 1 = internal error; never a panic's 101).

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
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
