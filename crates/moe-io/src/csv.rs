//! Numeric CSV tables: comma-separated numbers, one row per line, with an optional header line.
//!
//! The first line is a header when any of its fields is not a number. Blank lines are skipped.
//! Every row must have as many fields as the first row; every value must be a finite number.
//! Values are written in the shortest form that parses back to the same `f64`.

use std::fmt::Write as _;
use std::io::Read;
use std::path::Path;

use crate::atomic::write_atomic;
use crate::error::IoError;
use crate::files::{MEMORY, read_bytes, read_to_end};

/// A parsed numeric table.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CsvTable {
    /// Column names, when the file has a header line.
    pub header: Option<Vec<String>>,
    /// Rows of finite numbers, all of the same width.
    pub rows: Vec<Vec<f64>>,
}

/// Reads a numeric CSV table.
///
/// # Errors
/// [`IoError::Io`] if unreadable, [`IoError::Parse`] naming the line and column of a field that
/// is not a number or of a row with the wrong width, [`IoError::InvalidData`] naming the row and
/// column of a non-finite value.
pub fn read_csv(path: &Path) -> Result<CsvTable, IoError> {
    parse_csv(&read_bytes(path)?, path)
}

/// Reads a numeric CSV table from any reader (errors name the path `<memory>`).
///
/// # Errors
/// As [`read_csv`].
pub fn read_csv_from(reader: impl Read) -> Result<CsvTable, IoError> {
    let path = Path::new(MEMORY);
    parse_csv(&read_to_end(reader, path)?, path)
}

/// Reads points: rows of 3 (`x,y,z`) or 4 (e.g. `x,y,z,value`) numbers, optional header.
///
/// # Errors
/// As [`read_csv`]; also [`IoError::InvalidData`] when rows do not have 3 or 4 fields.
pub fn read_points_csv(path: &Path) -> Result<Vec<Vec<f64>>, IoError> {
    points_from_table(read_csv(path)?, path)
}

/// [`read_points_csv`] from any reader.
///
/// # Errors
/// As [`read_points_csv`].
pub fn read_points_csv_from(reader: impl Read) -> Result<Vec<Vec<f64>>, IoError> {
    let path = Path::new(MEMORY);
    points_from_table(parse_csv(&read_to_end(reader, path)?, path)?, path)
}

fn points_from_table(table: CsvTable, path: &Path) -> Result<Vec<Vec<f64>>, IoError> {
    match table.rows.first().map(Vec::len) {
        None | Some(3 | 4) => Ok(table.rows),
        Some(w) => Err(IoError::invalid(
            path,
            "row 1",
            format!("has {w} fields; points need 3 (x,y,z) or 4"),
        )),
    }
}

/// Writes a numeric CSV table, atomically. An empty `header` writes no header line.
///
/// # Errors
/// [`IoError::InvalidData`] for a header name containing a comma, quote or line break, a row
/// whose width differs from the header's (or the first row's), or a non-finite value (naming
/// the row and column, 1-based); otherwise as [`write_atomic`].
pub fn write_csv(path: &Path, header: &[&str], rows: &[Vec<f64>]) -> Result<(), IoError> {
    write_atomic(path, &csv_bytes(header, rows, path)?)
}

/// The text of a numeric CSV table; `path` only names errors.
///
/// # Errors
/// As [`write_csv`].
pub fn csv_bytes(header: &[&str], rows: &[Vec<f64>], path: &Path) -> Result<Vec<u8>, IoError> {
    if let Some(name) = header
        .iter()
        .find(|n| n.contains([',', '"', '\n', '\r']) || n.trim().is_empty())
    {
        return Err(IoError::invalid(
            path,
            format!("header '{name}'"),
            "column names must be non-empty without commas, quotes or line breaks",
        ));
    }
    let width = if header.is_empty() {
        rows.first().map_or(0, Vec::len)
    } else {
        header.len()
    };
    let mut s = String::new();
    if !header.is_empty() {
        s.push_str(&header.join(","));
        s.push('\n');
    }
    for (r, row) in rows.iter().enumerate() {
        if row.len() != width || width == 0 {
            return Err(IoError::invalid(
                path,
                format!("row {}", r + 1),
                format!("has {} values, expected {width}", row.len()),
            ));
        }
        for (c, v) in row.iter().enumerate() {
            if !v.is_finite() {
                return Err(IoError::invalid(
                    path,
                    format!("row {}, column {}", r + 1, c + 1),
                    format!("value {v} is not finite"),
                ));
            }
            if c > 0 {
                s.push(',');
            }
            let _ = write!(s, "{v:?}");
        }
        s.push('\n');
    }
    Ok(s.into_bytes())
}

