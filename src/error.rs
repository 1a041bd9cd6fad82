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

    /// Refuse, naming `what`, a hand-built value whose data (`held` elements, counted in
    /// `unit`s: "bytes", "values") disagrees with its sizes: `extents` times `per_cell` elements,
    /// multiplied without overflow. `shape` describes the sizes for the message, with its verb
    /// ("4x4x4 voxels of 3 channels take").
    pub(crate) fn check_held(
        what: &str,
        held: usize,
        extents: &[u32],
        per_cell: u64,
        unit: &str,
        shape: impl FnOnce() -> String,
    ) -> Result<()> {
        let needed = extents
            .iter()
            .try_fold(per_cell, |n, &e| n.checked_mul(u64::from(e)));
        if needed == Some(held as u64) {
            return Ok(());
        }
        // (None: more than a u64 counts, which no data holds.)
        let needed = needed.map_or("more than 2^64".to_string(), |n| n.to_string());
        Err(Error::invalid(
            what,
            format!("holds {held} {unit}; {} {needed}", shape()),
        ))
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
            text.push_str(&without_os_code(&c.to_string()));
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

/// A message without the " (os error 2)" the standard library appends to a system error's
/// description, wherever it stands: the description says what went wrong, and the number adds
/// nothing for a user.
pub fn without_os_code(message: &str) -> std::borrow::Cow<'_, str> {
    const MARK: &str = " (os error ";
    if !message.contains(MARK) {
        return message.into();
    }
    let mut text = String::with_capacity(message.len());
    let mut rest = message;
    while let Some(at) = rest.find(MARK) {
        let after = &rest[at + MARK.len()..];
        let digits = after
            .find(|c: char| !(c.is_ascii_digit() || c == '-'))
            .unwrap_or(after.len());
        if digits > 0 && after[digits..].starts_with(')') {
            text.push_str(&rest[..at]);
            rest = &after[digits + 1..];
        } else {
            text.push_str(&rest[..at + MARK.len()]);
            rest = after;
        }
    }
    text.push_str(rest);
    text.into()
}

/// What a system error says went wrong, for a message that names the file itself: the
/// description alone, without its number or the path `tempfile` appends to its errors
/// ("... at path \"/dir/.tmpXXXX\"", a name the user never gave).
pub fn io_problem(e: &std::io::Error) -> String {
    let text = e.to_string();
    let text = match (e.get_ref().is_some(), text.rfind(" at path \"")) {
        (true, Some(at)) => &text[..at],
        _ => &text,
    };
    without_os_code(text).into_owned()
}

/// Result alias used across the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn system_errors_are_reported_without_their_number() {
        let missing = std::io::Error::from_raw_os_error(2);
        assert!(missing.to_string().ends_with("(os error 2)"));
        let e = Error::io("in.png", missing);
        assert_eq!(e.report(), "in.png: No such file or directory");
        // Only the standard library's suffix goes; a message that merely mentions it stays.
        let text = "see (os error codes) in the manual";
        assert_eq!(without_os_code(text), text);
        assert_eq!(without_os_code("a (os error x)"), "a (os error x)");
        assert_eq!(
            without_os_code("x: Permission denied (os error 13) at path \"/p\""),
            "x: Permission denied at path \"/p\""
        );
        // A wrapper's path is left out where the message names the file itself.
        let wrapped = tempfile::NamedTempFile::new_in("/no/such/directory").unwrap_err();
        assert!(wrapped.to_string().contains("at path"), "{wrapped}");
        assert_eq!(io_problem(&wrapped), "No such file or directory");
    }
}
