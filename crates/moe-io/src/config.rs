//! JSON and TOML documents through serde.
//!
//! JSON is written pretty-printed with a trailing newline, atomically. `read_config` picks the
//! format by extension (`.toml`, `.json`); syntax and type errors carry the line and column the
//! parser reports.

use std::path::Path;

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::atomic::write_atomic;
use crate::error::IoError;
use crate::files::{extension, line_column, read_bytes};

/// Reads a JSON document into `T`.
///
/// # Errors
/// [`IoError::Io`] if unreadable, [`IoError::Parse`] (with line and column) for syntax errors,
/// type mismatches and unknown fields.
pub fn read_json<T: DeserializeOwned>(path: &Path) -> Result<T, IoError> {
    parse_json(&read_bytes(path)?, path)
}

/// Writes `value` as pretty JSON, atomically.
///
/// # Errors
/// [`IoError::Serialize`] when `value` cannot be represented in JSON (e.g. a map with
/// non-string keys); otherwise as [`write_atomic`]. Note that serde_json writes non-finite
/// floats as `null`.
pub fn write_json<T: Serialize + ?Sized>(path: &Path, value: &T) -> Result<(), IoError> {
    let mut bytes = serde_json::to_vec_pretty(value).map_err(|e| IoError::Serialize {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    bytes.push(b'\n');
    write_atomic(path, &bytes)
}

/// Reads a TOML (`.toml`) or JSON (`.json`) document into `T`.
///
/// # Errors
/// [`IoError::UnsupportedExtension`] for other extensions; otherwise as [`read_json`] /
/// [`parse_toml`].
pub fn read_config<T: DeserializeOwned>(path: &Path) -> Result<T, IoError> {
    match extension(path).as_str() {
        "toml" => parse_toml(&read_bytes(path)?, path),
        "json" => parse_json(&read_bytes(path)?, path),
        ext => Err(IoError::UnsupportedExtension {
            path: path.to_path_buf(),
            ext: ext.to_string(),
            expected: "toml or json",
        }),
    }
}

/// Writes `value` as TOML, atomically.
///
/// # Errors
/// [`IoError::Serialize`] when `value` has no TOML form (TOML has no null, and its top level
/// must be a table); otherwise as [`write_atomic`].
pub fn write_toml<T: Serialize + ?Sized>(path: &Path, value: &T) -> Result<(), IoError> {
    let text = toml::to_string_pretty(value).map_err(|e| IoError::Serialize {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    write_atomic(path, text.as_bytes())
}

/// Parses JSON bytes; `path` only names the source in errors.
///
/// # Errors
/// [`IoError::Parse`] with line and column.
pub fn parse_json<T: DeserializeOwned>(bytes: &[u8], path: &Path) -> Result<T, IoError> {
    serde_json::from_slice(bytes).map_err(|e| IoError::Parse {
        path: path.to_path_buf(),
        line: (e.line() > 0).then_some(e.line()),
        column: (e.column() > 0).then_some(e.column()),
        message: strip_position(&e.to_string()),
    })
}

/// Parses TOML bytes; `path` only names the source in errors.
///
/// # Errors
/// [`IoError::Parse`] (with line and column when the parser knows the span).
pub fn parse_toml<T: DeserializeOwned>(bytes: &[u8], path: &Path) -> Result<T, IoError> {
    let text = crate::files::utf8_text(bytes, path)?;
    toml::from_str(text).map_err(|e| {
        let (line, column) = match e.span() {
            Some(span) => {
                let (l, c) = line_column(text, span.start);
                (Some(l), Some(c))
            }
            None => (None, None),
        };
        IoError::Parse {
            path: path.to_path_buf(),
            line,
            column,
            message: e.message().to_string(),
        }
    })
}

/// serde_json appends " at line L column C" to its messages; the error carries them as fields.
fn strip_position(message: &str) -> String {
    match message.rfind(" at line ") {
        Some(i) => message[..i].to_string(),
        None => message.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, PartialEq, serde::Deserialize, serde::Serialize)]
    #[serde(deny_unknown_fields)]
    struct Doc {
        name: String,
        values: Vec<f64>,
    }

    #[test]
    fn json_errors_carry_line_and_column() {
        let e = parse_json::<Doc>(
            b"{\n  \"name\": \"a\",\n  \"valuez\": []\n}",
            Path::new("d.json"),
        )
        .unwrap_err();
        match e {
            IoError::Parse {
                line,
                column,
                message,
                ..
            } => {
                assert_eq!(line, Some(3));
                assert!(column.is_some());
                assert!(message.contains("valuez"), "{message}");
            }
            other => panic!("unexpected {other}"),
        }
    }

    #[test]
    fn toml_errors_carry_line_and_column() {
        let e = parse_toml::<Doc>(
            b"name = \"a\"\nvalues = [1.0, \"x\"]\n",
            Path::new("d.toml"),
        )
        .unwrap_err();
        assert!(
            matches!(
                e,
                IoError::Parse {
                    line: Some(2),
                    column: Some(_),
                    ..
                }
            ),
            "{e}"
        );
        let ok: Doc =
            parse_toml(b"name = \"a\"\nvalues = [1.5, 2]\n", Path::new("d.toml")).unwrap();
        assert_eq!(
            ok,
            Doc {
                name: "a".into(),
                values: vec![1.5, 2.0]
            }
        );
    }
}
