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

/// A parser's message (serde, toml, serde_json) without the text it quoted from the
/// file: every `` `…` `` or `"…"` segment before the word "expected" is replaced by
/// `(text not shown)`, so `invalid type: string "x", expected f64` keeps what was
/// expected (which comes from eoir) and loses `x` (which comes from the file). With
/// `keep_names`, a key or variant name (at most 40 characters of letters, digits, `_`,
/// `-` and `.`) right after "unknown field", "unknown variant", "missing field" or
/// "duplicate key" is kept: a sensor file's misspelt key is worth naming, and text
/// that is not a file's own key structure (a password line, a hash) never has that form.
/// The result is escaped and bounded like [`escape_bounded`]. Callers add the line and
/// column, which tell the user where to look without showing a private file.
pub fn redact_quoted(message: &str, max: usize, keep_names: bool) -> String {
    const NAMED_AFTER: [&str; 5] = [
        "unknown field ",
        "unknown variant ",
        "missing field ",
        "duplicate key ",
        "duplicate field ",
    ];
    let is_name = |q: &str| {
        !q.is_empty()
            && q.len() <= 40
            && q.chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'))
    };
    let mut out = String::new();
    let mut expected_seen = false;
    let mut chars = message.chars();
    let mut plain = String::new();
    while let Some(c) = chars.next() {
        if c == '`' || c == '"' {
            let mut quoted = String::new();
            let mut closed = false;
            for q in chars.by_ref() {
                if q == c {
                    closed = true;
                    break;
                }
                quoted.push(q);
            }
            expected_seen |= plain.contains("expected");
            let named = keep_names && NAMED_AFTER.iter().any(|n| plain.ends_with(n));
            out.push_str(&plain);
            plain.clear();
            if closed && (expected_seen || (named && is_name(&quoted))) {
                out.push(c);
                out.push_str(&quoted);
                out.push(c);
            } else {
                out.push_str("(text not shown)");
            }
        } else {
            plain.push(c);
        }
    }
    out.push_str(&plain);
    escape_bounded(&out, max)
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

#[cfg(test)]
mod tests {
    use super::redact_quoted;

    /// What a parser quoted from the file goes; what eoir lists as expected stays; a
    /// misspelt key is named only when asked and only when it has the form of a key.
    #[test]
    fn quoted_file_text_is_removed_and_expected_names_kept() {
        let m = r#"invalid type: string "root:$6$SECRET", expected f64"#;
        let r = redact_quoted(m, 200, true);
        assert!(!r.contains("SECRET") && r.contains("expected f64"), "{r}");
        let m = "unknown field `f_numbr`, expected one of `f_number`, `focal_length_m`";
        assert_eq!(
            redact_quoted(m, 200, true),
            "unknown field `f_numbr`, expected one of `f_number`, `focal_length_m`"
        );
        assert_eq!(
            redact_quoted(m, 200, false),
            "unknown field (text not shown), expected one of `f_number`, `focal_length_m`"
        );
        let m = "unknown field `root:x:0:0:SECRET`, expected `a`";
        assert!(!redact_quoted(m, 200, true).contains("SECRET"));
        // An unclosed quote hides the rest.
        assert_eq!(
            redact_quoted("bad `SECRET", 200, true),
            "bad (text not shown)"
        );
    }
}
