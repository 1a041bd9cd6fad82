//! The library's error type. `InvalidInput` is the user's fault (the CLI exits 2 for it);
//! everything else is an internal or environmental failure (exit 1).

use std::path::PathBuf;

/// Every fallible library call returns this.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A user-supplied value or file is unusable. `what` names the flag or file, `problem` says why.
    #[error("invalid {what}: {problem}")]
    InvalidInput { what: String, problem: String },

    /// A file that should be one of ours (e.g. `.ssa`) is damaged or of another version.
    #[error("{path}: {problem}")]
    CorruptFile { path: PathBuf, problem: String },

    /// Reading or writing a file failed. The message names the file; the cause is the error's
    /// source (printed after it by `{:#}` / error reporters), not repeated in the message.
    #[error("{path}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },

    /// No GPU adapter matched, or the GPU reported an error or timed out.
    #[error("GPU: {0}")]
    Gpu(String),

    /// A numerical step failed where valid input should never make it fail (a bug).
    #[error("internal error: {0}")]
    Internal(String),

    /// The caller cancelled the work (`util::cancel::CancelToken`); nothing was written.
    #[error("cancelled")]
    Cancelled,
}

impl Error {
    /// Shorthand for [`Error::InvalidInput`].
    pub fn invalid(what: impl Into<String>, problem: impl Into<String>) -> Self {
        Error::InvalidInput {
            what: what.into(),
            problem: problem.into(),
        }
    }

    /// Shorthand for [`Error::CorruptFile`].
    pub fn corrupt(path: impl Into<PathBuf>, problem: impl Into<String>) -> Self {
        Error::CorruptFile {
            path: path.into(),
            problem: problem.into(),
        }
    }

    /// Shorthand for [`Error::Io`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    /// The message followed by its causes (`path: No such file or directory`), for reports
    /// that do not walk the source chain themselves.
    pub fn report(&self) -> String {
        let mut text = self.to_string();
        let mut cause = std::error::Error::source(self);
        while let Some(c) = cause {
            text.push_str(": ");
            text.push_str(&c.to_string());
            cause = c.source();
        }
        text
    }

    /// True when the failure is the caller's input (bad flag, bad or damaged file): exit code 2.
    pub fn is_user_error(&self) -> bool {
        match self {
            Error::InvalidInput { .. } | Error::CorruptFile { .. } => true,
            // A missing input file or a directory in the way of an output is also the user's.
            Error::Io { source, .. } => matches!(
                source.kind(),
                std::io::ErrorKind::NotFound
                    | std::io::ErrorKind::PermissionDenied
                    | std::io::ErrorKind::IsADirectory
                    | std::io::ErrorKind::NotADirectory
                    | std::io::ErrorKind::AlreadyExists
                    | std::io::ErrorKind::InvalidData
                    | std::io::ErrorKind::UnexpectedEof
                    | std::io::ErrorKind::ReadOnlyFilesystem
            ),
            Error::Gpu(_) | Error::Internal(_) | Error::Cancelled => false,
        }
    }
}

/// Result alias used across the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;
