//! Where an input problem is, and hints for fixing it: shared by the loaders' error types.
//!
//! Every loader error renders as `<file>:<line>: <field>: <what is wrong> — <how to fix it>`;
//! [`Location`] is the `<file>:<line>: <field>` part.

use std::fmt;

/// Where in a user file something is wrong.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Location {
    /// The file as the user named it (or an origin such as `<stdin>`).
    pub file: String,
    /// 1-based line number in the file (for CSV: the line of the row), when known.
    pub line: Option<usize>,
    /// The field: a TOML key path such as `joint[2].alpha` (joints and links count from 1),
    /// or a CSV column name.
    pub field: Option<String>,
}

impl Location {
    /// A location naming only the file.
    pub fn file(file: impl Into<String>) -> Self {
        Location {
            file: file.into(),
            line: None,
            field: None,
        }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if let Some(field) = &self.field {
            write!(f, ": {field}")?;
        }
        Ok(())
    }
}

/// 1-based line number of byte `offset` in `text`.
pub fn line_of(text: &str, offset: usize) -> usize {
    let end = offset.min(text.len());
    text.as_bytes()[..end]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// The candidate closest to `word`, if it is close enough to be a plausible typo.
pub fn did_you_mean<'a>(word: &str, candidates: &[&'a str]) -> Option<&'a str> {
    let word = word.to_ascii_lowercase();
    candidates
        .iter()
        .map(|&c| (c, strsim::jaro_winkler(&word, &c.to_ascii_lowercase())))
        .filter(|&(_, score)| score >= 0.75)
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(c, _)| c)
}

/// `` `a`, `b`, `c` `` — for "expected one of" messages.
pub fn list(items: &[&str]) -> String {
    items
        .iter()
        .map(|s| format!("`{s}`"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A problem common to all TOML inputs; loaders wrap it in their own error kinds.
#[derive(Debug, Clone, PartialEq)]
pub enum TomlProblem {
    /// Not valid TOML at all.
    Syntax { message: String },
    /// A key the format does not have.
    UnknownKey {
        key: String,
        suggestion: Option<&'static str>,
        expected: Vec<&'static str>,
    },
    /// A value of the wrong TOML type.
    WrongType {
        expected: &'static str,
        found: &'static str,
    },
    /// A required key is absent.
    Missing { key: String },
    /// `nan` or `inf`.
    NonFinite,
    /// An array of the wrong length.
    WrongLength { expected: usize, found: usize },
}

impl fmt::Display for TomlProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TomlProblem::Syntax { message } => {
                write!(f, "not valid TOML: {message} — check quoting, brackets and `key = value` syntax")
            }
            TomlProblem::UnknownKey { key, suggestion: Some(s), .. } => {
                write!(f, "unknown key `{key}` — did you mean `{s}`?")
            }
            TomlProblem::UnknownKey { key, suggestion: None, expected } => {
                write!(f, "unknown key `{key}` — expected one of {}", list(expected))
            }
            TomlProblem::WrongType { expected, found } => {
                write!(f, "expected {expected}, got {found} — write e.g. {}", example(expected))
            }
            TomlProblem::Missing { key } => {
                write!(f, "missing required key `{key}` — add `{key} = {}`", example_for_key(key))
            }
            TomlProblem::NonFinite => {
                write!(f, "value is not a finite number — use a finite number (no `nan`/`inf`)")
            }
            TomlProblem::WrongLength { expected, found } => write!(
                f,
                "expected an array of {expected} numbers, got {found} — give exactly {expected} values"
            ),
        }
    }
}

fn example(expected: &str) -> &'static str {
    match expected {
        "a number" => "`1.5707963` (plain number, no quotes or units)",
        "a string" => "`\"revolute\"` (in double quotes)",
        "a boolean" => "`true`",
        "an array of numbers" => "`[0.0, 0.0, -9.81]`",
        "an array of tables" => "one `[[joint]]` / `[[link]]` section per item",
        "a table" => "a `[name]` section or an inline table `{ key = value }`",
        _ => "the value shown in the format description",
    }
}

fn example_for_key(key: &str) -> &'static str {
    let last = key.rsplit('.').next().unwrap_or(key);
    match last {
        "name" => "\"my_arm\"",
        "convention" => "\"modified\"",
        "gravity" => "[0.0, 0.0, -9.81]",
        "kind" => "\"revolute\"",
        "com" => "[0.0, 0.0, 0.0]",
        "inertia_com" | "inertia_origin" => "[ixx, ixy, ixz, iyy, iyz, izz]",
        _ => "0.0",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn typo_suggestions() {
        assert_eq!(
            did_you_mean("alhpa", &["alpha", "a", "d", "theta"]),
            Some("alpha")
        );
        assert_eq!(
            did_you_mean("thetta", &["alpha", "a", "d", "theta"]),
            Some("theta")
        );
        assert_eq!(did_you_mean("zzzzzz", &["alpha", "kind"]), None);
    }

    #[test]
    fn lines_count_from_one() {
        assert_eq!(line_of("a\nb\nc", 0), 1);
        assert_eq!(line_of("a\nb\nc", 2), 2);
        assert_eq!(line_of("a\nb\nc", 99), 3);
    }
}