/// Parses CSV bytes; `path` only names the source in errors.
pub(crate) fn parse_csv(bytes: &[u8], path: &Path) -> Result<CsvTable, IoError> {
    let text = crate::files::utf8_text(bytes, path)?;
    let mut table = CsvTable::default();
    let mut width = None;
    let mut row_number = 0;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let parsed: Vec<Result<f64, _>> = fields.iter().map(|f| f.parse::<f64>()).collect();
        if table.header.is_none() && table.rows.is_empty() && parsed.iter().any(Result::is_err) {
            table.header = Some(fields.iter().map(|f| f.to_string()).collect());
            width = Some(fields.len());
            continue;
        }
        row_number += 1;
        let expected = *width.get_or_insert(fields.len());
        if fields.len() != expected {
            return Err(IoError::Parse {
                path: path.to_path_buf(),
                line: Some(i + 1),
                column: None,
                message: format!(
                    "row {row_number} has {} fields, expected {expected}",
                    fields.len()
                ),
            });
        }
        let mut row = Vec::with_capacity(expected);
        for (c, value) in parsed.into_iter().enumerate() {
            let v = value.map_err(|_| IoError::Parse {
                path: path.to_path_buf(),
                line: Some(i + 1),
                column: Some(c + 1),
                message: format!(
                    "row {row_number}, column {}: '{}' is not a number",
                    c + 1,
                    fields[c]
                ),
            })?;
            if !v.is_finite() {
                return Err(IoError::invalid(
                    path,
                    format!("row {row_number}, column {} (line {})", c + 1, i + 1),
                    format!("value '{}' is not finite", fields[c]),
                ));
            }
            row.push(v);
        }
        table.rows.push(row);
    }
    Ok(table)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<CsvTable, IoError> {
        parse_csv(s.as_bytes(), Path::new("p.csv"))
    }

    #[test]
    fn header_is_optional() {
        let t = parse("x,y,z\n1,2,3\n\n4.5, -6e-3 ,7\n").unwrap();
        assert_eq!(t.header.unwrap(), vec!["x", "y", "z"]);
        assert_eq!(t.rows, vec![vec![1.0, 2.0, 3.0], vec![4.5, -6e-3, 7.0]]);
        let t = parse("1,2,3,4\n").unwrap();
        assert!(t.header.is_none());
    }

    #[test]
    fn non_finite_values_name_row_and_column() {
        let e = parse("x,y,z\n1,2,3\n1,inf,3\n").unwrap_err();
        assert!(matches!(e, IoError::InvalidData { .. }), "{e}");
        assert!(e.to_string().contains("row 2, column 2"), "{e}");
        let e = parse("1,2,3\n1,2\n").unwrap_err();
        assert!(matches!(e, IoError::Parse { line: Some(2), .. }), "{e}");
        let e = parse("1,2,3\n1,b,3\n").unwrap_err();
        assert!(
            matches!(
                e,
                IoError::Parse {
                    line: Some(2),
                    column: Some(2),
                    ..
                }
            ),
            "{e}"
        );
        let e = csv_bytes(&["a", "b"], &[vec![1.0, f64::NAN]], Path::new("o.csv")).unwrap_err();
        assert!(e.to_string().contains("row 1, column 2"), "{e}");
    }

    #[test]
    fn write_then_read_is_exact() {
        let rows = vec![
            vec![0.1, 1.0 / 3.0, -2e-300, 1e300],
            vec![-0.0, 5.0, 6.0, 7.0],
        ];
        let bytes = csv_bytes(&["x", "y", "z", "p"], &rows, Path::new("o.csv")).unwrap();
        let t = parse_csv(&bytes, Path::new("o.csv")).unwrap();
        assert_eq!(t.rows, rows);
        assert_eq!(t.header.unwrap(), vec!["x", "y", "z", "p"]);
    }
}
