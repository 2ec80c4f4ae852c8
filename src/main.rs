//! `ogm-corners`: the command-line tool. Exit status 0 on success, 2 on bad input or usage, 1 otherwise;
//! 130 when interrupted (SIGINT, SIGTERM, SIGHUP), with no half-written output left behind.

mod batch;
mod cli;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    // A panic is a bug: one escaped line, then exit 1 below (not Rust's multi-line message and 101).
    std::panic::set_hook(Box::new(|info| {
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        let what = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_default();
        ogm_corners::say!(
            "ogm-corners: internal error: the tool panicked{at}: {} (a bug; please report it)",
            ogm_corners::error::one_line(&what)
        );
    }));
    // Outputs are written to temporary files renamed into place when complete; an interrupted run removes
    // the ones in progress, so neither a partial output nor a stray temporary file is left.
    let _ = ctrlc::set_handler(|| {
        ogm_corners::say!("ogm-corners: interrupted; outputs in progress removed");
        ogm_corners::files::remove_pending_and_exit(130);
    });
    let parsed = match cli::Cli::try_parse() {
        Ok(c) => c,
        Err(e) if !e.use_stderr() => {
            // Help and version go to standard output with status 0.
            let _ = e.print();
            return ExitCode::SUCCESS;
        }
        Err(e) if e.kind() == clap::error::ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
            // `ogm-corners` alone: say so, then the help (clap would lead with the description).
            ogm_corners::say!("ogm-corners: error: no command given\n\n{}", e.render());
            return ExitCode::from(2);
        }
        Err(e) => {
            ogm_corners::say!("{}", usage_error(&e.render().to_string()).trim_end());
            return ExitCode::from(2);
        }
    };
    // A panic is a bug; report it as an internal failure (status 1), not Rust's default 101.
    match std::panic::catch_unwind(|| cli::run(parsed)) {
        Ok(Ok(())) => ExitCode::SUCCESS,
        Ok(Err(e)) => {
            // A declined merge is a verdict, already printed on standard output, not an error.
            if !matches!(e, ogm_corners::Error::Declined(_)) {
                ogm_corners::say!("ogm-corners: error: {e}");
            }
            ExitCode::from(e.exit_code() as u8)
        }
        // The panic hook has said what happened.
        Err(_) => ExitCode::from(1),
    }
}

/// clap's usage error with its first paragraph on one line, led like every other error of the tool
/// (`ogm-corners: error: ...`), then the usage and the hint as clap writes them.
fn usage_error(rendered: &str) -> String {
    let (first, rest) = rendered.split_once("\n\n").unwrap_or((rendered, ""));
    let first = first.trim().trim_start_matches("error:").trim();
    let line = first.split_whitespace().collect::<Vec<_>>().join(" ");
    if rest.trim().is_empty() {
        format!("ogm-corners: error: {line}\n")
    } else {
        format!("ogm-corners: error: {line}\n\n{}\n", rest.trim_end())
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn usage_errors_lead_with_one_line() {
        let clap = "error: the following required arguments were not provided:\n  <MAP>...\n\nUsage: ogm-corners detect <MAP>...\n\nFor more information, try '--help'.\n";
        let got = super::usage_error(clap);
        let mut lines = got.lines();
        assert_eq!(
            lines.next(),
            Some(
                "ogm-corners: error: the following required arguments were not provided: <MAP>..."
            )
        );
        assert!(got.contains("Usage: ogm-corners detect"));
    }
}
