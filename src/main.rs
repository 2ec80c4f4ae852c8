//! `ogm-corners`: the command-line tool. Exit status 0 on success, 2 on bad input or usage, 1 otherwise.

mod batch;
mod cli;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let parsed = match cli::Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            // Help and version go to stdout with status 0; usage errors exit with 2.
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
    };
    // A panic is a bug; report it as an internal failure (status 1), not Rust's default 101.
    match std::panic::catch_unwind(|| cli::run(parsed)) {
        Ok(Ok(())) => ExitCode::SUCCESS,
        Ok(Err(e)) => {
            eprintln!("ogm-corners: error: {e}");
            ExitCode::from(cli::exit_code(&e) as u8)
        }
        Err(_) => {
            eprintln!("ogm-corners: internal error: the tool panicked (a bug; please report it)");
            ExitCode::from(1)
        }
    }
}
