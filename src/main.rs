//! `ogm-corners`: the command-line tool. Exit status 0 on success, 2 on bad input or usage, 1 otherwise;
//! 130 when interrupted (SIGINT, SIGTERM, SIGHUP), with no half-written output left behind.

// Pipelines read as named stages: no function over 120 lines (clippy.toml sets the limit).
#![warn(clippy::too_many_lines)]

mod cli;

use std::alloc::{GlobalAlloc, Layout, System};
use std::process::ExitCode;

use clap::Parser;

/// The system allocator, with a failure that ends the run in one line (exit 2, outputs in progress
/// removed) instead of Rust's abort with a backtrace: what a limit the budget could not see (an address
/// space limit lowered after start, another process taking the memory) ends in.
struct Guarded;

// SAFETY: every call is forwarded to the system allocator unchanged; only a null result is acted on.
unsafe impl GlobalAlloc for Guarded {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        checked(System.alloc(layout), layout.size())
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        checked(System.alloc_zeroed(layout), layout.size())
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        checked(System.realloc(ptr, layout, new_size), new_size)
    }
}

#[global_allocator]
static ALLOCATOR: Guarded = Guarded;

/// `ptr`, unless the allocation failed: then one line on standard error (formatted on the stack: the heap
/// just failed) and exit 2 with the temporary outputs removed.
fn checked(ptr: *mut u8, size: usize) -> *mut u8 {
    if !ptr.is_null() || size == 0 {
        return ptr;
    }
    // Threads that fail together (rayon's workers under one limit) say it once: the first one reports and
    // exits; the others wait for the exit.
    static REPORTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);
    if REPORTED.swap(true, std::sync::atomic::Ordering::SeqCst) {
        loop {
            std::thread::park();
        }
    }
    use std::io::Write as _;
    let mut line = [0u8; 256];
    let mut cursor = std::io::Cursor::new(&mut line[..]);
    let _ = writeln!(
        cursor,
        "ogm-corners: error: out of memory: the system refused {:.1} MiB (a process or machine limit below \
         what the run needs); give a lower --max-memory, or raise the limit",
        size as f64 / (1u64 << 20) as f64
    );
    let n = cursor.position() as usize;
    let _ = std::io::stderr().write_all(&line[..n]);
    ogm_corners::support::files::remove_pending_and_exit(2)
}

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
            ogm_corners::support::error::one_line(&what)
        );
    }));
    quiet_display_probe();
    // Before the first parallel work, so the pool is made at its capped size.
    if let Some(note) = ogm_corners::support::threads::cap_pool() {
        ogm_corners::say!("ogm-corners: note: {note}");
    }
    // Past a file size limit (`ulimit -f`) a write then fails with EFBIG, reported and cleaned up like a
    // full disk, instead of SIGXFSZ killing the process with its temporary files left behind.
    #[cfg(unix)]
    // SAFETY: sets a signal's disposition to "ignore", before any other thread exists.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
    // Outputs are written to temporary files renamed into place when complete; an interrupted run removes
    // the ones in progress, so neither a partial output nor a stray temporary file is left.
    let _ = ctrlc::set_handler(|| {
        ogm_corners::say!("ogm-corners: interrupted; outputs in progress removed");
        ogm_corners::support::files::remove_pending_and_exit(130);
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

/// Without a desktop session (no `XDG_RUNTIME_DIR`), Mesa's Vulkan device-selection layer still asks
/// Wayland for the display's GPU when adapters are listed, and Wayland prints "error: XDG_RUNTIME_DIR is
/// invalid or not set" on standard error, however well the run goes. With no display there is nothing to
/// select by, so the layer is turned off (its own switch, `NODEVICE_SELECT`) unless the user set it.
fn quiet_display_probe() {
    let session = std::env::var_os("XDG_RUNTIME_DIR")
        .is_some_and(|d| !d.is_empty() && std::path::Path::new(&d).is_dir());
    if !session && std::env::var_os("NODEVICE_SELECT").is_none() {
        // At the start of main, before any other thread exists (the interrupt handler's and the
        // worker pool's are made after this).
        std::env::set_var("NODEVICE_SELECT", "1");
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
