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

    /// The process exit status the command-line tool uses: 2 for bad input, 1 otherwise.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Input { .. } => 2,
            Error::Output { .. } | Error::Unavailable(_) | Error::Internal(_) => 1,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Input {
                path: Some(p),
                message,
            } => write!(f, "{}: {}", p.display(), message),
            Error::Input {
                path: None,
                message,
            } => write!(f, "{message}"),
            Error::Output { path, message } => {
                write!(f, "{}: cannot write: {}", path.display(), message)
            }
            Error::Unavailable(m) => write!(f, "{m}"),
            Error::Internal(m) => write!(f, "internal error: {m}"),
        }
    }
}

impl std::error::Error for Error {}

/// Shorthand used throughout the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;
