//! One error type for the library, with the exit status the command-line tool maps it to.

use std::fmt;
use std::path::{Path, PathBuf};

/// Everything that can go wrong, split by whose fault it is so the CLI can pick an exit status.
#[derive(Debug)]
pub enum Error {
    /// The input (a map file, its yaml, a size) is missing, malformed or unsupported.
    Input {
        /// The file the problem is in, when there is one.
        path: Option<PathBuf>,
        /// What is wrong, in one line.
        message: String,
    },
    /// Writing a result failed (output file, overlay, directory).
    Output {
        /// The file that could not be written.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A resource the request needs is not there (no GPU adapter, a device too small).
    Unavailable(String),
    /// A bug or an environment failure that is nobody's input.
    Internal(String),
    /// `merge` was not confident enough to merge (the verdict has been printed; exit status 3).
    Declined(String),
    /// The caller stopped the work ([`crate::support::stop`]; Ctrl-C in Python).
    Interrupted,
}

impl Error {
    /// An input error about `path`.
    pub fn input(path: impl AsRef<Path>, message: impl Into<String>) -> Self {
        Error::Input {
            path: Some(path.as_ref().to_path_buf()),
            message: message.into(),
        }
    }

    /// An input error that is not about a file (a bad size, an empty map in memory).
    pub fn invalid(message: impl Into<String>) -> Self {
        Error::Input {
            path: None,
            message: message.into(),
        }
    }

    /// An error writing `path`.
    pub fn output(path: impl AsRef<Path>, message: impl ToString) -> Self {
        Error::Output {
            path: path.as_ref().to_path_buf(),
            message: message.to_string(),
        }
    }

    /// An error writing `path` from the system's error. A write past the process's file size limit
    /// (EFBIG under `ulimit -f`; the tool ignores SIGXFSZ so that it gets the error instead of dying) is
    /// said in words and met as a full disk is: exit status 1, nothing half-written left.
    pub fn write(path: impl AsRef<Path>, e: std::io::Error) -> Self {
        #[cfg(unix)]
        const EFBIG: i32 = 27;
        #[cfg(unix)]
        if e.raw_os_error() == Some(EFBIG) {
            return Error::output(
                path,
                "over this process's file size limit (ulimit -f; File too large)",
            );
        }
        Error::output(path, e)
    }

    /// The process exit status the command-line tool uses: 2 for bad input, 3 for a declined merge, 130
    /// when interrupted (as a shell reports SIGINT), 1 otherwise.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Input { .. } => 2,
            Error::Output { .. } | Error::Unavailable(_) | Error::Internal(_) => 1,
            Error::Declined(_) => 3,
            Error::Interrupted => 130,
        }
    }
}

impl fmt::Display for Error {
    /// One line: control characters in paths and messages (a newline in a file name, a NUL from a yaml)
    /// are written escaped, so an error never spans lines or carries raw bytes to a terminal.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let path = |p: &Path| one_line(&p.display().to_string());
        match self {
            Error::Input {
                path: Some(p),
                message,
            } => write!(f, "{}: {}", path(p), one_line(message)),
            Error::Input {
                path: None,
                message,
            } => write!(f, "{}", one_line(message)),
            Error::Output { path: p, message } => {
                write!(f, "{}: cannot write: {}", path(p), one_line(message))
            }
            Error::Unavailable(m) => write!(f, "{}", one_line(m)),
            Error::Internal(m) => write!(f, "internal error: {}", one_line(m)),
            Error::Declined(m) => write!(f, "not merged: {}", one_line(m)),
            Error::Interrupted => write!(f, "interrupted"),
        }
    }
}

/// `s` with control characters escaped (`\n`, `\0`, `\u{1b}`), everything else as it is.
pub fn one_line(s: &str) -> String {
    if !s.chars().any(char::is_control) {
        return s.to_string();
    }
    s.chars()
        .map(|c| {
            if c.is_control() {
                c.escape_default().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}

impl std::error::Error for Error {}

/// Shorthand used throughout the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_stay_on_one_line() {
        let e = Error::input("bad\nname.pgm", "image \"x\ny\0.pgm\" is missing");
        let m = e.to_string();
        assert_eq!(m, "bad\\nname.pgm: image \"x\\ny\\u{0}.pgm\" is missing");
        assert_eq!(one_line("café ok"), "café ok");
    }
}
