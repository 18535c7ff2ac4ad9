//! The library's typed error. Every message names what was wrong (file, field, value) and
//! what would be valid, so the CLI can print it as one line.

use std::path::PathBuf;

/// Result alias used throughout eoir.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in eoir, with enough context to fix it.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A configuration or function parameter outside its valid range.
    #[error("invalid parameter `{field}` = {value}: {expected}")]
    InvalidParameter {
        /// Name of the field or argument (dotted path for configuration keys).
        field: String,
        /// The offending value, as written.
        value: String,
        /// What would be valid.
        expected: String,
    },
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A file was read but its content is malformed or inconsistent. Displayed with
    /// control characters escaped and at most 600 characters of message, so a hostile
    /// or binary file cannot inject terminal escapes or have itself echoed at length.
    #[error("{}: {}", path.display(), escape_controls(message, 600))]
    Format {
        /// The file concerned.
        path: PathBuf,
        /// What is wrong and where (line, field, value).
        message: String,
    },
    /// A numerical inversion or evaluation that has no valid answer (e.g. a signal outside
    /// the range a temperature lookup covers).
    #[error("{0}")]
    OutOfRange(String),
    /// A size from a file or the command line that would exceed the memory limit (or
    /// overflow 64-bit arithmetic); checked before allocating (see [`crate::limits`]).
    #[error("{what} would need {needed}, more than the memory limit of {} (raise it with --max-memory if the machine has the memory)", human_bytes(*limit))]
    TooLarge {
        /// The structure or step concerned.
        what: String,
        /// The size it would need and how it follows from the input.
        needed: String,
        /// The limit in force, bytes.
        limit: u64,
    },
}

impl Error {
    /// Shorthand for [`Error::InvalidParameter`].
    pub fn param(
        field: impl Into<String>,
        value: impl std::fmt::Display,
        expected: impl Into<String>,
    ) -> Self {
        Error::InvalidParameter {
            field: field.into(),
            value: value.to_string(),
            expected: expected.into(),
        }
    }

    /// Shorthand for [`Error::Io`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    /// Shorthand for [`Error::Format`].
    pub fn format(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Format {
            path: path.into(),
            message: message.into(),
        }
    }
}

/// Checks that `value` is finite and strictly positive, naming `field` otherwise.
pub fn require_positive(field: &str, value: f64) -> Result<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(Error::param(field, value, "a finite number > 0"))
    }
}

/// Checks that `value` is finite and ≥ 0, naming `field` otherwise.
pub fn require_non_negative(field: &str, value: f64) -> Result<f64> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(Error::param(field, value, "a finite number >= 0"))
    }
}

/// Checks that `value` lies in the closed interval [lo, hi], naming `field` otherwise.
pub fn require_in_range(field: &str, value: f64, lo: f64, hi: f64) -> Result<f64> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(value)
    } else {
        Err(Error::param(
            field,
            value,
            format!("a number in [{lo}, {hi}]"),
        ))
    }
}

/// `bytes` as a short human-readable size (binary units).
pub fn human_bytes(bytes: u64) -> String {
    const UNITS: [&str; 7] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut v = bytes as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{bytes} B")
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}

/// A short, escaped rendering of untrusted text for an error message: at most 40
/// characters, control and non-ASCII characters escaped (`\n`, `\u{7f}`), `…` when cut.
/// Error messages quote file contents only through this.
pub fn escape_token(text: &str) -> String {
    escape_bounded(text, 40)
}

/// Like [`escape_token`] with a bound of `max` characters (for a parser's own message,
/// which may embed a value it read).
pub fn escape_bounded(text: &str, max: usize) -> String {
    let mut out = String::new();
    for (i, c) in text.chars().enumerate() {
        if i == max {
            out.push('…');
            break;
        }
        if c.is_ascii_graphic() || c == ' ' {
            out.push(c);
        } else {
            out.extend(c.escape_default());
        }
    }
    out
}

/// `text` with control characters escaped (`\n`, `\u{1b}`; other Unicode such as `µ`
/// kept) and cut at `max` characters with `…`.
pub fn escape_controls(text: &str, max: usize) -> String {
    let mut out = String::new();
    for (i, c) in text.chars().enumerate() {
        if i == max {
            out.push('…');
            break;
        }
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}
