//! The crate's error type: every failure a user can cause becomes one line that names
//! the file, the key or element, and what is wrong (ground rule: no panic on bad input).

use std::path::{Path, PathBuf};

/// A user-facing error. `Display` is the one line printed by the binaries.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// A file was read but its content is wrong: `what` names the key, element or line.
    #[error("{path}: {what}")]
    Invalid {
        /// The file concerned.
        path: PathBuf,
        /// What is wrong, naming the key, element or line.
        what: String,
    },
    /// A command-line or run-time condition that is not tied to one file.
    #[error("{0}")]
    Message(String),
}

impl Error {
    /// An I/O error on `path`.
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.as_ref().to_path_buf(),
            source,
        }
    }

    /// A content error in `path`; `what` names the key or element and the reason.
    pub fn invalid(path: impl AsRef<Path>, what: impl Into<String>) -> Self {
        Error::Invalid {
            path: path.as_ref().to_path_buf(),
            what: what.into(),
        }
    }
}

/// The crate's result type.
pub type Result<T> = std::result::Result<T, Error>;
