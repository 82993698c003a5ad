//! Small helpers shared by the readers: whole-file reads and extension dispatch.

use std::io::Read;
use std::path::Path;

use crate::error::IoError;

/// The pseudo-path that errors name when a reader was fed from memory.
pub const MEMORY: &str = "<memory>";

/// Reads a whole file.
///
/// # Errors
/// [`IoError::Io`] naming the file.
pub fn read_bytes(path: &Path) -> Result<Vec<u8>, IoError> {
    std::fs::read(path).map_err(|e| IoError::io(path, e))
}

/// Reads a reader to its end.
pub(crate) fn read_to_end(mut reader: impl Read, path: &Path) -> Result<Vec<u8>, IoError> {
    let mut bytes = Vec::new();
    reader
        .read_to_end(&mut bytes)
        .map_err(|e| IoError::io(path, e))?;
    Ok(bytes)
}

/// The lower-cased extension of a path (empty when there is none).
pub(crate) fn extension(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

/// Runs a third-party parser, turning a panic inside it into [`IoError::ParserPanic`].
///
/// The parser crates did not panic under the fuzz tests; this is a second line of defence so
/// that an input nobody tried still yields an error instead of aborting a long pipeline run.
/// Other format crates (`moe-record`) guard their parsers with it too.
///
/// # Errors
/// What `f` returns, or [`IoError::ParserPanic`] naming `path` and `parser`.
pub fn guarded<T>(
    path: &Path,
    parser: &'static str,
    f: impl FnOnce() -> Result<T, IoError>,
) -> Result<T, IoError> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).unwrap_or_else(|_| {
        Err(IoError::ParserPanic {
            path: path.to_path_buf(),
            parser,
        })
    })
}

/// `bytes` as UTF-8 text, or [`IoError::Parse`] at the line and column of the first invalid byte.
pub(crate) fn utf8_text<'a>(bytes: &'a [u8], path: &Path) -> Result<&'a str, IoError> {
    std::str::from_utf8(bytes).map_err(|e| {
        // The prefix before the first invalid byte is valid UTF-8 by definition.
        let valid = std::str::from_utf8(&bytes[..e.valid_up_to()]).unwrap_or_default();
        let (line, column) = line_column(valid, valid.len());
        IoError::Parse {
            path: path.to_path_buf(),
            line: Some(line),
            column: Some(column),
            message: "not valid UTF-8 text".into(),
        }
    })
}

/// 1-based line and column of a byte offset in `text`.
pub(crate) fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text.as_bytes()[..offset];
    let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
    let line_start = before
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |i| i + 1);
    (line, offset - line_start + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invalid_utf8_is_located() {
        assert_eq!(utf8_text(b"ok\nfine", Path::new("t")).unwrap(), "ok\nfine");
        let err = utf8_text(b"ok\nab\xffc", Path::new("t.csv")).unwrap_err();
        assert!(
            matches!(
                &err,
                IoError::Parse { line: Some(2), column: Some(3), message, .. }
                    if message == "not valid UTF-8 text"
            ),
            "{err:?}"
        );
    }

    #[test]
    fn line_column_counts_from_one() {
        let t = "ab\ncd\nef";
        assert_eq!(line_column(t, 0), (1, 1));
        assert_eq!(line_column(t, 4), (2, 2));
        assert_eq!(line_column(t, 100), (3, 3));
        assert_eq!(extension(Path::new("a/B.OBJ")), "obj");
        assert_eq!(extension(Path::new("noext")), "");
    }
}
